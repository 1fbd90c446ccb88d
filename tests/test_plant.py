import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from commission.controllers.plant import plant_advance, plant_vector, stribeck, stribeck_cut


def test_free_mass_matches_closed_form():
    # No friction: x(t) = 0.5 u/M t^2 exactly up to the O(h) integrator error.
    p = plant_vector(M=2.0, B=0.0, fc=0.0)
    x, v = plant_advance(p, 0.0, 0.0, 1.0, 1e-5, 100_000)
    assert math.isclose(v, 0.5, rel_tol=1e-9)
    assert math.isclose(x, 0.25, rel_tol=1e-4)


def test_viscous_decay_matches_exponential():
    p = plant_vector(M=1.0, B=4.0, fc=0.0)
    x, v = plant_advance(p, 0.0, 1.0, 0.0, 1e-6, 500_000)
    assert math.isclose(v, math.exp(-2.0), rel_tol=1e-4)
    assert math.isclose(x, (1 - math.exp(-2.0)) / 4.0, rel_tol=1e-4)


def test_stiction_holds_below_static_level_and_breaks_above():
    p = plant_vector(M=1.0, B=0.1, fc=0.1, fs=0.2, vs=0.01)
    x, v = plant_advance(p, 0.0, 0.0, 0.19, 1e-5, 10_000)
    assert x == 0.0 and v == 0.0
    x, v = plant_advance(p, 0.0, 0.0, -0.21, 1e-5, 10_000)
    assert v < 0.0 and x < 0.0


def test_coulomb_stop_lands_at_rest_without_reversal():
    # A sliding mass with no input stops in time v0 / (fc/M) (closed form)
    # and stays stopped: no chattering reversal.
    p = plant_vector(M=1.0, B=0.0, fc=0.5, fs=0.5)
    h = 1e-5
    x, v = plant_advance(p, 0.0, 1.0, 0.0, h, 300_000)
    assert v == 0.0
    assert math.isclose(x, 1.0 / (2 * 0.5), rel_tol=1e-3)


def test_reversal_under_constant_force():
    # Moving left against a constant push to the right: stops, then slides right.
    p = plant_vector(M=1.0, B=0.0, fc=0.1, fs=0.2)
    x, v = plant_advance(p, 0.0, -0.1, 1.0, 1e-5, 100_000)
    assert v > 0.0
    # Decelerates at (1+0.1) until v=0 then accelerates at (1-0.1) for the rest of 1 s.
    t_stop = 0.1 / 1.1
    assert math.isclose(v, 0.9 * (1.0 - t_stop), rel_tol=1e-3)


@settings(max_examples=300, deadline=None)
@given(fc=st.floats(1e-4, 10.0), ratio=st.floats(0.2, 5.0), vs=st.floats(1e-4, 0.1),
       xi=st.one_of(st.just(1.0), st.just(2.0), st.floats(0.3, 4.0)), v=st.floats(-5.0, 5.0))
def test_stribeck_shortcuts_give_the_formula_to_the_last_bit(fc, ratio, vs, xi, v):
    """The skipped curve above stribeck_cut and the squared exponent equal the plain formula exactly."""
    p = plant_vector(M=1.0, B=0.0, fc=fc, fs=fc * ratio, vs=vs, xi=xi)
    plain = 0.0 if v == 0.0 else math.copysign(fc + (fc * ratio - fc) * math.exp(-abs(v / vs) ** xi), v)
    assert stribeck(p, v, stribeck_cut(p)) == plain
    assert stribeck(p, v) == plain


def test_stribeck_cut_is_where_the_curve_drops_below_the_last_bit():
    p = plant_vector(M=1.0, B=0.0, fc=0.1, fs=0.12, vs=0.01, xi=2.0)
    cut = stribeck_cut(p)
    # (fs - fc) exp(-(v/vs)^2) = 2^-60 fc  <=>  v = vs sqrt(ln(0.2) + 60 ln 2)
    assert cut == pytest.approx(0.01 * math.sqrt(math.log(0.2) + 60 * math.log(2.0)), rel=1e-9)
    assert stribeck_cut(plant_vector(M=1.0, B=0.0, fc=0.1)) == 0.0  # Coulomb only
    assert stribeck_cut(plant_vector(M=1.0, B=0.0, fc=0.0, fs=0.1)) == math.inf  # no Coulomb level to round to


