"""Stability margins and the plant dynamics the rigid model lacks (structural mode, input delay).

The margins are computed from a linearisation of the compiled controller step
on the exactly sampled linear plant; every figure is checked against the
project's nonlinear closed-loop simulator (sub-stepped plant, compiled step),
which shares none of that linear algebra.

The paper's experimental fact (sec. 4): on the real stage the PID of (57) works
with its closed-loop poles at -300 rad/s and is unstable at -320 rad/s.  The
test axis below reproduces it with a load-side structural mode on the CONTRACT
sec. 5 reference plant; its frequency (479 Hz at damping 0.07, load fraction
0.3) was chosen once so that the linear loop loses stability near 310 rad/s,
and the tests check both sides in the simulator.
"""

import dataclasses
import math

import numpy as np
import pytest
from scipy.signal import cont2discrete, ss2tf

from commission.controllers.arc import arc_pack, arc_step, paper_gains_implementable
from commission.controllers.linear import continuous_model, discrete_response, sampled_plant
from commission.controllers.margins import (arc_operating_point, closed_loop_radius, frequency_grid, linearize_arc,
                                            linearize_pid, loop_margins)
from commission.controllers.pid import pid_pack, pid_place_poles
from commission.controllers.plant import (NX, P_B, P_DELAY, P_FC, P_FS, P_M, P_OFFSET, P_RIPPLE_AMP, plant_output,
                                          plant_start, plant_step, plant_vector)
from commission.controllers.simulate import KIND_ARC, KIND_PID, simulate
from commission.controllers.trajectory import Trajectory, sample_grid
from commission.paper import paper_pid_gains, reference_plant, scenario

TS = 1.0 / 2500.0
MODE = dict(mode_hz=479.0, mode_damping=0.07, mode_ratio=0.3, mode_load_side=True)


def paper_axis_with_mode(M=0.027):
    """The CONTRACT sec. 5 plant (Stribeck friction, ripple) with the load-side mode."""
    return reference_plant(M, **MODE)


def pid_at(pole, fric=True):
    Kp, Ki, Kd = pid_place_poles(0.02, -pole)
    g = dataclasses.replace(paper_pid_gains(TS), Kp=Kp, Ki=Ki, Kd=Kd)
    return g if fric else dataclasses.replace(g, fric_level=0.0)


# --------------------------------------------------------------------------- the sampled plant


def test_zero_delay_sampling_equals_scipy_cont2discrete():
    p = plant_vector(0.027, 0.273, **MODE)
    A, B, C = continuous_model(p)
    Ad, Bd, *_ = cont2discrete((A, B, C, np.zeros((1, 1))), TS, method="zoh")
    sp = sampled_plant(p, TS)
    assert np.allclose(sp.Phi, Ad, rtol=1e-12, atol=1e-15) and np.allclose(sp.G0, Bd, rtol=1e-12, atol=1e-18)
    assert sp.n == 0 and not sp.G1.any()


@pytest.mark.parametrize("kw", [{}, MODE, {**MODE, "mode_load_side": False}])
@pytest.mark.parametrize("delay", [0.0, 0.37, 1.6])
def test_sampled_plant_matches_the_finely_integrated_plant_kernel(kw, delay):
    """u_k -> y_k of the linear realisation against the plant kernel at 2000 sub-steps a sample."""
    p = plant_vector(0.027, 0.273, **kw, delay=delay * TS)
    A, B, C = sampled_plant(p, TS).state_space()
    u = np.random.default_rng(0).normal(size=300)
    x = np.zeros(A.shape[0])
    y_lin = np.empty(u.size)
    for k in range(u.size):
        y_lin[k] = (C @ x)[0]
        x = A @ x + B[:, 0] * u[k]
    st = np.zeros(NX)
    plant_start(p, st, 0.0)
    n, f = int(math.floor(delay)), delay - math.floor(delay)
    y = np.empty(u.size)
    for k in range(u.size):
        y[k] = plant_output(p, st)
        early = u[k - n - 1] if k >= n + 1 else 0.0
        late = u[k - n] if k >= n else 0.0
        if f > 0:
            plant_step(p, st, early, f * TS / 2000, 2000)
        plant_step(p, st, late, (1 - f) * TS / 2000, 2000)
    assert np.max(np.abs(y - y_lin)) < 2e-5 * np.max(np.abs(y_lin))


