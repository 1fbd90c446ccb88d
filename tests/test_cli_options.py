"""The identify and validation flags declared once and given to a command by with_identify_flags and
with_validate_flags (commission.cli.options)."""

from __future__ import annotations

import re
from pathlib import Path
from typing import Optional

import pytest
import typer
from typer.testing import CliRunner

from commission.cli.main import run
from commission.cli.options import _IDENTIFY, ValidateFlags, validate_flags, with_identify_flags, with_validate_flags
from commission.identification import IdentifyOptions
from commission.validate import DEFAULT_MONTE_CARLO

runner = CliRunner()


def _options_in_help(capsys, command: str) -> list[str]:
    """The options of ``command --help``, in its order (the flag that opens each row of its panels)."""
    assert run([command, "--help"]) == 0
    return re.findall(r"^\S[ *]{1,6}(--[a-z][a-z0-9-]*)", capsys.readouterr().out, re.M)


@pytest.mark.parametrize("table, commands", [(_IDENTIFY, ("identify", "run")),
                                             (validate_flags("seed", "plants"), ("validate", "run"))],
                         ids=["identify flags", "validation flags"])
def test_the_commands_list_every_shared_flag_together_in_the_table_order(capsys, table, commands):
    order = list(table)
    for command in commands:
        shown = _options_in_help(capsys, command)
        i = shown.index(order[0])
        assert shown[i:i + len(order)] == order, command


def test_the_command_receives_the_parsed_flags_and_keeps_its_own():
    seen: dict[str, object] = {}
    demo = typer.Typer()

    @demo.command()
    @with_identify_flags
    def cmd(out: Path = typer.Option(Path("x.json"), "--out"), o: IdentifyOptions = None,  # type: ignore[assignment]
            extra: Optional[int] = typer.Option(None, "--extra")) -> None:
        seen.update(out=out, o=o, extra=extra)

    r = runner.invoke(demo, ["--map", "q=qm", "--map", "u=vir", "--k-sigma", "2.5", "--fix", "M=0.5",
                             "--format", "csv", "--out", "y.json", "--extra", "7"])
    assert r.exit_code == 0, r.output
    o = seen["o"]
    assert isinstance(o, IdentifyOptions)
    assert dict(o.mapping) == {"q": "qm", "u": "vir"}
    assert o.bounds.k_sigma == 2.5 and o.fmt == "csv" and dict(o.fix) == {"M": 0.5}
    assert (seen["out"], seen["extra"]) == (Path("y.json"), 7)
    r = runner.invoke(demo, [])  # the table's defaults
    assert r.exit_code == 0, r.output
    assert seen["o"].bounds.k_sigma == _IDENTIFY["--k-sigma"].default and seen["o"].input_gain == 1.0


def test_a_bad_identify_flag_is_refused_by_run_before_anything_is_written(tmp_path, capsys):
    out = tmp_path / "out"
    assert run(["run", str(tmp_path / "log.h5"), "--out-dir", str(out), "--input-gain", "2"]) == 2
    err = capsys.readouterr().err
    assert "--input-gain" in err and "--u-unit" in err
    assert not out.exists()


def test_the_command_receives_the_validation_flags_as_one_record():
    seen: dict[str, object] = {}
    demo = typer.Typer()

    @demo.command()
    @with_validate_flags(seed_help="seed", monte_carlo_help="plants")
    def cmd(out: Path = typer.Option(Path("x.json"), "--out"), v: ValidateFlags = None) -> None:  # type: ignore[assignment]
        seen.update(out=out, v=v)

    r = runner.invoke(demo, ["--gate", "g.toml", "--force", "--seed", "7", "--monte-carlo", "3", "--workers", "2",
                             "--scheduler", "tcp://h:1", "--out", "y.json"])
    assert r.exit_code == 0, r.output
    assert seen["v"] == ValidateFlags(Path("g.toml"), True, 7, 3, 2, None, "tcp://h:1")
    assert seen["out"] == Path("y.json")
    r = runner.invoke(demo, [])  # the table's defaults
    assert r.exit_code == 0, r.output
    assert seen["v"] == ValidateFlags(None, False, 0, DEFAULT_MONTE_CARLO, None, None, None)
