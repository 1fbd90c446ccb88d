"""MUST SHOW 2: axes not in the repository: simulated log -> identify -> tune -> validate's default gate.

Each axis is drawn by :func:`commission.synth.random_axis` (known truth, not used
by the pipeline), its commissioning log simulated and written as HDF5, then the
product identifies it, tunes it with the default spec (sample rate = the log's;
the envelope's defaults lowered to what the +-10 V drive can move on the box's most
demanding plant, :func:`commission.tune.default_envelope`) and validates the tuning
against :mod:`commission.gate`'s defaults on the full matrix (12 fixed scenarios +
64 Monte-Carlo plants).

Measured (seed 0 of the search and of the Monte-Carlo sample), session 3: axes 2
(2 kHz, envelope scaled to 0.8 m/s, 7.7 m/s^2), 3 (5 kHz), 5 (4 kHz, envelope lowered to
0.24 m/s, 4.8 m/s^2), 6 (5 kHz), 7 (2 kHz, 0.44 m/s, 7.7 m/s^2), 8 (5 kHz) and 12
(2.5 kHz) pass every criterion on every scenario.  Axis 12 is the case of the interior
payloads (:func:`commission.scenarios.payload_scenarios`): before the tuning set had
them, its theta1 estimate drifted to the box's light end on a x1.9 payload and the ARC
lost to the PID by 19x there.

Axis 4 (1 kHz, M = 0.17 V s^2/m, stiction 1.1 V) is the case of a heavy axis with high
friction: identify's default load-force bound (10 x stiction = 11 V on a 10 V drive) used
to get it refused with exit 2.  tune now narrows that *defaulted* bound to half of the
drive's feedforward budget (:func:`commission.tune.fit_disturbance_to_drive`), and it
passes (session 4; so do axes 9, 10, 13, refused before for the same reason).

Axis 19 (4 kHz, M = 0.035 V s^2/m, 0.78 um encoder) is a light axis on a coarse encoder
(:func:`test_a_light_axis_on_a_coarse_encoder_passes_the_gate`): it failed one c_u check
(1.11) until the search's step stopped shrinking at :data:`commission.tune.STEP_FLOOR`
(session 7).

Axis 27 (4 kHz, 0.84 um encoder) is the case of a PID baseline that chatters beyond the
gate by itself at the defaulted pole (c_u 1.17 at 480 rad/s): tune now compares with the
fastest PID of the paper's family that meets the gate's c_u
(:func:`commission.tune.deployable_pid`), and the ARC tuned against it passes (session 8).

Axis 11 (1 kHz) was the case of a search whose best candidates fail the gate on tune's
hold-out plants (session 9).  Since the eta filter interpolates y between samples
(session 12), its first 96 candidates pass there; the continued search is now tested on
axis 16 (:func:`test_a_search_whose_best_fail_the_holdout_continues`), which still
continues by 40 candidates and then repairs.

Every one of seeds 0-29 passes, session 12 (``python benchmarks/sweep_random_axes.py
--seeds 0-29``).  The last to pass was axis 16, a light axis on a 0.55 um encoder at
5 kHz where both controllers track within an encoder step: it failed one check, c_u 1.04
on case1/friction_low (its PID baseline reaches 0.97 there), until the repair's first
round became a line search that lowers the caps
(:func:`test_a_search_whose_best_fail_the_holdout_continues`).  Until session 12, with
the eta filter holding y over the sample, 28 passed: axis 0 failed one ARC-vs-PID check
and 16 failed 12 (10 c_u, 2 ARC-vs-PID).  Holding y lagged eta by half a sample, which
left a direction-dependent offset of +-1.06 encoder steps in every Case-2 cruise on
axis 16.
"""

from __future__ import annotations

import numpy as np
import pytest

from commission.gate import GateSpec
from commission.identification import identify_log
from commission.jsonio import write_json_atomic
from commission.synth import write_random_axis_log
from commission.tune import run_tune
from commission.validate import validate

pytestmark = pytest.mark.slow


def _pipeline(seed: int, tmp_path_factory):
    """Simulate axis ``seed``'s log, identify, tune (seed 0), validate (seed 0)."""
    d = tmp_path_factory.mktemp(f"axis{seed}")
    truth = write_random_axis_log(seed, d / "log.h5")
    ident = identify_log(str(d / "log.h5")).ident
    write_json_atomic(d / "ident.json", ident.to_dict())
    tuning = run_tune(d / "ident.json", d / "tuning.json", seed=0)
    return truth, tuning, validate(tuning, GateSpec(), seed=0), seed


@pytest.fixture(scope="module", params=[2, 3, 4, 7, 8, 12],
                ids=["axis2-2kHz", "axis3-5kHz", "axis4-1kHz-load-narrowed", "axis7-2kHz-heavy", "axis8-5kHz",
                     "axis12-payload-drift"])