def _continuous_response(p, f):
    A, B, C = continuous_model(p)
    return np.array([(C @ np.linalg.solve(2j * np.pi * fi * np.eye(A.shape[0]) - A, B))[0, 0] for fi in f])


def test_mode_model_has_its_closed_form_resonance_and_anti_resonance():
    """Load side: |G / G_rigid| peaks at f_r with 1/(2 zeta) (light damping); motor side: zeros at f_r sqrt(1 - r)."""
    f = np.linspace(300, 700, 4001)
    rigid = _continuous_response(plant_vector(0.027, 0.273), f)
    load = np.abs(_continuous_response(plant_vector(0.027, 0.273, **MODE), f) / rigid)
    assert f[np.argmax(load)] == pytest.approx(479.0, rel=0.01)  # the damping moves the peak 0.5 % down
    assert load.max() == pytest.approx(math.sqrt(1 + 4 * 0.07 ** 2) / (2 * 0.07), rel=0.02)
    A, B, C = continuous_model(plant_vector(0.027, 0.273, **{**MODE, "mode_load_side": False}))
    num, den = ss2tf(A, B, C, np.zeros((1, 1)))
    c = num[0]
    zeros = np.roots(c[np.argmax(np.abs(c) > 1e-9 * np.abs(c).max()):])  # drop round-off leading terms
    assert np.abs(zeros) == pytest.approx([2 * np.pi * 479.0 * math.sqrt(0.7)] * 2, rel=1e-9)
    poles = np.roots(den)
    assert np.sort(np.abs(poles))[-1] == pytest.approx(2 * np.pi * 479.0, rel=0.01)  # B on the motor side moves it


# --------------------------------------------------------------------------- linearisation


def test_linearised_arc_reproduces_the_compiled_steps_small_signal_response():
    p = arc_pack(paper_gains_implementable(TS))
    lin = linearize_arc(p, (30.0, 10.0, 0.0))
    # the nonlinear step from the same operating point, driven by a 1 nm sequence
    q, s = arc_operating_point(p, (30.0, 10.0, 0.0))
    c0 = arc_step(q, s.copy(), 0.0, 0.0, 0.0, 0.0)
    ys = 1e-9 * np.sin(0.3 * np.arange(200))
    c_nl = np.empty(ys.size)
    for k, y in enumerate(ys):
        c_nl[k] = arc_step(q, s, y, 0.0, 0.0, 0.0)
    xc = np.zeros(lin.Ac.shape[0])
    c_lin = np.empty(ys.size)
    for k, y in enumerate(ys):
        c_lin[k] = (lin.Cc @ xc)[0] + lin.Dc * y
        xc = lin.Ac @ xc + lin.Bc[:, 0] * y
    assert abs(c0) < 1e-12  # at rest the command is zero: the response is the deviation
    assert np.max(np.abs(c_nl - c_lin)) < 1e-4 * np.max(np.abs(c_lin))


def _dense_response(A, B, C, D, Ts, f):
    """The definition, one dense LU per frequency (what discrete_response must equal)."""
    z = np.exp(1j * 2 * np.pi * f * Ts)
    x = np.linalg.solve(z[:, None, None] * np.eye(A.shape[0]) - A, np.broadcast_to(B.astype(complex), (z.size, *B.shape)))
    return x[:, :, 0] @ C[0] + D


