"""Issue 23, CLI: -h, readable metavars, pipeline order, shell completion, --quiet/--verbose,
and a help that loads no numerics (its wall time is measured by benchmarks/bench_cli_help.py)."""

from __future__ import annotations

import re
import subprocess
import sys
from pathlib import Path

import pytest

from commission.cli.commands import COMMANDS
from commission.cli.main import run

SAMPLE = Path(__file__).resolve().parents[1] / "sample_data" / "axis_excitation.h5"


def _help(capsys, *argv: str) -> str:
    assert run(list(argv)) == 0
    return capsys.readouterr().out


def test_dash_h_is_help_for_the_group_and_every_command(capsys):
    assert _help(capsys, "-h") == _help(capsys, "--help")
    for name in COMMANDS:
        text = _help(capsys, name, "-h")
        assert f"Usage: commission {name}" in text and text == _help(capsys, name, "--help")


def test_commands_are_listed_in_pipeline_order(capsys):
    text = _help(capsys, "--help")
    where = [text.index(f" {name} ") for name in ("identify", "tune", "validate", "run", "paper-table")]
    assert where == sorted(where)
    assert list(COMMANDS)[:5] == ["excite", "identify", "tune", "validate", "run"]


@pytest.mark.parametrize("name", list(COMMANDS))
def test_metavars_are_readable(capsys, name):
    text = _help(capsys, name, "-h")
    for typer_style in ("<bool>", "<path>", "<float>", "<int>", "<str>", "<list[", "{log}", "{ident}", "{tuning}"):
        assert typer_style not in text, (name, typer_style)
    if name == "identify":
        assert re.search(r"Usage: commission identify \[OPTIONS\] LOG", text)
        assert re.search(r"--out\s+-o\s+PATH", text) and "auto|coulomb|stribeck" in text


def test_shell_completion_is_installed_by_typer(capsys):
    text = _help(capsys, "--help")
    assert "--install-completion" in text and "--show-completion" in text


def test_help_loads_no_numerics(tmp_path):
    probe = ("import sys; sys.argv = ['commission', '--help']; from commission.cli.main import run; "
             "import io, contextlib; f = io.StringIO(); code = None\n"
             "with contextlib.redirect_stdout(f): code = run(['--help'])\n"
             "print(code, sorted(m for m in ('numpy', 'scipy', 'numba', 'h5py', 'matplotlib') if m in sys.modules))")
    # run outside the checkout: `python -c` puts the working folder first on sys.path, and the source
    # folder `commission/` would shadow the installed package (which also holds commission.cli)
    out = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True, check=True,
                         cwd=tmp_path).stdout
    assert out.strip() == "0 []", out


def test_quiet_prints_nothing_on_stdout_and_verbose_adds_the_time(tmp_path, capsys):
    assert run(["-q", "identify", str(SAMPLE), "--out", str(tmp_path / "a.json")]) == 0
    cap = capsys.readouterr()
    assert cap.out == "" and (tmp_path / "a.json").exists()
    assert run(["identify", str(SAMPLE), "--out", str(tmp_path / "b.json")]) == 0
    assert "wrote" in capsys.readouterr().out
    assert run(["-v", "identify", str(SAMPLE), "--out", str(tmp_path / "c.json")]) == 0
    assert re.search(r"^elapsed \d+\.\d\d s$", capsys.readouterr().err, re.M)
    assert run(["-q", "-v", "identify", str(SAMPLE)]) == 2
    assert "exclude each other" in capsys.readouterr().err
