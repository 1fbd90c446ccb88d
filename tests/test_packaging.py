"""Installing commission must not shadow other distributions (PyPI `identify`)."""

import ast
import importlib
import pathlib

import pytest


def test_pypi_identify_and_ours_coexist():
    pypi_identify = importlib.import_module("identify.identify")  # pre-commit's package
    ours = importlib.import_module("commission.identify")
    assert hasattr(pypi_identify, "tags_from_filename")
    assert ours.__name__ == "commission.identify"
    assert "commission" in pathlib.Path(ours.__file__).parts[-2] or ours.__file__.endswith("__init__.py")
    assert importlib.import_module("identify").__file__ != ours.__file__


@pytest.mark.parametrize("pkg", ["commission.identify", "commission.controllers"])
def test_numerics_never_import_io_or_ui(pkg):
    # Dependencies point one way: numerics never import typer, h5py or matplotlib,
    # nor the pipeline layer above them.
    mod = importlib.import_module(pkg)
    root = pathlib.Path(mod.__file__).parent
    banned = {"typer", "h5py", "matplotlib", "click", "rich"}
    for src in root.rglob("*.py"):
        tree = ast.parse(src.read_text())
        for node in ast.walk(tree):
            names = []
            if isinstance(node, ast.Import):
                names = [a.name for a in node.names]
            elif isinstance(node, ast.ImportFrom) and node.module:
                names = [node.module]
            for n in names:
                top = n.split(".")[0]
                assert top not in banned, f"{src.name} imports {n}"
                if n.startswith("commission.") and not n.startswith(pkg):
                    allowed = ("commission.identify", "commission.controllers")
                    assert n.startswith(allowed), f"{src.name} imports pipeline module {n}"


def test_cli_help_lists_and_exits_zero():
    from typer.testing import CliRunner

    from commission.cli.main import app

    r = CliRunner().invoke(app, ["--help"])
    assert r.exit_code == 0
    assert "commission" in r.output.lower()
