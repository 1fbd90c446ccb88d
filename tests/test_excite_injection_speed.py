"""`commission excite`: the injection rides on a cruise fast enough that friction keeps one sign.

Known answers: on a linear holding loop with one-signed friction the velocity the injection
adds to the cruise does not depend on the cruise, so a plan whose default cruise is slower than
that swing (the velocity would cross zero, and Coulomb friction would damp the modes the
injection is there to measure) gets a cruise at least as fast as the swing on the
pre-simulation's light model; a plan whose swing is small keeps the default cruise.  On a
known-truth axis with friction and a lightly damped motor-side mode, the mode identified from
the excite log is the truth's (random axis 517: the default slow cruise read its damping 2.7x
too high).
"""

from __future__ import annotations

import tomllib

import numpy as np
import pytest

from commission.excite import excite_spec_from_mapping, loop_gains_for, mass_bracket, plan_run, play
from commission.excite.plan import design_plan, injection_speed_bounds
from commission.excite.presim import _model_truth, injection_swing
from test_excite import SMALL

LIMITS = SMALL  # test_excite.py's axis: 1 kHz, 0.03 V s^2/m, 0.1 V of friction, a 30 Hz holding loop


def _light_swing(plan, spec) -> float:
    light = mass_bracket(spec)[0]
    return injection_swing(plan, play(plan, _model_truth(spec, light), loop_gains_for(spec, light)))


def _cruise(plan) -> float:
    return next(g for g in plan.segments if g.name == "injection").info["speed"]


def test_a_cruise_slower_than_the_injections_swing_is_raised_to_it():
    spec = excite_spec_from_mapping(tomllib.loads(LIMITS), "limits.toml")
    default, top = injection_speed_bounds(spec)
    first = design_plan(spec)
    assert _cruise(first) == pytest.approx(default)
    assert _light_swing(first, spec) > 2.0 * default  # the default cruise would reverse: the raise is needed
    plan = plan_run(spec)
    v = _cruise(plan)
    assert default < v <= top
    assert _light_swing(plan, spec) <= v * (1.0 + 1e-9)  # the velocity no longer crosses zero on the light model
    # every injection sample still sits on a cruise at that speed
    on = np.zeros(plan.t.size, bool)
    for a, b in next(g for g in plan.segments if g.name == "injection").info["windows_s"]:
        on |= (plan.t >= a) & (plan.t < b)
    assert np.allclose(np.abs(plan.v_ref[on]), v)
    assert np.all(plan.u_inject[~on & (plan.t > 1.0)] == 0.0)


def test_a_small_swing_keeps_the_default_cruise():
    spec = excite_spec_from_mapping(tomllib.loads(LIMITS.replace("n_speeds = 4", "n_speeds = 4\ninjection_fraction = 0.02")),
                                    "limits.toml")
    default, _ = injection_speed_bounds(spec)
    plan = plan_run(spec)
    assert _cruise(plan) == pytest.approx(default)
    assert _light_swing(plan, spec) <= default


@pytest.mark.slow
def test_the_mode_of_a_frictional_axis_is_identified_from_the_excite_log(tmp_path):
    from commission.identification import identify_log
    from commission.synth import random_axis, record_random_axis_log

    truth = random_axis(np.random.default_rng(517))  # 66 kg, Coulomb 1.2 V of 10, 271 Hz motor-side mode, zeta 0.018
    rec = record_random_axis_log(517, tmp_path / "log.h5")
    assert rec.log == "excite", rec.note
    model = identify_log(str(tmp_path / "log.h5")).ident.to_dict()["frequency_response"]["model"]
    assert model["mode_hz"] == pytest.approx(truth.mode_hz, rel=0.01)
    assert model["mode_damping"] == pytest.approx(truth.mode_damping, rel=0.15)
    assert not model["mode_load_side"]