@pytest.mark.parametrize("theta", [(30.0, 10.0, 0.0), (8.3, 17.5, 50.0)])
def test_frequency_response_of_the_badly_scaled_linearised_arc_equals_a_dense_solve(theta):
    """The balanced Schur evaluation against the definition on the linearised ARC (states fifteen
    decades apart, near-repeated poles at z = 1) and on the sampled mode plant."""
    lin = linearize_arc(arc_pack(paper_gains_implementable(TS)), theta)
    f = frequency_grid(TS)
    ref = _dense_response(lin.Ac, lin.Bc, lin.Cc, lin.Dc, TS, f)
    np.testing.assert_allclose(lin.frequency_response(f), ref, rtol=1e-9)
    p = paper_axis_with_mode()
    p[P_DELAY] = 1.4 * TS
    sp = sampled_plant(p, TS)
    A, B, C = sp.state_space()
    np.testing.assert_allclose(sp.frequency_response(f), _dense_response(A, B, C, 0.0, TS, f), rtol=1e-9)
    # the compiled back-substitution (the controllers' path) on the plant too, and the array form on the ARC
    np.testing.assert_allclose(discrete_response(A, B, C, 0.0, TS, f, compiled=True),
                               _dense_response(A, B, C, 0.0, TS, f), rtol=1e-9)
    np.testing.assert_allclose(discrete_response(lin.Ac, lin.Bc, lin.Cc, lin.Dc, TS, f, compiled=False), ref, rtol=1e-9)


# --------------------------------------------------------------------------- the paper's fact


def test_paper_fact_pid_at_300_is_stable_and_at_320_oscillates_in_the_simulator():
    sc = scenario("set1")
    p = paper_axis_with_mode()
    late = {}
    for pole in (300.0, 320.0):
        r = simulate(p, KIND_PID, pid_pack(pid_at(pole)), sc.traj, quant=1e-6, u_sat=10.0, e_abort=0.01)
        assert not r.diverged
        e = r.y - r.qd
        late[pole] = float(np.sqrt(np.mean(e[-2500:] ** 2)))
    # measured: 3.7 um at -300 rad/s, 157 um (a limit cycle at the rail) at -320 rad/s
    assert late[300.0] < 10e-6
    assert late[320.0] > 50e-6


def test_paper_fact_margins_are_positive_at_300_and_cross_zero_before_320():
    sp = sampled_plant(paper_axis_with_mode(), TS)
    m300 = loop_margins(linearize_pid(pid_pack(pid_at(300.0))), sp)
    m320 = loop_margins(linearize_pid(pid_pack(pid_at(320.0))), sp)
    assert m300.stable and m300.gain_margin_db > 0 and m300.delay_margin_samples > 0
    assert not m320.stable and m320.gain_margin_db < 0 and m320.delay_margin_samples < 0
    # the same PID on the rigid plant keeps wide margins: the mode is what caps it
    rigid = loop_margins(linearize_pid(pid_pack(pid_at(320.0))), sampled_plant(reference_plant(), TS))
    assert rigid.stable and rigid.gain_margin_db > 10


# --------------------------------------------------------------------------- margins against simulation


def _settles(kind, ctrl_p, plant):
    """True: a 10 um initial error dies out within 2 s; False: the loop diverges or grows."""
    t = sample_grid(2.0, TS)
    z = np.zeros_like(t)
    r = simulate(plant, kind, ctrl_p, Trajectory(t=t, qd=z, dqd=z, ddqd=z), quant=0.0, y0=1e-5, substeps=20)
    if r.diverged:
        return False
    return float(np.abs(r.y[-500:]).max()) < 1e-7


def _frictionless(p):
    q = p.copy()
    for i in (P_FC, P_FS, P_OFFSET, P_RIPPLE_AMP):  # the linear part only
        q[i] = 0.0
    return q


AXES = {
    "reference": plant_vector(0.027, 0.273),
    "mode": plant_vector(0.027, 0.273, mode_hz=180.0, mode_damping=0.03, mode_ratio=0.4),
    "heavy_delayed": plant_vector(0.1, 0.5, delay=0.6 * TS),
}


