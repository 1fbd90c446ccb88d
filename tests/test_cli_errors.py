"""Every long command refused for bad input prints exactly one line on stderr (CONTRACT §4)."""

from __future__ import annotations

import json
import os
from pathlib import Path

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


# --------------------------------------------------------------------------- one file twice, --fix


SAMPLE = Path(__file__).resolve().parents[1] / "sample_data" / "axis_excitation.h5"


def _twice(d: Path, how: str) -> tuple[list[str], str, str]:
    """Log arguments naming one file twice, and the two spellings the refusal must name."""
    folder = d / "logs"
    folder.mkdir()
    a = folder / "a.h5"
    a.write_bytes(SAMPLE.read_bytes())
    if how == "same":
        return [str(a), str(a)], str(a), str(a)
    if how == "folder":
        return [str(a), str(folder)], str(a), f"{a} (in the folder {folder})"
    if how == "symlink":
        (d / "link.h5").symlink_to(a)
        return [str(d / "link.h5"), str(a)], str(d / "link.h5"), str(a)
    os.link(a, d / "hard.h5")
    return [str(folder), str(d / "hard.h5")], f"{a} (in the folder {folder})", str(d / "hard.h5")


@pytest.mark.parametrize("command", ["identify", "run"])
@pytest.mark.parametrize("how", ["same", "folder", "symlink", "hardlink"])
def test_one_log_given_twice_is_refused_naming_both_spellings(tmp_path, command, how):
    logs, first, second = _twice(tmp_path, how)
    out = ["--out", str(tmp_path / "i.json")] if command == "identify" else ["--out-dir", str(tmp_path / "r")]
    before = sorted(p.name for p in tmp_path.iterdir())
    r = runner.invoke(app, [command, *logs, *out])
    assert r.exit_code == 2, r.output
    assert r.stderr == (f"error: {first} and {second}: the same file given twice; give each log once "
                        "(its samples would be fitted twice)\n")
    assert sorted(p.name for p in tmp_path.iterdir()) == before


@pytest.mark.parametrize("command", ["identify", "run"])
@pytest.mark.parametrize("fix, message", [
    (["M=0.03", "M=0.05"], "--fix M: given twice ('M=0.03' and 'M=0.05'); give it once"),
    (["M=0.03", " M=0.03"], "--fix M: given twice ('M=0.03' and ' M=0.03'); give it once"),
    (["M=1e300"], "--fix 'M=1e300': M = 1e+300 is outside the plausible range [1e-12, 1e+12] u-unit·s²/m "
                  "(theta1 = 1/M must lie in tune's range for theta1)"),
    (["M=1e-300"], "--fix 'M=1e-300': M = 1e-300 is outside the plausible range [1e-12, 1e+12] u-unit·s²/m "
                   "(theta1 = 1/M must lie in tune's range for theta1)"),
])
def test_a_repeated_or_implausible_fix_is_refused_by_name(tmp_path, command, fix, message):
    out = ["--out", str(tmp_path / "i.json")] if command == "identify" else ["--out-dir", str(tmp_path / "r")]
    r = runner.invoke(app, [command, str(SAMPLE), *out, *(a for f in fix for a in ("--fix", f))])
    assert r.exit_code == 2, r.output
    assert r.stderr == f"error: {message}\n"
    assert list(tmp_path.iterdir()) == []


def test_the_fix_range_is_theta1s_range_of_the_tune_spec():
    from commission.identification import FIX_RANGES, parse_fix
    from commission.spec import RANGES
    from commission.errors import UsageError

    lo, hi = RANGES[("controller", "theta1_0")]
    assert FIX_RANGES["M"] == (1 / hi, 1 / lo)
    assert parse_fix([f"M={1 / hi!r}", ]) == {"M": 1 / hi} and parse_fix([f"M={1 / lo!r}"]) == {"M": 1 / lo}
    for v in (0.99 / hi, 1.01 / lo, 0.0, -1.0, float("inf"), float("nan")):
        with pytest.raises(UsageError, match=r"^--fix 'M="):
            parse_fix([f"M={v!r}"])
