"""The sampled-data loop against an independent discretisation, and its bookkeeping."""

import dataclasses
import math

import numpy as np
import pytest
from scipy.signal import cont2discrete, dlsim

from commission.controllers.pid import PidGains, pid_pack, pid_place_poles
from commission.controllers.plant import plant_vector
from commission.controllers.simulate import (
    KIND_PID,
    SimulationError,
    simulate,
    simulate_batch,
    step_disturbance,
)
from commission.controllers.trajectory import back_and_forth, sinusoid

TS = 1 / 2500
M, B = 0.027, 0.273
LIN_GAINS = PidGains(Ts=TS, M_hat=0.05, B_hat=0.24, Kp=5400.0, Ki=5.4e5, Kd=18.0)


def exact_zoh_loop(g, traj, d, delay):
    """The same loop built as one linear discrete system and run by scipy's dlsim.

    Plant M qdd = u + d - B qd discretised exactly under ZOH; controller (57)
    without friction compensation.  State X = [q, v, y_prev, I (, c_prev)],
    inputs [qd, dqd, ddqd, d], outputs [q, u].
    """
    Ts = traj.Ts
    Ad, Bd, *_ = cont2discrete((np.array([[0, 1], [0, -B / M]]), np.array([[0], [1 / M]]),
                                np.eye(2), np.zeros((2, 1))), Ts, method="zoh")
    Bd = Bd[:, 0]
    a = np.array([(g.B_hat - g.Kd) / Ts - g.Kp - g.Ki * Ts, 0.0, -(g.B_hat - g.Kd) / Ts, -g.Ki])
    b = np.array([g.Kp + g.Ki * Ts, g.Kd, g.M_hat, 0.0])
    nx = 5 if delay else 4
    A = np.zeros((nx, nx))
    Bm = np.zeros((nx, 4))
    C = np.zeros((2, nx))
    D = np.zeros((2, 4))
    A[:2, :2] = Ad
    if delay:
        A[:2, 4] += Bd
        A[4, :4] = a
        Bm[4] = b
        C[1, 4] = 1.0
    else:
        A[:2, :4] += np.outer(Bd, a)
        Bm[:2] += np.outer(Bd, b)
        C[1, :4] = a
        D[1] = b
    Bm[:2, 3] += Bd
    A[2, 0] = 1.0
    A[3, 0] += Ts
    A[3, 3] = 1.0
    Bm[3, 0] = -Ts
    C[0, 0] = 1.0
    w = np.column_stack([traj.qd, traj.dqd, traj.ddqd, d])
    _, yout, _ = dlsim((A, Bm, C, D, Ts), w, x0=np.zeros(nx))
    return yout[:, 0], yout[:, 1]


@pytest.mark.parametrize("delay", [False, True])
def test_linear_loop_converges_to_exact_zoh_discretisation(delay):
    traj = sinusoid(2.0, TS)
    d = step_disturbance(traj.t, [(0.5, 1.5, 0.5)])
    q_ref, u_ref = exact_zoh_loop(LIN_GAINS, traj, d, delay)
    e_scale = np.abs(q_ref - traj.qd).max()
    p = plant_vector(M, B, fc=0.0)
    errs = []
    for n in (10, 100):
        r = simulate(p, KIND_PID, pid_pack(LIN_GAINS), traj, quant=0.0, disturbance=d,
                     substeps=n, delay=delay)
        assert not r.diverged and r.n_steps == traj.n
        errs.append(np.abs(r.q - q_ref).max())
        np.testing.assert_allclose(r.u, u_ref, atol=0.3 / n)
    # The plant kernel is first order in the sub-step: 10x the sub-steps, 1/10 the error.
    assert errs[0] < 0.02 * e_scale
    assert errs[1] < 0.002 * e_scale
    assert 8.0 < errs[0] / errs[1] < 12.0


def test_encoder_quantization_and_noise():
    traj = sinusoid(1.0, TS)
    p = plant_vector(M, B, fc=0.1, fs=0.12, ripple_amp=0.01, ripple_pitch=0.03)
    q_res = 1e-6
    r = simulate(p, KIND_PID, pid_pack(LIN_GAINS), traj, quant=q_res)
    k = r.y / q_res
    np.testing.assert_allclose(k, np.round(k), atol=1e-6)
    assert np.abs(r.y - r.q).max() <= q_res / 2 * (1 + 1e-9)
    # Noise is added to the true position before the encoder; without quantization y = q + n.
    noise = np.random.default_rng(3).normal(0.0, 2e-7, traj.n)
    r = simulate(p, KIND_PID, pid_pack(LIN_GAINS), traj, quant=0.0, noise=noise)
    np.testing.assert_array_equal(r.y, r.q + noise)