@pytest.mark.parametrize("axis", sorted(AXES))
@pytest.mark.parametrize("kind", [KIND_PID, KIND_ARC])
def test_delay_margin_is_where_the_simulated_loop_loses_stability(axis, kind):
    plant = AXES[axis]
    if kind == KIND_PID:
        ctrl = pid_pack(pid_at(300.0, fric=False))
        lin = linearize_pid(ctrl)
    else:
        g = dataclasses.replace(paper_gains_implementable(TS), fric_level=0.0)
        ctrl = arc_pack(g)
        lin = linearize_arc(ctrl, g.theta0)
    m = loop_margins(lin, sampled_plant(plant, TS))
    assert m.stable and 0.1 < m.delay_margin_samples < 20
    for factor, expect in ((0.9, True), (1.1, False)):
        q = _frictionless(plant)
        q[P_DELAY] = plant[P_DELAY] + factor * m.delay_margin_samples * TS
        assert _settles(kind, ctrl, q) is expect, (axis, factor, m)


@pytest.mark.parametrize("axis", sorted(AXES))
def test_gain_margin_is_where_the_simulated_loop_loses_stability(axis):
    plant = AXES[axis]
    ctrl = pid_pack(pid_at(300.0, fric=False))
    m = loop_margins(linearize_pid(ctrl), sampled_plant(plant, TS))
    assert m.stable and 0.5 < m.gain_margin_db < 60
    for factor, expect in ((0.9, True), (1.1, False)):
        k = 10 ** (m.gain_margin_db / 20) * factor  # loop gain x k: the plant's mass and viscous / k
        q = _frictionless(plant)
        q[P_M] /= k
        q[P_B] /= k
        assert _settles(KIND_PID, ctrl, q) is expect, (axis, factor, m)
    # and the eigenvalues agree with the frequency-domain figure
    sp = sampled_plant(plant, TS)
    lin = linearize_pid(ctrl)
    g = 10 ** (m.gain_margin_db / 20)
    assert closed_loop_radius(lin, sp, 0.98 * g) < 1 < closed_loop_radius(lin, sp, 1.02 * g)


def test_compiled_unwrap_and_phase_crossovers_equal_the_array_forms():
    """loop_margins' compiled unwrap is numpy.unwrap to the last bit (exact +-pi steps included), and
    its phase-crossover gain margin is the array form's (np.unique branches, sign changes, interpolation)."""
    from commission.controllers.margins import _at, _crossings, _phase_crossover_gain_margin, _unwrap

    rng = np.random.default_rng(3)
    for t in range(30):
        p = np.angle(np.exp(1j * np.cumsum(rng.normal(0.0, rng.uniform(0.1, 3.0), 2000))))
        if t % 3 == 0:
            p = np.round(p / np.pi) * np.pi  # steps of exactly +-pi: numpy's boundary rule
        assert np.array_equal(_unwrap(p), np.unwrap(p))
        phase = np.unwrap(p) * rng.uniform(0.5, 3.0)
        mag_db = rng.normal(0.0, 10.0, p.size)
        k = np.round((phase + math.pi) / (2 * math.pi))
        first = float(rng.uniform(-1.0, p.size / 2))
        pc = []
        for kk in np.unique(k):
            pc.extend(_crossings(phase + math.pi - 2 * math.pi * kk).tolist())
        vals = [-_at(mag_db, c) for c in pc if c > first]
        found, gm = _phase_crossover_gain_margin(phase, k, mag_db, first)
        assert found == bool(vals) and (gm == min(vals) if vals else gm == math.inf)


