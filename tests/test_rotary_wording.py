"""A rotary axis (q in rad) says "inertia J" with its unit wherever a linear one says "mass M"."""

from __future__ import annotations

import json
from types import SimpleNamespace

import pytest
from typer.testing import CliRunner

from commission.artifacts import Estimate, Identification, ThetaBox, mass_wording
from commission.cli.main import app
from commission.report import identification_markdown

runner = CliRunner()


def _ident(q: str, u: str, *, with_mass: bool) -> Identification:
    params = {"M": Estimate(0.012, 0.0004) if with_mass else None, "B": Estimate(0.3, 0.01),
              "fc": Estimate(0.1, 0.002), "fs": None, "vs": None, "xi": None, "offset": Estimate(0.01, 0.001)}
    theta = ThetaBox((1 / 0.012, 25.0, 0.8), (50.0, 10.0, -5.0), (120.0, 40.0, 5.0)) if with_mass else None
    extra = {"source": {"path": "axis.csv", "n_samples": 1000, "sample_rate": 1000.0},
             "model": {"friction": "coulomb", "method": "dynamic"},
             "not_identified": {} if with_mass else {"M": "no acceleration in the log"}}
    return Identification(units={"u": u, "q": q}, parameters=params, relative_error=0.05, condition_number=20.0,
                          validation_relative_error=None, theta=theta, delta_d=1.0 if with_mass else None,
                          fric_level=0.1, fric_slope=100.0, extra=extra)


def test_mass_wording_names_inertia_with_its_unit_on_a_rotary_axis():
    assert mass_wording({"u": "Nm", "q": "rad"}) == ("inertia J", "Nm·s²/rad")
    assert mass_wording({"u": "N", "q": "m"}) == ("mass M", "N·s²/m")


@pytest.mark.parametrize("q, u, word, unit, other", [("rad", "Nm", "inertia J", "Nm·s²/rad", "mass"),
                                                     ("m", "N", "mass", "N·s²/m", "inertia")])
def test_the_report_labels_m_as_the_axis_kind_says(q, u, word, unit, other):
    text = "\n".join(identification_markdown(SimpleNamespace(identification=_ident(q, u, with_mass=True))))
    row = next(line for line in text.splitlines() if line.startswith("| M ("))
    assert row.startswith(f"| M ({word}) |") and row.endswith(f"| {unit} |"), row
    assert other not in text.split("| Parameter")[0] + row


def test_tune_refuses_a_rotary_identification_without_inertia_naming_the_inertia(tmp_path):
    path = tmp_path / "ident.json"
    path.write_text(json.dumps(_ident("rad", "Nm", with_mass=False).to_dict()))
    res = runner.invoke(app, ["tune", str(path), "--out", str(tmp_path / "t.json")])
    assert res.exit_code == 2, res.output
    msg = " ".join(res.output.split())
    assert "$.parameters.M: not identified" in msg and "tune needs the inertia J (Nm·s²/rad)" in msg
    assert "mass" not in msg and not (tmp_path / "t.json").exists()
    (gap,) = _ident("m", "N", with_mass=False).tuning_gaps()
    assert "tune needs the mass M (N·s²/m)" in gap and "inertia" not in gap
