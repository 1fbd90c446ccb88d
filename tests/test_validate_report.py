"""Text of the validation report: Table-1 layout, Monte-Carlo summary, stdout summary."""

import math
from types import SimpleNamespace

import pytest

from commission.gate import GateSpec, evaluate_gate, resolve_gate
from commission.report import monte_carlo_summary, summary_text, table1_markdown, verdict_text
from commission.scenarios import VARIANTS
from commission.controllers.metrics import Indexes

NAN = math.nan


def sc(e_rms, diverged=False):
    if diverged:
        return Indexes(NAN, NAN, NAN, NAN, NAN, NAN, 10.0, True)
    return Indexes(10 * e_rms, 3 * e_rms, e_rms, 0.2, 0.06, 0.3, 0.7, False)


def run(name, tags, arc, pid):
    return SimpleNamespace(name=name, tags=tags, arc=arc, pid=pid, theta_final=(1.0, 2.0, 3.0),
                           theta_true=(1.0, 2.0, -0.0))


@pytest.fixture()
def result():
    runs = [run(f"case1/{v}", ("case1", v, "tune"), sc(1e-6 * (i + 1)), sc(2e-6 * (i + 1)))
            for i, v in enumerate(VARIANTS)]
    runs += [run("mc/000", ("case1", "monte_carlo"), sc(4e-6), sc(3e-6)),
             run("mc/001", ("case2", "monte_carlo"), sc(0, diverged=True), sc(5e-6)),
             run("mc/002", ("case1", "monte_carlo"), sc(2e-6), sc(0, diverged=True))]
    lim = resolve_gate(GateSpec(arc_vs_pid_e_rms=1.0), lsb=1e-6, travel=0.4, u_max=10.0)
    verdict = evaluate_gate(lim, [(r.name, r.arc, r.pid, 0.5 if r.arc.diverged else NAN) for r in runs])
    return SimpleNamespace(runs=tuple(runs), verdict=verdict, units={"u": "V"})


def test_table1_layout(result):
    lines = table1_markdown(result, "case1", "V").splitlines()
    assert lines[0].startswith("| Controller | nominal PID | nominal ARC | payload_light PID | payload_light ARC |")
    assert lines[1] == "|---|" + "---:|" * 12
    labels = [ln.split("|")[1].strip() for ln in lines[2:]]
    assert labels == ["e_M (um)", "e_F (um)", "‖e‖rms (um)", "‖u‖rms (V)", "‖Δu‖rms (V)", "c_u"]
    # case1/nominal: PID e_rms 2 um, ARC 1 um; payload_light: 4 and 2 um (um, 3 significant digits)
    rms = lines[4].split("|")[2:6]
    assert [c.strip() for c in rms] == ["2", "1", "4", "2"]
    assert lines[2].split("|")[2].strip() == "20"  # PID e_M = 10 x 2 um


def test_diverged_cells_and_case2_without_fixed_scenarios(result):
    # case2 has no fixed scenario here: a header only
    assert table1_markdown(result, "case2", "V").count("\n") == 7
    mc = monte_carlo_summary(result)
    assert mc["n"] == 3 and mc["arc"]["diverged"] == 1 and mc["pid"]["diverged"] == 1
    assert mc["arc"]["e_rms"] == (pytest.approx(3e-6), pytest.approx(4e-6))  # median and worst of 4, 2 um
    assert mc["arc_better"] == 1  # mc/002 (PID diverged); mc/000 is worse, mc/001 diverged


def test_stdout_summary_lists_verdict_and_every_failure(result):
    text = summary_text(result)
    assert "case1/disturbance" in text and "mc worst of 3 (1 diverged)" in text
    fails = result.verdict.failures
    assert f"gate FAILED: {len(fails)} of {len(result.verdict.checks)} checks on 9 scenarios" in text
    for c in fails:
        assert f"{c.criterion} {c.scenario}: {c.detail}" in text
    # mc/000 worse than the PID, mc/001 diverged, and the Monte-Carlo quantiles (median 1.24, p90 inf)
    assert {c.scenario for c in fails} == {"mc/000", "mc/001", "monte_carlo"}
    assert verdict_text(result).count("\n") == len(fails)
