"""``--friction auto`` on the real EMPS log (../shared/data/emps; Janot, Gautier and Brunot, 2019).

The Stribeck fit there is anti-Stribeck (fs < fc), which the compensated model does not expect:
auto must fall back to the Coulomb model, with a warning giving both figures, and the Coulomb
fit is the benchmark's published IDIM-LS one (README: M 95.1089, Fv 203.5034, Fc 20.3935,
offset -3.1648).  ``--terms none`` keeps auto to that choice; with the default terms auto goes on
to the delay-aware model chosen by cross-validation (tests/test_identify_richer.py).  The published
model has no force ripple, so ``--ripple-pitch none`` turns the default ripple search off (it finds a
small one on EMPS's legs, tests/test_identify_richer.py).
"""

from __future__ import annotations

import json

import pytest
from shared_paths import EMPS_DIR
from typer.testing import CliRunner

from commission.cli.main import app

pytestmark = pytest.mark.skipif(not (EMPS_DIR / "DATA_EMPS.mat").exists(), reason="EMPS data not present")


def test_auto_gives_coulomb_with_an_anti_stribeck_warning(tmp_path):
    out = tmp_path / "ident.json"
    r = CliRunner().invoke(app, ["identify", str(EMPS_DIR / "DATA_EMPS.mat"), "--map", "q=qm", "--map", "u=vir",
                                 "--input-gain", "35.15065188248547", "--u-unit", "N", "--terms", "none",
                                 "--ripple-pitch", "none", "--out", str(out)])
    assert r.exit_code == 0, r.output
    doc = json.loads(out.read_text())
    assert (doc["model"]["friction"], doc["model"]["friction_requested"]) == ("coulomb", "auto")
    p = doc["parameters"]
    for name, ref in (("M", 95.1089), ("B", 203.5034), ("fc", 20.3935), ("offset", -3.1648)):
        assert round(p[name]["value"], 4) == ref
    anti = [w for w in doc["warnings"] if w.startswith("friction auto: the Stribeck fit is anti-Stribeck")]
    assert len(anti) == 1 and "fs = " in anti[0] and "< fc = " in anti[0]
