"""``commission run`` on the real EMPS log with the drive's real limit, +-10 V x 35.15 N/V = 351.5 N
(data: ../shared/data/emps; Janot, Gautier and Brunot, EMPS benchmark, 2019).

A too-large envelope is refused (exit 2) with a remedy; following the remedy's numbers gives a
controller.json labelled in N.  Slow: the tune and validate stages take minutes.
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


def spec(tmp_path, v, a):
    p = tmp_path / f"spec_{v}_{a}.toml"
    # [evidence]: an assumption stated for this test (no structural mode below 5 kHz, beyond the
    # 500-Hz Nyquist frequency), so that it stays on the envelope (commission/evidence.py).
    p.write_text(f"[controller]\nu_max = 351.5\n\n[evidence]\nfirst_mode_hz = 5000.0\n\n"
                 f"[trajectory]\ntravel = 0.2\nv_max = {v}\na_max = {a}\n")
    return p


def test_refusal_names_an_envelope_that_passes_when_followed(tmp_path):
    runner = CliRunner()
    mat = str(EMPS_DIR / "DATA_EMPS.mat")
    r = runner.invoke(app, ["run", mat, *ARGS, "--spec", str(spec(tmp_path, 0.1, 0.763)),
                            "--out-dir", str(tmp_path / "a")])
    assert r.exit_code == 2
    text = " ".join(r.output.split())
    m = re.search(r"set trajectory\.v_max <= ([0-9.e-]+) m/s with trajectory\.a_max <= ([0-9.e-]+) m/s\^2", text)
    assert m, text
    assert text.index("narrow the box") < text.index("only if the drive really has it")
    out = tmp_path / "b"
    r = runner.invoke(app, ["run", mat, *ARGS, "--spec", str(spec(tmp_path, m.group(1), m.group(2))),
                            "--out-dir", str(out)])
    assert json.loads(deployable(r, out).read_text())["units"]["u"] == "N"
    assert "actuator limit 351.5 N" in (out / "report.md").read_text()