def test_saturation_limits_the_applied_input():
    traj = back_and_forth(8.0, TS)
    p = plant_vector(M, B, fc=0.1, fs=0.12)
    r = simulate(p, KIND_PID, pid_pack(LIN_GAINS), traj, u_sat=0.5)
    free = simulate(p, KIND_PID, pid_pack(LIN_GAINS), traj)
    assert np.abs(free.u).max() > 0.5
    assert np.abs(r.u).max() == 0.5


def test_delay_shifts_the_command_by_one_sample():
    # A pure feedforward law (no feedback gains) makes the command independent of
    # the plant, so the delayed run must apply exactly the same sequence one sample late.
    traj = sinusoid(0.2, TS)
    p = plant_vector(M, B, fc=0.1, fs=0.12)
    ff = pid_pack(PidGains(Ts=TS, M_hat=0.05, B_hat=0.0, Kp=0.0, Ki=0.0, Kd=0.0))
    a = simulate(p, KIND_PID, ff, traj)
    b = simulate(p, KIND_PID, ff, traj, delay=True)
    np.testing.assert_array_equal(a.u, 0.05 * traj.ddqd)
    assert b.u[0] == 0.0
    np.testing.assert_array_equal(b.u[1:], a.u[:-1])
    assert not np.array_equal(a.q, b.q)


def unstable_gains():
    # Poles designed at -1600 rad/s: far beyond what 2.5 kHz sampling supports.
    Kp, Ki, Kd = pid_place_poles(0.02, -1600.0)
    return dataclasses.replace(LIN_GAINS, Kp=Kp, Ki=Ki, Kd=Kd, fric_level=0.1, fric_slope=900.0)


def test_divergence_is_reported_not_raised():
    traj = sinusoid(10.0, TS)
    p = plant_vector(M, B, fc=0.1, fs=0.12)
    r = simulate(p, KIND_PID, pid_pack(unstable_gains()), traj)
    assert r.diverged
    assert 0 < r.n_steps < traj.n
    assert r.indexes is None
    assert r.y.shape == (r.n_steps,) and np.all(np.isfinite(r.y)) and np.all(np.isfinite(r.u))
    # Stable gains on the same plant do not abort.
    ok = simulate(p, KIND_PID, pid_pack(LIN_GAINS), traj)
    assert not ok.diverged and ok.indexes is not None


def test_abort_thresholds():
    traj = sinusoid(1.0, TS)
    p = plant_vector(M, B, fc=0.1, fs=0.12)
    r = simulate(p, KIND_PID, pid_pack(LIN_GAINS), traj, e_abort=1e-6)
    assert r.diverged and r.n_steps > 0
    assert abs(r.q[-1] - r.qd[-1]) <= 1e-6
    r = simulate(p, KIND_PID, pid_pack(LIN_GAINS), traj, u_abort=1e-3)
    assert r.diverged


def plants_grid(n):
    Ms = np.linspace(0.02, 0.12, n)
    return np.stack([plant_vector(m, B * (1 + 0.5 * i / n), fc=0.1, fs=0.12, ripple_amp=0.01,
                                  ripple_pitch=0.03) for i, m in enumerate(Ms)])


def test_batch_equals_single_runs_and_is_thread_independent():
    traj = sinusoid(2.0, TS)
    plants = plants_grid(5)
    g = pid_pack(LIN_GAINS)
    rng = np.random.default_rng(1)
    noise = rng.normal(0, 1e-7, (5, traj.n))
    d = step_disturbance(traj.t, [(0.3, 1.2, 0.4)])
    b1 = simulate_batch(plants, KIND_PID, g, traj, noise=noise, disturbance=d, workers=1,
                        return_traces=True)
    b2 = simulate_batch(plants, KIND_PID, np.tile(g, (5, 1)), traj, noise=noise, disturbance=d, workers=2)
    assert b2.y is None
    for i in range(5):
        r = simulate(plants[i], KIND_PID, g, traj, noise=noise[i], disturbance=d)
        assert r.indexes == b1.indexes(i) == b2.indexes(i)
        np.testing.assert_array_equal(b1.y[i], r.y)
        np.testing.assert_array_equal(b1.u[i], r.u)
        assert b2.u_peak[i] == np.abs(r.u).max()
    assert not b1.diverged.any()
    assert np.all(np.isnan(b1.theta_final))  # PID has no estimates