def validated(request, tmp_path_factory):
    return _pipeline(request.param, tmp_path_factory)


@pytest.mark.parametrize("seed", [19, 27, 0], ids=["axis19-4kHz-0.78um", "axis27-4kHz-0.84um-pid-lowered",
                                                  "axis0-4kHz-0.82um-pid-lowered"])
def test_a_light_axis_on_a_coarse_encoder_passes_the_gate(seed, tmp_path_factory):
    """Axes 19, 27 and 0 (module docstring): the default gate passes, c_u included.

    Both controllers track within an encoder step here, so the ARC is level with the PID
    (axis 19: median e_rms ratio 1.03 over the matrix, session 7) rather than better on most
    of it: the median check of :func:`test_arc_vs_pid_on_the_matrix` does not apply, the
    gate's comparison (within the quantization noise of the PID, scenario by scenario) does.
    On axes 27 and 0 the defaulted PID pole (480 rad/s) chatters beyond the gate's c_u by
    itself, so the baseline runs lower (axis 0: 391 rad/s), and within that limit on every
    tuning scenario; on axis 19 it does not, and the pole is kept.  Axis 0 passes since
    session 12 (with eta holding y it failed one ARC-vs-PID check, module docstring).
    """
    truth, tuning, result, _ = _pipeline(seed, tmp_path_factory)
    assert tuning.spec.sample_rate == pytest.approx(truth.sample_rate, rel=1e-6)
    assert result.passed, [f.detail for f in result.verdict.failures]
    moved = tuning.pid_pole < tuning.spec.pid_pole
    assert moved == (seed in (27, 0))
    if moved:
        assert max(r["pid"].c_u for r in tuning.scores.values()) <= 1.0


def test_a_search_whose_best_fail_the_holdout_continues(tmp_path_factory):
    """Axis 16 (5 kHz, 0.55 um encoder; module docstring): the search continues, then repairs.

    The best of the first 96 candidates fail the default gate on tune's hold-out plants,
    so the defaulted search continues by 40 candidates
    (:func:`commission.tune.search_extension`: the light 4-5 kHz axes fill the slowest
    default search's work with 40); the best of the 136 still fail there (c_u 1.04 on
    case1/friction_low, where the PID reaches 0.97), so the repair runs.  Its first round
    lowers the caps (:data:`commission.tune.REPAIR_CAP_FACTORS`): the k2 cap /1.05 clears
    the hold-out, and validate's gate then passes.  (Until session 12 this test ran axis 11,
    whose search no longer needs to continue.)
    """
    _, tuning, result, _ = _pipeline(16, tmp_path_factory)
    se = tuning.search
    assert (se.budget, se.extension, se.n_evaluations) == (96, 40, 136)
    assert min(se.holdout_failures) > 0
    assert se.repair_failures == 0 and se.repair_moves[0] == "k2 /1.05"
    assert result.passed, [f.detail for f in result.verdict.failures]


def test_tuning_uses_the_logs_rate_and_is_feasible(validated):
    truth, tuning, _, _ = validated
    assert tuning.spec.sample_rate == pytest.approx(truth.sample_rate, rel=1e-6)
    assert tuning.theorem1.holds and tuning.feasibility["arc"].holds


def test_the_default_gate_passes(validated):
    _, _, result, _ = validated
    # 12 fixed, one more sample of delay on each trajectory (the advisory robustness runs), 64 Monte-Carlo
    assert len(result.runs) == 12 + 2 + 64
    assert result.passed, [f.detail for f in result.verdict.failures]


def test_arc_vs_pid_on_the_matrix(validated):
    _, _, result, _ = validated
    slack = result.verdict.limits.arc_vs_pid_slack
    runs = [r for r in result.runs if "robustness" not in r.tags]  # the gated matrix (robustness is advisory)
    # no worse than the PID anywhere beyond the quantization noise (the gate), and better on most of the matrix
    assert all(r.arc.e_rms <= r.pid.e_rms + slack for r in runs)
    assert np.median([r.arc.e_rms / r.pid.e_rms for r in runs]) < 0.85


def test_only_a_defaulted_load_bound_that_leaves_no_envelope_is_narrowed(validated):
    _, tuning, _, seed = validated
    bounds = tuning.identification.extra["bounds"]
    assert bounds["disturbance_bound_defaulted"] is True  # none of these logs was given --disturbance-bound
    narrowed = bounds.get("narrowed_by_tune")
    assert (narrowed is not None) == (seed == 4)
    if narrowed is not None:
        # the box tune designed for (and validate tested) lies inside identify's
        assert narrowed["theta3_min"] < tuning.identification.theta.min[2] < 0 < tuning.identification.theta.max[2]
        assert tuning.identification.theta.max[2] < narrowed["theta3_max"]
