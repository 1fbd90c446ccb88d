"""Safe but not better (:func:`commission.gate.safe_not_better`): a validation that fails only on the
comparison with the PID yardstick is said so plainly and leaves a deployable, flagged ARC
(``controller_not_better.json``) that ``load_controller`` loads; never ``controller.json``."""

from __future__ import annotations

import math

import pytest

from typer.testing import CliRunner

from commission.cli.main import app
from commission.gate import GateSpec, safe_not_better
from commission.jsonio import sha256_file
from commission.report import not_better_lines
from commission.runtime import load_controller
from commission.validate import CONTROLLER_NAME, FLAGGED_NAME, controller_config, validate, write_outputs
from reference_tuning import reference_tuning


@pytest.fixture(scope="module")
def tuned():
    return reference_tuning(8)


def test_a_safe_arc_that_does_not_beat_the_yardstick_is_flagged_not_refused_silently(tuned, tmp_path):
    # limits (a user's gate.toml) the ARC alone meets, a comparison with the PID it cannot meet
    loose = GateSpec(e_rms=_um(100), e_F=_um(200), e_M=_um(2000), arc_vs_pid_median=1e-3, arc_vs_pid_p90=1e3)
    r = validate(tuned, loose, seed=0, n_monte_carlo=2, workers=1)
    assert not r.passed and safe_not_better(r.verdict), [c.detail for c in r.verdict.failures]
    assert {c.criterion for c in r.verdict.failures} == {"arc_vs_pid_median"}
    tuned.save(str(tmp_path / "tuning.json"))
    written = write_outputs(r, tuned, sha256_file(tmp_path / "tuning.json"), tmp_path)
    assert not (tmp_path / CONTROLLER_NAME).exists() and tmp_path / FLAGGED_NAME in written
    ctrl = load_controller(str(tmp_path / FLAGGED_NAME))
    assert ctrl.config.gains == r.arc_gains
    flag = ctrl.config.validated["flag"]
    assert flag["beats_yardstick"] is False and flag["verdict"] == "safe_not_better"
    assert [f["criterion"] for f in flag["failed"]] == [c.criterion for c in r.verdict.failures]
    assert math.isclose(flag["pid_gains"]["Kp"], tuned.pid.Kp)
    report = (tmp_path / "report.md").read_text()
    assert "Safe, but not better than the PID yardstick." in report.split("## Axis and controller")[0]
    lines = not_better_lines(r, tuned)
    assert "controller_not_better.json" in lines[1] and "--controller pid" in lines[1]
    # the command the report gives exports the validated PID yardstick from it
    out = CliRunner().invoke(app, ["export", str(tmp_path / FLAGGED_NAME), "--controller", "pid", "--tuning",
                                   str(tmp_path / "tuning.json"), "--target", "c", "--out-dir", str(tmp_path / "c")])
    assert out.exit_code == 0, out.output
    assert (tmp_path / "c" / "commission_pid_params.c").is_file()
    # a failure of the ARC itself (here an e_rms limit below what it reaches) is no "safe but not better"
    tight = validate(tuned, GateSpec(e_rms=_um(0.1), arc_vs_pid_median=1e-3), seed=0, n_monte_carlo=2, workers=1)
    assert not safe_not_better(tight.verdict)
    with pytest.raises(ValueError, match="flagged only"):
        controller_config(tight, tuned, "1" * 64, flagged=True)
    write_outputs(tight, tuned, sha256_file(tmp_path / "tuning.json"), tmp_path)
    assert not (tmp_path / FLAGGED_NAME).exists()  # never left next to a report that does not say so


def _um(x: float):
    from commission.gate import ErrorLimit
    return ErrorLimit(x * 1e-6, "m", f"{x} um")