def test_batch_marks_diverged_scenarios():
    traj = sinusoid(2.0, TS)
    plants = plants_grid(3)
    ctrl = np.stack([pid_pack(unstable_gains()), pid_pack(LIN_GAINS), pid_pack(LIN_GAINS)])
    b = simulate_batch(plants, KIND_PID, ctrl, traj, return_traces=True)
    assert b.diverged.tolist() == [True, False, False]
    assert b.indexes(0) is None and math.isnan(b.e_M[0]) and math.isnan(b.c_u[0])
    assert 0 < b.n_steps[0] < traj.n and b.n_steps[1] == traj.n
    assert np.all(np.isfinite(b.y[0, : b.n_steps[0]])) and np.all(np.isnan(b.y[0, b.n_steps[0]:]))
    assert np.isfinite(b.e_M[1:]).all()
    assert b.u_peak[0] == np.abs(b.u[0, : b.n_steps[0]]).max()


def test_input_errors_name_field_and_shape():
    traj = sinusoid(1.0, TS)
    p = plant_vector(M, B)
    g = pid_pack(LIN_GAINS)
    with pytest.raises(SimulationError, match=rf"plant_p: expected shape \({p.size},\), got \(8,\)"):
        simulate(p[:8], KIND_PID, g, traj)
    with pytest.raises(SimulationError, match=r"disturbance: expected shape \(2500,\), got \(2499,\)"):
        simulate(p, KIND_PID, g, traj, disturbance=np.zeros(2499))
    bad = np.zeros(traj.n)
    bad[12] = np.nan
    with pytest.raises(SimulationError, match="noise: element 12 is nan"):
        simulate(p, KIND_PID, g, traj, noise=bad)
    with pytest.raises(SimulationError, match="packed for Ts=0.001 s"):
        simulate(p, KIND_PID, pid_pack(dataclasses.replace(LIN_GAINS, Ts=1e-3)), traj)
    with pytest.raises(SimulationError, match="kind"):
        simulate(p, 7, g, traj)
    with pytest.raises(SimulationError, match=rf"plants: expected shape \(m, {p.size}\)"):
        simulate_batch(p, KIND_PID, g, traj)
    with pytest.raises(SimulationError, match=r"noise: expected shape \(2500,\) or \(2, 2500\)"):
        simulate_batch(np.stack([p, p]), KIND_PID, g, traj, noise=np.zeros((3, traj.n)))


def test_arc_path_records_estimates_and_batches_like_single_runs():
    from commission.controllers.arc import arc_pack, paper_gains_implementable
    from commission.controllers.simulate import KIND_ARC

    traj = sinusoid(2.0, TS)
    g = paper_gains_implementable(TS)
    ctrl = arc_pack(g)
    plants = plants_grid(3)
    b = simulate_batch(plants, KIND_ARC, ctrl, traj, workers=2)
    for i in range(3):
        r = simulate(plants[i], KIND_ARC, ctrl, traj)
        assert r.theta_hat.shape == (traj.n, 3)
        lo, hi = np.array(g.theta_min), np.array(g.theta_max)
        assert np.all(r.theta_hat >= lo) and np.all(r.theta_hat <= hi)  # projection (20)
        assert not np.array_equal(r.theta_hat[-1], np.array(g.theta0))  # it adapts
        np.testing.assert_array_equal(b.theta_final[i], r.theta_hat[-1])
        assert b.indexes(i) == r.indexes