def _zoh_response(p, u, Ts):
    """Encoder position under the held inputs ``u`` from the exact ZOH discretisation of the linear model."""
    from scipy.linalg import expm

    from commission.controllers.linear import continuous_model
    A, B, C = continuous_model(p)
    n = A.shape[0]
    aug = np.zeros((n + 1, n + 1))
    aug[:n, :n], aug[:n, n:] = A * Ts, B * Ts
    E = expm(aug)
    Ad, Bd = E[:n, :n], E[:n, n:]
    x = np.zeros(n)
    y = np.empty(len(u))
    for k, uk in enumerate(u):
        x = Ad @ x + Bd[:, 0] * uk
        y[k] = (C @ x)[0]
    return y


@pytest.mark.parametrize("encoder", ["motor", "load", "load2"])
def test_two_mode_plant_matches_its_exact_linear_discretisation(encoder):
    # Friction-free, the sub-stepped integrator must reproduce the linear model's exact ZOH response
    # (an independent computation: matrix exponential of the continuous model) to the integrator's error.
    from commission.controllers.plant import NX, plant_output, plant_start, plant_step
    p = plant_vector(0.8, 2.0, mode_hz=450.0, mode_damping=0.05, mode_ratio=0.3, mode_load_side=encoder == "load",
                     mode2_hz=1000.0, mode2_damping=0.03, mode2_ratio=0.08, mode2_load_side=encoder == "load2")
    Ts = 1.0 / 5000.0
    rng = np.random.default_rng(3)
    u = rng.normal(0.0, 1.0, 500)
    st = np.empty(NX)
    plant_start(p, st, 0.0)
    y = np.empty(len(u))
    for k, uk in enumerate(u):
        plant_step(p, st, uk, Ts / 10, 10)
        y[k] = plant_output(p, st)
    ref = _zoh_response(p, u, Ts)
    assert np.max(np.abs(y - ref)) < 2e-3 * np.max(np.abs(ref))
    if encoder == "load2":  # the bracket's own motion differs visibly from the motor side's
        p_motor = p.copy()
        p_motor[17] = 0.0
        steps = np.diff(ref)
        assert np.max(np.abs(steps - np.diff(_zoh_response(p_motor, u, Ts)))) > 1e-2 * np.max(np.abs(steps))


def test_structural_modes_are_the_two_mass_closed_form_and_shift_when_coupled():
    from commission.controllers.linear import structural_modes
    # One mode, no viscous loss: the free-free mode is exactly mode_hz with damping zeta.
    (f1, z1), = structural_modes(plant_vector(1.0, 0.0, mode_hz=500.0, mode_damping=0.04, mode_ratio=0.3))
    assert f1 == pytest.approx(500.0, rel=1e-9) and z1 == pytest.approx(0.04, rel=1e-9)
    two = structural_modes(plant_vector(1.0, 0.0, mode_hz=450.0, mode_damping=0.04, mode_ratio=0.3,
                                        mode2_hz=1000.0, mode2_damping=0.03, mode2_ratio=0.05))
    assert len(two) == 2
    assert two[0][0] == pytest.approx(450.0, rel=0.05) and two[1][0] == pytest.approx(1000.0, rel=0.05)
    assert two[0][0] != pytest.approx(450.0, rel=1e-6)  # coupled through the motor: shifted, not equal


@pytest.mark.parametrize("kw", [dict(mode2_hz=800.0),  # a second mode without a first
                                dict(mode_hz=400.0, mode_ratio=0.6, mode2_hz=800.0, mode2_ratio=0.4),
                                dict(mode_hz=400.0, mode2_hz=800.0, mode2_damping=1.0),
                                dict(mode_hz=400.0, mode2_hz=float("inf"))])
def test_second_mode_is_refused_outside_its_domain(kw):
    with pytest.raises(ValueError, match="second mode"):
        plant_vector(1.0, 1.0, **kw)


def _ripple_reference(M, A, pitch, x, v, h, n, mode=None):
    """The plant's semi-implicit Euler steps written out with the plain ``A sin(2 pi x / pitch)``.

    No input, friction-free (``fc = fs = 0``: no stick decision can hinge on rounding), from
    the motor and any load at ``x`` moving at ``v``.  ``mode``: ``(f_r, zeta, r)`` of a load,
    integrated on the kernel's split grid (``2 pi f_r h / split <= 0.25``).  Returns the motor's
    position (m) and velocity (m/s) after ``n`` steps of ``h`` seconds.
    """
    if mode is None:
        for _ in range(n):
            v += -A * math.sin(2.0 * math.pi * x / pitch) / M * h
            x += v * h
        return x, v
    f, z, r = mode
    m1, m2 = (1.0 - r) * M, r * M
    mu = (1.0 - r) * M * m2 / M
    w = 2.0 * math.pi * f
    k, c = w * w * mu, 2.0 * z * w * mu
    split = max(1, math.ceil(w * h / 0.25))
    hh = h / split
    x2, v2 = x, v
    for _ in range(n * split):
        fk = k * (x - x2) + c * (v - v2)
        v1n = v + (-A * math.sin(2.0 * math.pi * x / pitch) - fk) / m1 * hh
        v2 = v2 + fk / m2 * hh
        v = v1n
        x += v * hh
        x2 += v2 * hh
    return x, v


