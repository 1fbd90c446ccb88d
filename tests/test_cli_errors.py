"""Every long command refused for bad input prints exactly one line on stderr (CONTRACT §4)."""

from __future__ import annotations

import json

import pytest
from typer.testing import CliRunner

from commission.cli.main import app
from commission.paper import reference_identification

runner = CliRunner()


@pytest.fixture()
def ident_json(tmp_path):
    p = tmp_path / "ident.json"
    p.write_text(json.dumps(reference_identification().to_dict()))
    return p


@pytest.mark.parametrize(
    "argv, pattern",
    [
        (lambda d, i: ["tune", str(d / "missing.json"), "--out", str(d / "t.json")], "missing.json: no such file"),
        (lambda d, i: ["validate", str(i), "--out-dir", str(d / "v")], r"\$\.kind: expected kind 'tuning'"),
        (lambda d, i: ["run", str(i), "--out-dir", str(d / "r")], r"unknown log format '\.json'"),
        (lambda d, i: ["tune", str(i), "--out", str(d / "t.json"), "--spec", str(d / "nope.toml")], "nope.toml"),
    ],
)
def test_refused_command_prints_one_line_and_writes_nothing(tmp_path, ident_json, argv, pattern):
    import re

    before = sorted(p.name for p in tmp_path.iterdir())
    r = runner.invoke(app, argv(tmp_path, ident_json))
    assert r.exit_code == 2, r.output
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1, r.stderr
    assert lines[0].startswith("error: ") and re.search(pattern, lines[0]), lines[0]
    assert sorted(p.name for p in tmp_path.iterdir()) == before