def test_batch_scratch_reuse_and_theta_at_abort_match_single_runs():
    """One thread runs every row on the same scratch (workers=1): a row aborted early, two full
    rows, a row aborted later; each row's indexes, peak and last estimate are the single run's."""
    from commission.controllers.arc import arc_pack, paper_gains_implementable
    from commission.controllers.simulate import KIND_ARC

    traj = sinusoid(2.0, TS)
    ctrl = arc_pack(paper_gains_implementable(TS))
    plants = plants_grid(4)
    kick = [step_disturbance(traj.t, [(0.1, 2.5, 50.0)]), np.zeros(traj.n), np.zeros(traj.n),
            step_disturbance(traj.t, [(1.5, 2.5, 50.0)])]  # a push of 50 u drives the axis off by 1 m
    single = [simulate(plants[i], KIND_ARC, ctrl, traj, disturbance=kick[i]) for i in range(4)]
    assert [r.diverged for r in single] == [True, False, False, True]
    assert 0 < single[0].n_steps < single[3].n_steps < traj.n
    b = simulate_batch(plants, KIND_ARC, ctrl, traj, disturbance=np.stack(kick), workers=1)
    for i, r in enumerate(single):
        assert b.diverged[i] == r.diverged and b.n_steps[i] == r.n_steps
        assert b.indexes(i) == r.indexes
        assert b.u_peak[i] == np.abs(r.u).max()
        np.testing.assert_array_equal(b.theta_final[i], r.theta_hat[-1])


def _varied_plants():
    """Rigid, one mode (motor- and load-side encoder), two modes, ripple, Stribeck or Coulomb friction,
    offsets and input delays of 0, a fraction, one and more samples: each next to a different kind."""
    from commission.controllers.plant import (P_DELAY, P_MODE2_DAMPING, P_MODE2_HZ, P_MODE2_LOAD_SIDE,
                                              P_MODE2_RATIO, P_MODE_DAMPING, P_MODE_HZ, P_MODE_LOAD_SIDE,
                                              P_MODE_RATIO, P_OFFSET)
    rng = np.random.default_rng(5)
    out = []
    for i in range(13):
        p = plant_vector(M * 10 ** rng.uniform(-0.4, 0.4), B * rng.uniform(0.5, 2.0), fc=0.1,
                         fs=0.12 if i % 3 else 0.1, ripple_amp=0.01 if i % 4 == 3 else 0.0, ripple_pitch=0.03)
        if i % 3:
            p[P_MODE_HZ], p[P_MODE_DAMPING], p[P_MODE_RATIO] = rng.uniform(250, 1100), 0.05, 0.3
            p[P_MODE_LOAD_SIDE] = float(i % 5 == 1)
        if i % 3 == 2:
            p[P_MODE2_HZ], p[P_MODE2_DAMPING], p[P_MODE2_RATIO] = rng.uniform(900, 1800), 0.04, 0.1
            p[P_MODE2_LOAD_SIDE] = float(i % 5 == 2)
        p[P_DELAY] = TS * (0.0, 0.4, 1.0, 2.3)[i % 4]
        p[P_OFFSET] = 0.01 * (i % 3 - 1)
        out.append(p)
    return np.stack(out)


@pytest.mark.parametrize("kind", ["pid", "arc"])
@pytest.mark.parametrize("delay", [False, True])
def test_batch_rows_are_the_single_runs_to_the_last_bit_on_varied_plants(kind, delay):
    """Each row of a batch is exactly its own single run whatever the rows beside it: rigid next to
    modes, different input delays (sub-step counts), rows that abort early or later on a thread's
    reused scratch, traces kept or not, one thread or two."""
    from commission.controllers.arc import arc_pack, paper_gains_implementable
    from commission.controllers.simulate import KIND_ARC

    traj = sinusoid(1.0, TS)
    plants = _varied_plants()
    m = plants.shape[0]
    k, ctrl = ((KIND_ARC, arc_pack(paper_gains_implementable(TS))) if kind == "arc"
               else (KIND_PID, pid_pack(LIN_GAINS)))
    rng = np.random.default_rng(3)
    noise = rng.normal(0, 2e-7, (m, traj.n))
    d = np.stack([step_disturbance(traj.t, [(0.2, 0.7, rng.uniform(-0.3, 0.3))]) for _ in range(m)])
    d[4] = step_disturbance(traj.t, [(0.1, 1.0, 50.0)])  # aborts early when saturated; the next rows run on
    d[7] = step_disturbance(traj.t, [(0.6, 1.0, 50.0)])  # aborts later
    for u_sat in (math.inf, 0.4):
        kept = simulate_batch(plants, k, ctrl, traj, noise=noise, disturbance=d, delay=delay, u_sat=u_sat,
                              workers=1, return_traces=True)
        two = simulate_batch(plants, k, ctrl, traj, noise=noise, disturbance=d, delay=delay, u_sat=u_sat, workers=2)
        for i in range(m):
            r = simulate(plants[i], k, ctrl, traj, noise=noise[i], disturbance=d[i], delay=delay, u_sat=u_sat)
            for b in (kept, two):
                assert b.diverged[i] == r.diverged and b.n_steps[i] == r.n_steps, (i, u_sat)
                assert b.indexes(i) == r.indexes, (i, u_sat)
                assert b.u_peak[i] == np.abs(r.u).max()
                if k == KIND_ARC:
                    np.testing.assert_array_equal(b.theta_final[i], r.theta_hat[-1])
            np.testing.assert_array_equal(kept.y[i, :r.n_steps], r.y)
            np.testing.assert_array_equal(kept.q[i, :r.n_steps], r.q)
            np.testing.assert_array_equal(kept.u[i, :r.n_steps], r.u)
            assert np.all(np.isnan(kept.y[i, r.n_steps:]))
        if u_sat < math.inf:  # the drive cannot push back: the two pushed rows abort, the others do not
            assert kept.diverged[4] and kept.diverged[7] and kept.n_steps[4] < kept.n_steps[7] < traj.n
            assert not kept.diverged[5] and not kept.diverged[6]


