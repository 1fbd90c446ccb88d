"""Runtime guards of the compiled ARC step (issue 24, must-show 4), run in the closed-loop simulator.

The axis: the paper's identified plant with the §4.3 gains carried over to it
(``base_arc_gains``), the default envelope and gate, and the guards that
``validate`` sets for them (:func:`commission.validate.guard_values`).  A
measurement glitch is a one-sample spike in the simulator's ``noise`` (added
to the position before the encoder rounds it).
"""

import dataclasses
import math

import numpy as np
import pytest

from commission.controllers import arc as A
from commission.controllers.simulate import KIND_ARC, simulate
from commission.gate import GateSpec, resolve_gate
from commission.paper import reference_identification
from commission.runtime import Controller
from commission.controller_config import ControllerConfig, ControllerProvenance
from commission.scenarios import case1_trajectory, case2_trajectory, identified_plant, plant_substeps
from commission.spec import default_spec
from commission.tune import base_arc_gains
from commission.validate import deployable_gains, guard_values

LSB = 1e-6


@pytest.fixture(scope="module")
def axis():
    spec = default_spec()
    ident = reference_identification(delta_d=0.5)
    raw = base_arc_gains(ident, spec)
    limits = resolve_gate(GateSpec(), lsb=LSB, travel=spec.travel, u_max=spec.u_max)
    guarded = deployable_gains(raw, guard_values(raw.Ts, LSB, spec.v_max, spec.travel, limits.e_M))
    trajs = {"case1": case1_trajectory(spec).render(raw.Ts, 0.0), "case2": case2_trajectory(spec).render(raw.Ts, 0.0)}
    return dict(spec=spec, plant=identified_plant(ident), raw=raw, g=guarded, limits=limits, trajs=trajs)


def run(axis, g, traj, noise=None, disturbance=None):
    spec = axis["spec"]
    return simulate(axis["plant"], KIND_ARC, A.arc_pack(g), traj, substeps=plant_substeps(1.0 / g.Ts), quant=LSB,
                    noise=noise, disturbance=disturbance, u_sat=spec.u_max, e_abort=spec.travel)


def controller(g):
    prov = ControllerProvenance(None, "0" * 64, "0" * 64, "test", "2001-06-01T00:00:00Z")
    return Controller(ControllerConfig(gains=g, sample_rate=1.0 / g.Ts, units={"u": "V", "q": "m"}, validated={},
                                       provenance=prov))


def replay(g, sim, traj):
    """The runtime on the simulation's measurements: its commands and its fault state."""
    ctrl = controller(g)
    ctrl.reset(sim.y[0])
    u = np.array([ctrl.step(sim.y[k], traj.qd[k], traj.dqd[k], traj.ddqd[k]) for k in range(sim.n_steps)])
    return u, ctrl


def spike(n, k, amp):
    noise = np.zeros(n)
    noise[k] = amp
    return noise


def test_guards_chosen_from_envelope_and_gate(axis):
    g, spec = axis["g"], axis["spec"]
    assert g.dy_max == pytest.approx(2 * spec.v_max * g.Ts + 2 * LSB)  # 0.802 mm at 1 m/s, 2.5 kHz
    assert g.dy_max < 1e-3 < g.dy_fault == spec.travel
    assert g.e_max == pytest.approx(2 * axis["limits"].e_M)
    assert g.n_reject_max == 5.0 and g.freeze_on_saturation


@pytest.mark.parametrize("case", ["case1", "case2"])
def test_guards_never_act_in_a_normal_run(axis, case):
    traj = axis["trajs"][case]
    plain, guarded = run(axis, axis["raw"], traj), run(axis, axis["g"], traj)
    assert not guarded.diverged and guarded.n_steps == traj.n
    assert np.array_equal(plain.u, guarded.u) and np.array_equal(plain.theta_hat, guarded.theta_hat)


@pytest.mark.parametrize("case", ["case1", "case2"])
def test_one_sample_1mm_glitch_costs_at_most_two_samples_at_the_rail(axis, case):
    g, traj = axis["g"], axis["trajs"][case]
    k = traj.n // 3  # in the middle of a move
    clean = run(axis, g, traj)
    hit = run(axis, g, traj, noise=spike(traj.n, k, 1e-3))
    assert not hit.diverged and hit.n_steps == traj.n
    at_rail = int(np.sum(np.abs(hit.u) >= g.u_max))
    assert at_rail <= 2
    # the axis returns: its final accuracy is within the validated e_F, as without the glitch
    assert hit.indexes.e_F <= axis["limits"].e_F
    assert abs(hit.indexes.e_F - clean.indexes.e_F) <= LSB
    # the true position never leaves the clean run by more than e_F
    assert np.max(np.abs(hit.q - clean.q)) <= axis["limits"].e_F
    # the runtime on the same measurements: the glitch was rejected, no fault
    u, ctrl = replay(g, hit, traj)
    assert np.array_equal(u, hit.u) and not ctrl.fault and ctrl.fault_reason == "none"


