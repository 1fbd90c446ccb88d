"""commission.report.tables: the Monte-Carlo table of report.md (median and worst per controller),
its headings from the one index table, its cells in the table's display scale."""

from __future__ import annotations

import math
from types import SimpleNamespace

from commission.controllers.metrics import INDEX_ROWS
from commission.report.tables import monte_carlo_markdown
from commission.controllers.metrics import Indexes

NAN = math.nan


def _run(name, arc, pid):
    return SimpleNamespace(name=name, tags=("case1", "monte_carlo"), arc=arc, pid=pid)


def _score(e_rms, c_u, u_peak, diverged=False):
    if diverged:
        return Indexes(NAN, NAN, NAN, NAN, NAN, NAN, u_peak, True)
    return Indexes(10 * e_rms, 3 * e_rms, e_rms, 0.2, 0.06, c_u, u_peak, False)


def test_monte_carlo_table_shows_median_and_worst_in_display_units():
    runs = [_run("mc/000", _score(1e-6, 0.1, 1.0), _score(2e-6, 0.05, 2.0)),
            _run("mc/001", _score(3e-6, 0.3, 5.0), _score(4e-6, 0.15, 3.0)),
            _run("mc/002", _score(0, 0, 9.0, diverged=True), _score(6e-6, 0.25, 4.0))]
    result = SimpleNamespace(runs=runs, seed=7)
    lines = monte_carlo_markdown(result, "V")
    assert lines[1] == "### Monte-Carlo plants (3, theta uniform in the box, seed 7)"
    rows = {ln.split("|")[1].strip(): [c.strip() for c in ln.split("|")[2:6]] for ln in lines if ln.startswith("| ")}
    # ARC: the diverged plant left out (median and worst of 1 and 3 um); PID: of 2, 4 and 6 um
    assert rows["‖e‖rms (um)"] == ["2", "3", "4", "6"]
    assert rows["e_M (um)"] == ["20", "30", "40", "60"]
    # c_u shown to 3 significant digits here (medians), not the table's 2 decimals
    assert rows["c_u"] == ["0.2", "0.3", "0.15", "0.25"] and INDEX_ROWS["c_u"].fmt == "{:.2f}"
    assert rows["peak command (V)"] == ["3", "5", "3", "4"]
    assert rows["diverged"] == ["1", "", "0", ""]
    assert lines[-1] == "ARC e_rms no worse than PID on 2 of 3 plants."


def test_no_monte_carlo_plants_no_table():
    assert monte_carlo_markdown(SimpleNamespace(runs=[], seed=0), "V") == []