def test_compiled_back_substitution_equals_python_complex_arithmetic_to_the_last_bit():
    """The response's compiled back-substitution (real and imaginary parts in separate arrays) gives
    the values Python's own complex product, sum and quotient (CPython's ``_Py_c_quot``) give in the
    same order: on the linearised ARC's Schur form, and on a random triangular one with poles on
    either side of the diagonal of the complex plane (both branches of the quotient), on a grid longer
    than one block of the substitution (``TRI_BLOCK``)."""
    from scipy.linalg import matrix_balance, schur

    from commission.controllers.linear import TRI_BLOCK, _triangular_response

    def python_complex(T, bt, ct, D, z):
        n = T.shape[0]
        out = []
        for zi in z.tolist():
            x = [0j] * n
            for k in range(n - 1, -1, -1):
                acc = complex(bt[k])
                for j in range(k + 1, n):
                    acc = acc + complex(T[k, j]) * x[j]
                x[k] = acc / (zi - complex(T[k, k]))
            o = complex(D)
            for k in range(n):
                o = o + x[k] * complex(ct[k])
            out.append(o)
        return np.array(out)

    rng = np.random.default_rng(5)
    f = frequency_grid(TS, TRI_BLOCK + 44)
    z = np.exp(1j * 2.0 * np.pi * f * TS)
    lin = linearize_arc(arc_pack(paper_gains_implementable(TS)), (30.0, 10.0, 0.5))
    Ab, (scale, _) = matrix_balance(lin.Ac, permute=False, separate=True)
    T, U = schur(Ab.astype(complex), output="complex")
    cases = [(np.ascontiguousarray(T), U.conj().T @ (lin.Bc[:, 0] / scale), (lin.Cc[0] * scale) @ U, complex(lin.Dc))]
    n = 6
    R = np.triu(rng.normal(size=(n, n)) + 1j * rng.normal(size=(n, n)))
    R[np.diag_indices(n)] = rng.uniform(0.2, 0.99, n) * np.exp(1j * rng.uniform(-np.pi, np.pi, n))
    cases.append((R, rng.normal(size=n) + 1j * rng.normal(size=n), rng.normal(size=n) + 1j * rng.normal(size=n), 0.3 - 0.1j))
    for T, bt, ct, D in cases:
        got = _triangular_response(T, bt, ct, D, z)
        assert np.array_equal(got.view(np.float64), python_complex(T, bt, ct, D, z).view(np.float64))


def test_linearisations_are_kept_read_only_and_equal_a_fresh_one():
    """linearize_arc returns the kept object for the same (p, theta_hat) bits, its arrays and
    responses read-only, with the values a fresh linearisation gives."""
    import commission.controllers.margins as mg

    p = arc_pack(paper_gains_implementable(TS))
    th = (30.0, 10.0, 0.0)
    a = linearize_arc(p, th)
    assert linearize_arc(p.copy(), tuple(th)) is a
    f = frequency_grid(TS)
    r = a.frequency_response(f)
    assert a.frequency_response(f.copy()) is r and not r.flags.writeable and not a.Ac.flags.writeable
    mg._arc_linearisations.clear()
    b = linearize_arc(p, th)
    assert b is not a
    for x, y in ((a.Ac, b.Ac), (a.Bc, b.Bc), (a.Cc, b.Cc)):
        assert np.array_equal(x, y)
    assert a.Dc == b.Dc and np.array_equal(b.frequency_response(f), r)
    assert linearize_arc(p, (30.0, 10.0, 1.0)) is not b  # another estimate, another linearisation


@pytest.mark.parametrize("theta", [(30.0, 10.0, 0.0), (45.0, 3.0, -2.0)])
def test_compiled_arc_jacobian_equals_the_python_differences_to_the_last_bit(theta):
    """linearize_arc's compiled central differences give the matrices the generic Python
    _jacobian (calling the compiled step 2 (n + 1) times) gives, bit for bit."""
    import commission.controllers.margins as mg
    from commission.controllers.arc import S_DYNAMIC

    p = arc_pack(paper_gains_implementable(TS))
    pl, s = arc_operating_point(p, theta)
    ref = mg._jacobian(arc_step, pl, s, S_DYNAMIC, mg._scales(arc_step, pl, s, S_DYNAMIC), 1e-9)
    mg._arc_linearisations.clear()
    got = linearize_arc(p, theta)
    for x, y in ((got.Ac, ref.Ac), (got.Bc, ref.Bc), (got.Cc, ref.Cc)):
        assert x.shape == y.shape and np.array_equal(x, y)
    assert got.Dc == ref.Dc and got.Ts == ref.Ts