def test_without_the_guards_a_1mm_glitch_drives_to_the_rail(axis):
    """The same glitch without the plausibility guard: the command hits the rail (the guard is what helps)."""
    traj = axis["trajs"]["case1"]
    hit = run(axis, axis["raw"], traj, noise=spike(traj.n, traj.n // 3, 1e-3))
    assert np.sum(np.abs(hit.u) >= axis["raw"].u_max) >= 1


@pytest.mark.parametrize("case", ["case1", "case2"])
def test_1m_glitch_latches_a_fault_safe_command_theta_kept(axis, case):
    g, traj = axis["g"], axis["trajs"][case]
    k = traj.n // 3
    hit = run(axis, g, traj, noise=spike(traj.n, k, 1.0))
    clean = run(axis, g, traj)
    assert np.array_equal(hit.u[:k], clean.u[:k])
    assert np.all(hit.u[k:] == 0.0)  # the safe command from the glitch on
    assert np.array_equal(hit.theta_hat[k:], np.broadcast_to(hit.theta_hat[k - 1], hit.theta_hat[k:].shape))
    u, ctrl = replay(g, hit, traj)
    assert np.array_equal(u, hit.u)
    assert ctrl.fault and ctrl.fault_code == A.FAULT_JUMP
    assert ctrl.fault_reason == "measurement jump beyond dy_fault"
    assert np.array_equal(ctrl.theta_hat, hit.theta_hat[k - 1])


def test_a_run_of_implausible_measurements_latches_a_fault(axis):
    g, traj = axis["g"], axis["trajs"]["case1"]
    k = traj.n // 3
    noise = np.zeros(traj.n)
    n_rej = int(g.n_reject_max)
    noise[k:k + n_rej] = 2.0 * g.dy_max * np.arange(1, n_rej + 1)  # each beyond dy_max (1 + r)
    hit = run(axis, g, traj, noise=noise)
    u, ctrl = replay(g, hit, traj)
    assert ctrl.fault and ctrl.fault_code == A.FAULT_GLITCH_RUN
    first_zero = k + n_rej - 1  # the n-th rejection latches
    assert np.all(hit.u[first_zero:] == 0.0) and np.all(hit.u[k:first_zero] != 0.0)
    # theta_hat frozen from the first rejected sample on
    assert np.array_equal(hit.theta_hat[-1], hit.theta_hat[k - 1])


def test_tracking_watchdog_latches(axis):
    g, traj = axis["g"], axis["trajs"]["case1"]
    k = traj.n // 3
    d = np.zeros(traj.n)
    d[k:] = 3.0 * axis["spec"].u_max  # a load the drive cannot hold: the axis is pushed away
    hit = run(axis, g, traj, disturbance=d)
    u, ctrl = replay(g, hit, traj)
    assert ctrl.fault and ctrl.fault_code == A.FAULT_TRACKING
    kf = int(np.argmax(np.abs(hit.e) > g.e_max))
    assert kf > k and np.all(hit.u[kf:] == 0.0) and hit.u[kf - 1] != 0.0


def test_adaptation_frozen_while_saturated():
    g = dataclasses.replace(A.paper_gains_implementable(), u_max=0.05)
    for freeze in (False, True):
        p = A.arc_pack(dataclasses.replace(g, freeze_on_saturation=freeze))
        s = A.arc_new_state(p)
        A.arc_reset(p, s, 0.0)
        moved_while_saturated = False
        for k in range(50):
            th = s[A.S_THETA:A.S_THETA + 3].copy()
            u = A.arc_step(p, s, 0.0, 1e-3, 0.0, 0.0)  # a 1 mm step demand: saturates
            if abs(u) == 0.05:
                assert s[A.S_FROZEN] == (1.0 if freeze else 0.0)
                moved_while_saturated |= not np.array_equal(th, s[A.S_THETA:A.S_THETA + 3])
        assert moved_while_saturated == (not freeze)


def test_guard_fields_round_trip_and_default_off(tmp_path, axis):
    g = axis["g"]
    doc = controller(g).config.to_dict()
    assert doc["runtime"] == {"dy_max": g.dy_max, "dy_fault": g.dy_fault, "n_reject_max": g.n_reject_max,
                              "e_max": g.e_max, "freeze_on_saturation": True}
    assert ControllerConfig.from_dict(doc).gains == g
    assert "runtime" not in controller(axis["raw"]).config.to_dict()  # files without guards keep their checksum
    for field, bad in (("n_reject_max", 0.5), ("dy_max", -1.0), ("e_max", 0.0)):
        with pytest.raises(ValueError, match=field):
            dataclasses.replace(g, **{field: bad})
    assert math.isinf(axis["raw"].dy_max)


def test_guards_act_only_where_the_gate_fails_on_the_validation_matrix(axis):
    """validate's scenario matrix (12 fixed + 8 Monte-Carlo plants): with the guards the ARC runs bit for bit
    as without them, except on a scenario the gate fails anyway (command at u_max, or e_M beyond the gate)."""
    from commission.scenarios import scenario_matrix
    from commission.paper import reference_identification

    ident = reference_identification(delta_d=0.5)
    spec, lim = axis["spec"], axis["limits"]
    same = 0
    for sc in scenario_matrix(ident, spec, rng=np.random.default_rng(0), n_monte_carlo=8):
        traj = sc.trajectory.render(axis["g"].Ts, sc.y0)
        d = sc.disturbance.samples(traj.t)
        kw = dict(substeps=plant_substeps(1.0 / axis["g"].Ts), quant=sc.quantization,
                  disturbance=d if np.any(d) else None, y0=sc.y0, u_sat=spec.u_max, e_abort=spec.travel)
        plain = simulate(sc.plant, KIND_ARC, A.arc_pack(axis["raw"]), traj, **kw)
        guarded = simulate(sc.plant, KIND_ARC, A.arc_pack(axis["g"]), traj, **kw)
        if np.array_equal(plain.u, guarded.u):
            same += 1
            continue
        fails_gate = plain.diverged or np.max(np.abs(plain.u)) >= spec.u_max or plain.indexes.e_M > lim.e_M
        assert fails_gate, sc.name
    assert same >= 18, same  # measured: 20 of 20