@pytest.mark.parametrize("delay", [False, True])
def test_pair_kernel_runs_are_the_single_kernel_runs_to_the_last_bit(delay):
    """closed_loop_pair_kernel runs two loops whose plants it steps together when their segments agree
    (pair_key): each loop's traces, estimates and abort are closed_loop_kernel's, bit for bit, for
    pairs of every kind (rigid, modes, different delays) and when one loop aborts and the other runs on."""
    from commission.controllers.arc import arc_new_state, arc_pack, paper_gains_implementable
    from commission.controllers.simulate import closed_loop_kernel, closed_loop_pair_kernel, pair_key

    traj = sinusoid(0.6, TS)
    n = traj.n
    plants = _varied_plants()
    ctrl = arc_pack(paper_gains_implementable(TS))
    rng = np.random.default_rng(11)
    noise = rng.normal(0, 2e-7, (plants.shape[0], n))
    d = np.zeros((plants.shape[0], n))
    d[3] = step_disturbance(traj.t, [(0.3, 0.6, 50.0)])  # a push that drives this loop off: it aborts mid-run
    args = (traj.qd, traj.dqd, traj.ddqd, TS, 10, 1e-6)

    def single(i):
        out = np.full((3, n), np.nan), np.full((1, 3), np.nan)
        s = arc_new_state(ctrl)
        k, div = closed_loop_kernel(plants[i], 1, ctrl, s, *args, d[i], noise[i], delay, 0.0, math.inf, 0.05, 1e6,
                                    out[0][0], out[0][1], out[0][2], out[1])
        return k, div, out[0], out[1], s

    keys = [tuple(pair_key(p, TS, 10, delay)) for p in plants]
    pairs = [(i, j) for i in range(len(plants)) for j in range(i + 1, len(plants)) if keys[i] == keys[j]][:6]
    pairs += [(0, 1), (3, 4), (4, 3)]  # keys that differ (the plants stepped one after the other), and the abort
    assert sum(keys[i] == keys[j] for i, j in pairs) >= 4
    aborted = False
    for i, j in pairs:
        ref = [single(i), single(j)]
        got = [[np.full((3, n), np.nan), np.full((1, 3), np.nan), arc_new_state(ctrl)] for _ in range(2)]
        lanes = []
        for r, (tr, th, s) in zip((i, j), got):
            lanes.append((plants[r], ctrl, s, d[r], noise[r], tr[0], tr[1], tr[2], th))
        ka, da, kb, db = closed_loop_pair_kernel(1, *args, delay, 0.0, math.inf, 0.05, 1e6, *lanes[0], *lanes[1])
        for (k, div, tr, th, s), (k2, div2), (tr2, th2, s2) in zip(ref, ((ka, da), (kb, db)), got):
            assert (k, div) == (k2, div2), (i, j)
            np.testing.assert_array_equal(tr2, tr)
            np.testing.assert_array_equal(th2, th)
            np.testing.assert_array_equal(s2, s)
            aborted |= bool(div) and 0 < k < n
    assert aborted  # one loop stopped mid-run while the other went on