@pytest.mark.parametrize("pitch, speed", [(0.03, 0.4), (0.0025, 1.5), (0.05, -0.02)])
@pytest.mark.parametrize("mode", [None, (480.0, 0.04, 0.4)])
def test_force_ripple_is_the_plain_sine_along_many_pitches(pitch, speed, mode):
    """The kernel's ripple is ``A sin(2 pi x / pitch)`` on every sub-step, sample after sample.

    Against the same integrator written out here with the plain sine (a faster evaluation of the
    ripple must keep this), positions agree to 1e-11 of the travel after 2,000 samples (the fast
    axis crosses hundreds of pitches, the slow one a fraction of one), on a rigid plant and on one with a structural mode.  The frictionless
    rigid axis also keeps its energy ``M v^2 / 2 - A pitch / (2 pi) cos(2 pi x / pitch)`` to the
    integrator's O(h), which a ripple of the wrong sign or pitch would not; and the ripple
    really acts: the speed swings by the amount that energy balance gives.
    """
    from commission.controllers.plant import NX, V_LOAD, V_MOTOR, X_MOTOR, plant_start, plant_step
    M, h, n_sub, x0, n = 0.8, 1e-4 / 8, 8, 0.0137, 2000
    A = 0.4 * M * speed ** 2 * math.pi / pitch  # the ripple's potential swing is 0.8 of the kinetic energy
    kw = {} if mode is None else dict(mode_hz=mode[0], mode_damping=mode[1], mode_ratio=mode[2])
    p = plant_vector(M, 0.0, 0.0, 0.0, ripple_amp=A, ripple_pitch=pitch, **kw)
    st = np.empty(NX)
    plant_start(p, st, x0)
    st[V_MOTOR] = st[V_LOAD] = speed
    energy, speeds = [], []
    for _ in range(n):
        plant_step(p, st, 0.0, h, n_sub)
        energy.append(0.5 * M * st[V_MOTOR] ** 2 - A * pitch / (2 * math.pi) * math.cos(2 * math.pi * st[X_MOTOR] / pitch))
        speeds.append(st[V_MOTOR])
    x_ref, v_ref = _ripple_reference(M, A, pitch, x0, speed, h, n * n_sub, mode)
    travel = abs(st[X_MOTOR] - x0)
    assert abs(st[X_MOTOR] - x_ref) <= 1e-11 * max(travel, pitch)
    assert abs(st[V_MOTOR] - v_ref) <= 1e-11 * abs(speed)
    if mode is None:
        e = np.asarray(energy)
        assert np.ptp(e) <= 5e-2 * 0.5 * M * speed ** 2  # O(h): 2 % at 600 Hz of ripple on this grid
        if travel > pitch:  # crossed a whole pitch: the speed swung through the ripple's potential
            assert np.ptp(speeds) > 0.3 * abs(speed)


def test_the_anchored_ripple_is_the_closed_form_along_a_run():
    """The simulator rotates the ripple from an anchor it keeps in the state (module docstring of
    commission.controllers.plant) instead of taking a sin at every sub-step.  Along a walk like a
    run's (sub-step moves from nanometres to a tenth of the pitch, both ways, over a 1 m travel),
    every value equals A_r sin(2 pi x / pitch) to the rounding of that argument itself."""
    from commission.controllers.plant import NX, X_ANCHOR, ripple, ripple_anchored

    rng = np.random.default_rng(7)
    for pitch in (0.0023, 0.03, 0.2):
        p = plant_vector(M=1.0, B=0.0, ripple_amp=0.37, ripple_pitch=pitch)
        kr = 2.0 * math.pi / pitch
        st = np.empty(NX)
        st[X_ANCHOR] = math.nan
        x, worst, moved = 0.0, 0.0, 0
        for _ in range(20000):
            x += rng.choice([1e-9, 1e-6, 1e-4 * pitch, 0.1 * pitch]) * rng.choice([-1.0, 1.0])
            x = min(max(x, -0.5), 0.5)
            a = st[X_ANCHOR]
            got = ripple_anchored(p, st, x, kr)
            moved += st[X_ANCHOR] != a
            tol = 0.37 * (8 * np.spacing(abs(kr * x)) + 8 * np.finfo(float).eps)
            worst = max(worst, abs(got - ripple(p, x)) / tol)
        assert worst <= 1.0, (pitch, worst)
        assert 100 < moved < 20000  # both paths taken: rotated, and re-anchored beyond the phase bound


