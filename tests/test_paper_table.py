"""Table 1 of Xu & Yao (2001) on the CONTRACT sec. 5 reference plant."""

import dataclasses
import json

import numpy as np
import pytest
from typer.testing import CliRunner

from commission.cli.main import app
from commission.controllers.pid import pid_place_poles
from commission.paper import (
    CONTROLLERS,
    INDEX_NAMES,
    PAPER_TABLE1,
    SCENARIOS,
    format_table,
    paper_pid_gains,
    run_paper_table,
    scenario,
)


@pytest.fixture(scope="module")
def table():
    return run_paper_table()


def test_scenarios_are_the_contracts():
    s1, s2, s3, c2 = (scenario(n) for n in SCENARIOS)
    assert s1.plant_p[0] == 0.027 and s2.plant_p[0] == 0.1 and s3.plant_p[0] == 0.027
    assert s1.traj.n == 25000 and c2.traj.n == 20000
    # Set 3: +0.5 V on 2.2 s <= t < 7.2 s, i.e. 12500 samples at 2.5 kHz.
    d = s3.disturbance
    assert set(np.unique(d)) == {0.0, 0.5} and np.count_nonzero(d) == 12500
    assert d[5499] == 0.0 and d[5500] == 0.5 and d[17999] == 0.5 and d[18000] == 0.0
    assert s1.disturbance is None and c2.disturbance is None


@pytest.mark.parametrize("name", ["set1", "set2", "set3"])
def test_pid_column_matches_the_paper(table, name):
    # Validates the stand-in plant: the paper's PID must land within +-35 % of
    # the published PID column on e_M, e_F and e_rms.
    cell = table.cells[name]["PID"]
    assert not cell.diverged
    got = cell.as_json()
    for k in ("e_M", "e_F", "e_rms"):
        ref = PAPER_TABLE1[name]["PID"][k]
        assert abs(got[k] / ref - 1.0) <= 0.35, f"{name} PID {k}: {got[k]:.3g} um vs paper {ref} um"


@pytest.mark.parametrize("name", SCENARIOS)
def test_arc_beats_pid(table, name):
    pid, arc = table.cells[name]["PID"], table.cells[name]["ARC"]
    assert not pid.diverged and not arc.diverged
    for k in ("e_M", "e_F", "e_rms"):
        assert getattr(arc.indexes, k) < getattr(pid.indexes, k), f"{name} {k}"
    assert arc.indexes.c_u <= 0.35


def test_diverged_run_is_a_failed_cell_not_a_crash():
    Kp, Ki, Kd = pid_place_poles(0.02, -1600.0)
    unstable = dataclasses.replace(paper_pid_gains(), Kp=Kp, Ki=Ki, Kd=Kd)
    t = run_paper_table(scenarios=("set1",), controllers=("PID",), pid=unstable)
    cell = t.cells["set1"]["PID"]
    assert cell.diverged and cell.indexes is None
    js = t.as_json()["set1"]["PID"]
    assert js["diverged"] is True and all(js[k] is None for k in INDEX_NAMES)
    text = format_table(t, with_paper=False)
    assert "DIVERGED (failed): set1/PID" in text
    json.dumps(t.as_json(), allow_nan=False)  # no NaN can reach the JSON


def test_cli_writes_the_table(table, tmp_path):
    out = tmp_path / "paper_table.json"
    r = CliRunner().invoke(app, ["paper-table", "--out", str(out)])
    assert r.exit_code == 0, r.output
    for label in ("e_M (um)", "e_F (um)", "||e||rms (um)", "||u||rms (V)", "||du||rms (V)", "c_u",
                  "Set 1", "Set 2", "Set 3", "Case 2"):
        assert label in r.output
    text = out.read_text()
    data = json.loads(text)
    assert list(data) == sorted(SCENARIOS)
    for s in SCENARIOS:
        assert set(data[s]) == set(CONTROLLERS)
        for c in CONTROLLERS:
            cell = data[s][c]
            assert set(cell) == set(INDEX_NAMES) | {"diverged"}
            ix = table.cells[s][c].indexes
            # Errors in um, inputs in V.
            assert cell["e_M"] == pytest.approx(ix.e_M * 1e6, rel=1e-12)
            assert cell["e_rms"] == pytest.approx(ix.e_rms * 1e6, rel=1e-12)
            assert cell["u_rms"] == pytest.approx(ix.u_rms, rel=1e-12)
            assert cell["c_u"] == pytest.approx(ix.du_rms / ix.u_rms, rel=1e-12)
    assert text == json.dumps(data, sort_keys=True, indent=2) + "\n"


def test_cli_out_directory_is_a_usage_error(tmp_path):
    r = CliRunner().invoke(app, ["paper-table", "--out", str(tmp_path)])
    assert r.exit_code == 2
    assert "is a directory" in r.output
    assert list(tmp_path.iterdir()) == []
