"""``commission run`` on the real EMPS log at the benchmark's own speed, 0.128 m/s and 1.33 m/s^2, given as the
machine's moves (``[[trajectory.move]]``), with the drive's real limit 351.5 N (data: ../shared/data/emps;
Janot, Gautier and Brunot, EMPS benchmark, 2019).

Before the moves could be given, this speed was refused ("582 N needed": the paper's Case-1 start-up counted)
and a third of it was certified.  Now:

1. With identify's default load-force bound (10 x the friction, about 204 N of unknown constant force on top of
   a 10-kg payload), the moves are refused, exit 2, naming each force with its figures against u_max and the
   scenarios, and a ``--disturbance-bound`` that leaves the feedback 30 % of u_max.
2. Following it, ``run`` writes a controller.json: the envelope (and the runtime guard) is the moves' own,
   the ``user/...`` scenarios pass beside Case 1 and Case 2 (the reference, at the envelope derived for the
   drive), and ``commission validate`` on the tuning.json re-creates the same moves.

Slow: tune and validate take minutes.
"""

from __future__ import annotations

import json
import re

import pytest
from shared_paths import EMPS_DIR
from typer.testing import CliRunner

from commission.cli.main import app
from verdicts import deployable

pytestmark = [pytest.mark.skipif(not (EMPS_DIR / "DATA_EMPS.mat").exists(), reason="EMPS data not present"),
              pytest.mark.slow]

ARGS = ["--map", "q=qm", "--map", "u=vir", "--input-gain", "35.15065188248547", "--u-unit", "N",
        "--payload-max", "10", "--workers", "1"]
V, A, J = 0.128, 1.33, 20.0


def moves_spec(tmp_path):
    p = tmp_path / "emps_moves.toml"
    move = "[[trajectory.move]]\nto = {to}\nv_max = %g\na_max = %g\nj_max = %g\n" % (V, A, J)
    # [evidence]: an assumption stated for this test (no structural mode below 5 kHz, beyond the
    # 500-Hz Nyquist frequency), so that it stays on the envelope; without it the 36-Hz band the EMPS log backs
    # shapes the loops (commission/evidence.py).
    p.write_text("[controller]\nu_max = 351.5\n\n[evidence]\nfirst_mode_hz = 5000.0\n\n"
                 + "dwell = 0.5\n\n".join(move.format(to=to) for to in (0.2, 0.0, 0.2, 0.0)))
    return p


def test_emps_at_its_own_speed_refusal_names_the_forces_then_its_value_gives_a_controller(tmp_path):
    runner = CliRunner()
    mat = str(EMPS_DIR / "DATA_EMPS.mat")
    spec = moves_spec(tmp_path)
    r = runner.invoke(app, ["run", mat, *ARGS, "--spec", str(spec), "--out-dir", str(tmp_path / "a")])
    assert r.exit_code == 2, r.output
    text = " ".join(r.output.split())
    m = re.search(r"controller\.u_max = 351\.5 N is below the ([0-9.]+) N that trajectory\.move \(4 moves\) need", text)
    assert m, text
    need = float(m.group(1))
    assert need > 351.5
    # Each force with its figures: M a at the moves' a_max, B v, friction, the box's constant load force.
    forces = re.search(r"M a = [0-9.]+ x 1\.33 m/s\^2 = ([0-9.]+) N, B v = [0-9.]+ x [0-9.]+ m/s = ([0-9.]+) N, "
                       r"friction \+20 % ([0-9.]+) N, ripple ([0-9.]+) N and the box's largest constant load force "
                       r"([0-9.]+) N", text)
    assert forces, text
    assert sum(float(x) for x in forces.groups()) == pytest.approx(need, rel=2e-3)
    assert "user/payload_heavy" in text and "582" not in text  # no Case-1 start-up counted
    d = re.search(r"--disturbance-bound ([0-9.]+) \(N; now ([0-9.]+) N, the default", text)
    assert d, text
    assert float(d.group(1)) < float(d.group(2))
    out = tmp_path / "b"
    r = runner.invoke(app, ["run", mat, *ARGS, "--disturbance-bound", d.group(1), "--spec", str(spec),
                            "--out-dir", str(out)])
    ctrl = json.loads(deployable(r, out).read_text())
    assert ctrl["units"]["u"] == "N"
    tuning = json.loads((out / "tuning.json").read_text())
    traj = tuning["spec"]["trajectory"]
    # The envelope is the moves' own, not a derivation from u_max; Case 1/2 at the derived reference.
    assert (traj["v_max"], traj["a_max"], traj["travel"]) == (pytest.approx(V), pytest.approx(A), pytest.approx(0.2))
    assert 0 < traj["reference_v_max"] <= V and 0 < traj["reference_a_max"] <= A
    assert len(traj["move"]) == 4
    # The runtime's plausibility guard follows the moves' speed: dy_max = 2 v_max Ts + 2 LSB.
    dy = re.search(r'"dy_max": ([0-9.e-]+)', json.dumps(ctrl))
    assert dy and float(dy.group(1)) == pytest.approx(2 * V * ctrl["sample_period"], rel=0.01)
    val = json.loads((out / "validation.json").read_text())
    names = {x["name"] for x in val["runs"]}
    assert {"user/nominal", "user/payload_heavy", "user/disturbance", "case1/nominal", "case2/nominal"} <= names
    report = (out / "report.md").read_text()
    assert "envelope from the machine's moves" in report and "actuator limit 351.5 N" in report
    assert "The machine's own moves" in report
    assert (out / "tracking_user.png").is_file() and "![tracking_user.png](tracking_user.png)" in report
    # validate alone re-creates the same moves from tuning.json.
    r = runner.invoke(app, ["validate", str(out / "tuning.json"), "--out-dir", str(tmp_path / "v"),
                            "--monte-carlo", "3", "--workers", "1"])
    deployable(r, tmp_path / "v")
    again = json.loads((tmp_path / "v" / "validation.json").read_text())
    first = {x["name"]: x for x in val["runs"]}
    for x in again["runs"]:
        if x["name"] == "user/nominal":
            assert x["arc"] == first["user/nominal"]["arc"]