def test_plant_step_and_plant_advance_are_one_integrator():
    """A rigid plant's plant_step (anchor kept across calls) and plant_advance (anchor per call) give
    the same motion to rounding over a second of stick-slip under a ripple."""
    from commission.controllers.plant import NX, plant_start, plant_step

    p = plant_vector(M=0.027, B=0.273, fc=0.1, fs=0.12, vs=0.01, ripple_amp=0.01, ripple_pitch=0.03)
    st = np.empty(NX)
    plant_start(p, st, 0.0)
    x, v = 0.0, 0.0
    for k in range(2500):
        u = 0.2 * np.sin(2 * np.pi * 3.0 * k / 2500)
        plant_step(p, st, u, 4e-5, 10)
        x, v = plant_advance(p, x, v, u, 4e-5, 10)
    assert abs(st[0]) > 1e-4  # it moved
    assert st[0] == pytest.approx(x, rel=1e-6, abs=1e-9) and st[1] == pytest.approx(v, rel=1e-5, abs=1e-7)


def _pair_plants():
    """Rigid (Stribeck with ripple; Coulomb only; no friction), one mode (load- and motor-side encoder,
    at two splits), two modes: every kind plant_step_pair interleaves, and pairs it must not."""
    return {
        "rigid ripple": plant_vector(M=0.027, B=0.273, fc=0.1, fs=0.12, vs=0.01, ripple_amp=0.01, ripple_pitch=0.03),
        "rigid coulomb": plant_vector(M=0.08, B=0.5, fc=0.15, offset=0.02),
        "rigid frictionless": plant_vector(M=0.05, B=0.0),
        "mode load": plant_vector(M=0.03, B=0.3, fc=0.1, fs=0.12, ripple_amp=0.01, ripple_pitch=0.02,
                                  mode_hz=500.0, mode_damping=0.04, mode_ratio=0.4, mode_load_side=True),
        "mode motor": plant_vector(M=0.5, B=2.0, fc=0.3, fs=0.35, mode_hz=700.0, mode_damping=0.06, mode_ratio=0.3),
        "mode split 3": plant_vector(M=0.03, B=0.3, fc=0.1, mode_hz=2500.0, mode_damping=0.05, mode_ratio=0.5),
        "two modes": plant_vector(M=0.04, B=0.3, fc=0.1, fs=0.13, mode_hz=400.0, mode_damping=0.05, mode_ratio=0.3,
                                  mode2_hz=900.0, mode2_damping=0.03, mode2_ratio=0.1, mode2_load_side=True),
    }


def test_plant_step_pair_is_the_two_plant_steps_to_the_last_bit():
    """Two plants advanced together (interleaved when both rigid or both modal with one split, else one
    after the other) end every call where two plant_step calls do, bit for bit, through stick-slip,
    reversals and different sub-step lengths."""
    from commission.controllers.plant import NX, plant_start, plant_step, plant_step_pair, plant_steps

    plants = _pair_plants()
    h = 4e-5
    splits = {plant_steps(p, h) for p in plants.values()}
    assert {0, 1} < splits and max(splits) > 1  # rigid, modal at split 1 and at a larger split
    names = list(plants)
    stuck = 0
    for a in names:
        for b in names:
            pa, pb = plants[a], plants[b]
            sa, sb, ra, rb = (np.zeros(NX) for _ in range(4))  # the anchor slots a plant without ripple never writes: equal
            for s, p in ((sa, pa), (sb, pb), (ra, pa), (rb, pb)):
                plant_start(p, s, 0.001)
            for k in range(1500):
                ua = 0.6 * math.sin(2 * math.pi * 2.0 * k / 2500) + 0.01 * (k % 7 - 3)  # sticks near the turns
                ub = -0.4 * math.sin(2 * math.pi * 3.0 * k / 2500)
                hb = h * (1.0 + 0.25 * (k % 2))  # the two plants' sub-steps need not be equal
                plant_step_pair(pa, sa, ua, h, pb, sb, ub, hb, 10, -1.0, -1.0)
                plant_step(pa, ra, ua, h, 10)
                plant_step(pb, rb, ub, hb, 10)
                assert np.array_equal(sa, ra, equal_nan=True) and np.array_equal(sb, rb, equal_nan=True), (a, b, k)
                stuck += ra[1] == 0.0
            assert abs(sa[0] - 0.001) > 1e-5 and abs(sb[0] - 0.001) > 1e-5, (a, b)  # both moved
    assert stuck > 100  # and stood still at times (the stiction branch)
