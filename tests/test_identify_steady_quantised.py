"""Constant-speed legs of one log whose velocity is quantised to 1 rpm (issue 21).

An EPOS recorder logs the motor speed in whole rpm at a slow sample period, and the
reader integrates it into the position (``commission.logs.epos``).  At 6.4 ms the
detector's 20 ms smoothing spans three samples, so a speed toggling between 1 and
2 rpm swings the smoothed velocity by up to a whole rpm: the legs at 1-2 rpm must
still be found, with the rest of the ladder, and their mean command must be the
friction at their speed.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.integrate import cumulative_trapezoid

from commission.identify import find_steady_segments, fit_axis, preprocess, quantization_step, stribeck_friction

RPM = math.pi / 30.0  # rad/s per rpm
H = 0.0064  # s, the recorder's sample period
SPEEDS = (1.0, 2.0, 5.0, 10.0, 20.0)  # rpm, each forward then backward
# u in % of rated torque, q in rad: J %·s²/rad, B %·s/rad, fc/fs/offset %, vs rad/s
TRUTH = dict(J=0.02, B=0.05, fc=2.0, fs=3.0, vs=3.0 * RPM, xi=2.0, offset=0.3)


def _friction(v: np.ndarray) -> np.ndarray:
    p = TRUTH
    return p["B"] * v + stribeck_friction(v, p["fc"], p["fs"], p["vs"], p["xi"]) + p["offset"]


def _log(seed: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(t, q, u)``: 1.5 s legs, 200 rpm/s ramps, 0.3 s rests; speed noise 0.3 rpm, rounded to whole rpm."""
    rng = np.random.default_rng(seed)
    parts = [np.zeros(int(0.3 / H))]
    for s in SPEEDS:
        n_ramp = max(2, math.ceil(s / 200.0 / H))
        ramp = np.arange(1, n_ramp + 1) / n_ramp * s
        for d in (1.0, -1.0):
            parts += [d * ramp, np.full(int(1.5 / H), d * s), d * ramp[::-1], np.zeros(int(0.3 / H))]
    v_ref = np.concatenate(parts) * RPM
    t = np.arange(v_ref.size) * H
    v = v_ref + 0.3 * RPM * rng.standard_normal(t.size)  # the true speed
    v_rec = np.rint(v / RPM) * RPM  # what the recorder stores
    q = np.concatenate([[0.0], cumulative_trapezoid(v_rec, t)])  # as commission.logs.epos integrates it
    u = TRUTH["J"] * np.gradient(v_ref, H) + _friction(v) + 0.05 * rng.standard_normal(t.size)
    return t, q, u


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_every_leg_of_a_1rpm_quantised_log(seed):
    t, q, u = _log(seed)
    pp = preprocess(t, q, u)
    quant = quantization_step(q)
    assert quant == pytest.approx(0.5 * RPM * H, rel=1e-6)  # trapezoid of whole rpm: half-rpm steps
    segs = find_steady_segments(pp.t, pp.q, pp.qd, pp.u, v_tol=quant / 0.02, v_quantum=quant * pp.sample_rate)
    want = np.sort(np.concatenate([SPEEDS, -np.asarray(SPEEDS)]))
    assert len(segs) == want.size
    np.testing.assert_allclose(np.sort(segs.velocity) / RPM, want, atol=0.5)
    assert np.all(segs.duration >= 1.0)  # each leg whole, not split
    np.testing.assert_allclose(segs.command, _friction(segs.velocity), rtol=0.02)


def test_single_log_fit_uses_the_whole_ladder():
    t, q, u = _log(0)
    fit = fit_axis(t, q, u, friction="stribeck", allow_unidentified_mass=True, velocity_logged=True)
    assert fit.method == "steady+dynamic"
    v = fit.steady_velocity
    assert v.size == 2 * len(SPEEDS)
    np.testing.assert_allclose(np.sort(np.abs(v)) / RPM, np.repeat(SPEEDS, 2), atol=0.5)
    p = {k: val for k, (val, _) in fit.parameters.items()}
    F_hat = p["B"] * v + stribeck_friction(v, p["fc"], p["fs"], p["vs"], p["xi"]) + p["offset"]
    np.testing.assert_allclose(F_hat, _friction(v), rtol=0.02)
    for name in ("B", "fc", "fs", "offset"):
        assert p[name] == pytest.approx(TRUTH[name], rel=0.05), name
