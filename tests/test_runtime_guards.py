"""Runtime guards of the compiled ARC step (issues 24 and 29), run in the closed-loop simulator.

The axis: the paper's identified plant with the §4.3 gains carried over to it
(``base_arc_gains``), the default envelope and gate, and the guards that
``validate`` sets for them (:func:`commission.validate.guard_values` with the
envelope's acceleration and the holding force, as :func:`runtime_guards` does).
A measurement glitch is a one-sample spike in the simulator's ``noise`` (added
to the position before the encoder rounds it); a frozen encoder, which the
simulator cannot express, runs in :func:`sensor_loop`, the same loop with the
reading passed through a function.
"""

import dataclasses
import math
import subprocess

import numpy as np
import pytest

from commission.controllers import arc as A
from commission.controllers.plant import NX, P_DELAY, plant_output, plant_start, plant_step
from commission.controllers.simulate import KIND_ARC, simulate
from commission.gate import GateSpec, resolve_gate
from commission.paper import reference_identification
from commission.runtime import Controller
from commission.controller_config import ControllerConfig, ControllerProvenance
from commission.scenarios import case1_trajectory, case2_trajectory, identified_plant, plant_substeps
from commission.spec import default_spec
from commission.tune.gains import base_arc_gains
from commission.validate import deployable_gains, envelope_acceleration, guard_values, holding_force
from sensor_faults import frozen

LSB = 1e-6


@pytest.fixture(scope="module")
def axis():
    spec = default_spec()
    ident = reference_identification(delta_d=0.5)
    raw = base_arc_gains(ident, spec)
    plant = identified_plant(ident)
    limits = resolve_gate(GateSpec(), lsb=LSB, travel=spec.travel, u_max=spec.u_max)
    guards = guard_values(raw.Ts, LSB, spec.v_max, spec.travel, limits.e_M, a_max=envelope_acceleration(spec, raw.Ts),
                          theta1_min=raw.theta_min[0], u_max=raw.u_max, u_free=holding_force(ident, plant))
    guarded = deployable_gains(raw, guards)
    trajs = {"case1": case1_trajectory(spec).render(raw.Ts, 0.0), "case2": case2_trajectory(spec).render(raw.Ts, 0.0)}
    return dict(spec=spec, plant=plant, raw=raw, g=guarded, limits=limits, trajs=trajs)


def run(axis, g, traj, noise=None, disturbance=None):
    spec = axis["spec"]
    return simulate(axis["plant"], KIND_ARC, A.arc_pack(g), traj, substeps=plant_substeps(1.0 / g.Ts), quant=LSB,
                    noise=noise, disturbance=disturbance, u_sat=spec.u_max, e_abort=spec.travel)


def controller(g):
    prov = ControllerProvenance(None, "0" * 64, "0" * 64, "0.1.0", "2001-06-01T00:00:00Z")
    return Controller(ControllerConfig(gains=g, sample_rate=1.0 / g.Ts, units={"u": "V", "q": "m"}, validated={},
                                       provenance=prov))


def replay(g, sim, traj):
    """The runtime on the simulation's measurements: its commands and its fault state."""
    ctrl = controller(g)
    ctrl.reset(sim.y[0])
    u = np.array([ctrl.step(sim.y[k], traj.qd[k], traj.dqd[k], traj.ddqd[k]) for k in range(sim.n_steps)])
    return u, ctrl


def sensor_loop(axis, g, traj, sensor, n):
    """The simulator's loop (ZOH command, exact plant sub-steps, encoder rounding) with ``sensor(k, y)``
    between the encoder and the compiled step: the command, the step's flags and the bound per sample."""
    plant = axis["plant"]
    assert plant[P_DELAY] == 0.0
    p = A.arc_pack(g)
    s = A.arc_new_state(p)
    st = np.empty(NX)
    plant_start(plant, st, traj.qd[0])
    sub = plant_substeps(1.0 / g.Ts)
    A.arc_reset(p, s, LSB * math.floor(plant_output(plant, st) / LSB + 0.5))
    out = {k: np.zeros(n) for k in ("y", "u", "rejected", "fault", "bound")}
    for k in range(n):
        y = sensor(k, LSB * math.floor(plant_output(plant, st) / LSB + 0.5))
        u = A.arc_step(p, s, y, traj.qd[k], traj.dqd[k], traj.ddqd[k])
        out["y"][k], out["u"][k], out["rejected"][k], out["fault"][k], out["bound"][k] = \
            y, u, s[A.S_REJECTED], s[A.S_FAULT], s[A.S_BOUND]
        plant_step(plant, st, min(max(u, -g.u_max), g.u_max), g.Ts / sub, sub)
    return out


def cruise(axis):
    """Case 2 and a sample in its first cruise at v_max."""
    traj = axis["trajs"]["case2"]
    return traj, int(np.argmax(np.abs(traj.dqd) >= 0.999 * axis["spec"].v_max)) + 50


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
    # Case 1's filter starts at q_dd = 20 m/s^2, above the spec's 12: the envelope is the trajectories'
    a_env = np.max(np.abs(axis["trajs"]["case1"].ddqd))
    assert a_env > spec.a_max and g.accel_max == pytest.approx(3 * a_env)
    assert g.y_err == 0.5 * LSB and 0 < g.u_free < g.u_max
    assert g.n_frozen_max == 3.0  # the minimum: a 1 um encoder sees the push of the rail within 1 sample


def test_validate_records_the_new_guards_from_the_tuning():
    """runtime_guards on a tuning.json: the innovation and frozen-encoder limits come from its envelope,
    encoder, box and identified forces, and controller.json carries them."""
    from pathlib import Path

    from commission.tuning import Tuning
    from commission.validate import runtime_guards

    tuning = Tuning.load(str(Path(__file__).parent / "data" / "tuning_paper_budget8.json"))
    spec = tuning.spec
    limits = resolve_gate(GateSpec(), lsb=tuning.quantization, travel=spec.travel, u_max=spec.u_max)
    gd = runtime_guards(tuning, limits)
    assert gd["accel_max"] == 3 * envelope_acceleration(spec, tuning.arc.Ts)
    assert gd["y_err"] == 0.5 * tuning.quantization
    assert gd["u_free"] == holding_force(tuning.identification, tuning.plant) and 0 < gd["u_free"] < spec.u_max
    assert gd["n_frozen_max"] >= 3 and gd["n_frozen_max"] == int(gd["n_frozen_max"])
    doc = controller(deployable_gains(tuning.arc, gd)).config.to_dict()
    assert {k: doc["runtime"][k] for k in ("accel_max", "y_err", "n_frozen_max", "u_free")} == \
        {k: gd[k] for k in ("accel_max", "y_err", "n_frozen_max", "u_free")}


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
    """The watchdog alone: e_max lowered below the error of a normal Case-1 run trips at its first excess."""
    traj = axis["trajs"]["case1"]
    clean = run(axis, axis["g"], traj)
    g = dataclasses.replace(axis["g"], e_max=0.5 * clean.indexes.e_M)
    hit = run(axis, g, traj)
    u, ctrl = replay(g, hit, traj)
    assert ctrl.fault and ctrl.fault_code == A.FAULT_TRACKING
    kf = int(np.argmax(np.abs(hit.e) > g.e_max))
    assert kf > 0 and np.all(hit.u[kf:] == 0.0) and hit.u[kf - 1] != 0.0
    assert np.array_equal(hit.u[:kf], clean.u[:kf])


def test_a_load_beyond_the_drive_latches_a_fault_within_milliseconds(axis):
    """A load step of 3 u_max pushes the axis away at an acceleration no validated run has: its readings
    are implausible to the innovation guard (or the error exceeds e_max), and a fault latches within
    n_reject_max samples of the first implausible reading (the true error may then exceed e_max already:
    no guard undoes the push of a load three times the drive's)."""
    g, traj = axis["g"], axis["trajs"]["case1"]
    k = traj.n // 3
    d = np.zeros(traj.n)
    d[k:] = 3.0 * axis["spec"].u_max
    hit = run(axis, g, traj, disturbance=d)
    u, ctrl = replay(g, hit, traj)
    assert ctrl.fault and ctrl.fault_code in (A.FAULT_GLITCH_RUN, A.FAULT_TRACKING)
    kf = int(np.argmax(hit.u[k:] == 0.0)) + k
    assert np.all(hit.u[kf:] == 0.0) and kf - k <= g.n_reject_max + 2


def test_frozen_encoder_at_1m_s_latches_within_n_frozen_max_and_never_reaches_the_rail(axis):
    """Issue 29 must-show 4 on the paper's axis: the encoder repeats one reading for 20 ms in the
    1 m/s cruise.  Each frozen reading misses the prediction by v Ts or more, is rejected (the law runs
    on the held tracking error) and counts: the n_frozen_max-th latches FAULT_FROZEN."""
    g = axis["g"]
    traj, k0 = cruise(axis)
    nf = round(0.02 / g.Ts)
    r = sensor_loop(axis, g, traj, frozen(k0, nf), k0 + nf + 100)
    at_rail = int(np.sum(np.abs(r["u"][k0:]) >= g.u_max))
    assert at_rail == 0  # must-show 4 asks for at most 5
    kf = k0 + int(np.argmax(r["fault"][k0:] != 0))
    assert r["fault"][kf] == A.FAULT_FROZEN and kf - k0 == g.n_frozen_max - 1
    assert np.all(r["rejected"][k0:kf] == 1.0) and np.all(r["u"][kf:] == 0.0)
    assert A.FAULT_REASONS[A.FAULT_FROZEN].startswith("measurement frozen")


def test_frozen_encoder_half_way_up_the_acceleration_latches_within_n_frozen_max(axis):
    g = axis["g"]
    traj = axis["trajs"]["case2"]
    k_move = int(np.argmax(np.abs(traj.dqd) > 0.0))
    k0 = k_move + int(np.argmax(np.abs(traj.dqd[k_move:]) >= 0.5 * axis["spec"].v_max))
    nf = round(0.02 / g.Ts)
    r = sensor_loop(axis, g, traj, frozen(k0, nf), k0 + nf + 100)
    assert not np.any(np.abs(r["u"][k0:]) >= g.u_max)
    kf = k0 + int(np.argmax(r["fault"][k0:] != 0))
    assert r["fault"][kf] == A.FAULT_FROZEN and kf - k0 == g.n_frozen_max - 1


def test_frozen_encoder_at_rest_is_caught_at_the_latest_when_it_recovers(axis):
    """Frozen from just before a move starts: the prediction says "still", and on this axis the command
    stays below u_free during the 20 ms (the push that would prove a motion), so no guard can tell the
    reading from a still axis -- the limit of the frozen-encoder guard at rest (docs/interface.md).  No
    sample reaches the rail, and the reading's jump when the encoder recovers is rejected: n_reject_max
    of them latch FAULT_GLITCH_RUN."""
    g = axis["g"]
    traj = axis["trajs"]["case2"]
    k0 = int(np.argmax(np.abs(traj.dqd) > 0.0)) - 5
    nf = round(0.02 / g.Ts)
    r = sensor_loop(axis, g, traj, frozen(k0, nf), k0 + nf + 100)
    assert np.max(np.abs(r["u"][k0:k0 + nf])) < g.u_free
    assert not np.any(np.abs(r["u"][k0:]) >= g.u_max)
    kf = k0 + int(np.argmax(r["fault"][k0:] != 0))
    assert r["fault"][kf] == A.FAULT_GLITCH_RUN and kf == k0 + nf + g.n_reject_max - 1


@pytest.mark.parametrize("amp", [0.3e-3, 0.79e-3, -0.79e-3, 1e-3, -1e-3])
def test_glitch_beyond_the_bound_is_rejected_alone_and_costs_no_rail_sample(axis, amp):
    """Issue 29: a 0.3 mm glitch (below dy_max) put 2 samples at the rail; a 0.79 mm glitch was
    accepted and the good reading after it rejected.  Now each misses the prediction, is rejected, and
    the next reading -- compared with the prediction from before the glitch -- is accepted."""
    g = axis["g"]
    traj, k0 = cruise(axis)
    r = sensor_loop(axis, g, traj, lambda k, y: y + amp if k == k0 else y, k0 + 200)
    assert np.nonzero(r["rejected"])[0].tolist() == [k0]
    assert not np.any(np.abs(r["u"]) >= g.u_max) and not np.any(r["fault"])


@pytest.mark.parametrize("frac", [0.9, -0.9])
def test_glitch_below_the_bound_is_accepted_and_so_is_the_next_reading_no_rail(axis, frac):
    """A glitch of 0.9 x the innovation bound the step held that sample to passes, and so do the good
    readings after it (the prediction uses the velocity of the pair before the last: a glitch among
    the accepted readings shifts the next innovations by at most the glitch); no sample at the rail."""
    g = axis["g"]
    traj, k0 = cruise(axis)
    clean = sensor_loop(axis, g, traj, lambda k, y: y, k0 + 1)
    amp = frac * clean["bound"][k0]
    assert 5 * LSB < abs(amp) < 0.1 * g.dy_max
    r = sensor_loop(axis, g, traj, lambda k, y: y + amp if k == k0 else y, k0 + 200)
    assert not np.any(r["rejected"]) and not np.any(r["fault"])
    assert not np.any(np.abs(r["u"]) >= g.u_max)


def test_no_glitch_of_any_size_puts_the_cruise_at_the_rail(axis):
    """One-sample glitches from 2 um to 1 mm, both signs, in the 1 m/s cruise: none reaches u_max
    (below the bound the kick is small, above it the reading is rejected)."""
    g = axis["g"]
    traj, k0 = cruise(axis)
    for amp in np.geomspace(2e-6, 1e-3, 16):
        for sign in (1.0, -1.0):
            r = sensor_loop(axis, g, traj, lambda k, y: y + sign * amp if k == k0 else y, k0 + 60)
            assert not np.any(np.abs(r["u"]) >= g.u_max), sign * amp


def test_exported_c_runs_the_new_guards_bit_for_bit(axis, tmp_path):
    """The C export (translated from arc_step) on readings that take every branch of the issue-29
    guards: a frozen encoder at speed, a rejected glitch, an accepted one, and one at rest.  Replayed
    by the export's own test program: max |u_C - u_Py| = 0 and the same fault codes."""
    from typer.testing import CliRunner

    from commission.cli.main import app
    from commission.export import Vectors
    from commission.export.build import build_replay, find_cc
    from commission.jsonio import write_json_atomic

    if find_cc() is None:
        pytest.skip("no C compiler (cc) on the PATH")
    g = axis["g"]
    traj, k0 = cruise(axis)
    n = k0 + 150
    k_move = int(np.argmax(np.abs(traj.dqd) > 0.0))
    cases = {"frozen": frozen(k0, 50), "rest": frozen(k_move - 5, 50),
             "glitch": lambda k, y: y + (0.3e-3 if k == k0 else 8e-6 if k == k0 + 40 else 0.0)}
    rows = {c: [] for c in ("scenario", "k", "y", "qd", "dqd", "ddqd", "u", "fault")}
    codes = set()
    for name, sensor in cases.items():
        r = sensor_loop(axis, g, traj, sensor, n)
        codes |= set(r["fault"].astype(int).tolist())
        for c, v in (("scenario", [name] * n), ("k", range(n)), ("y", r["y"]), ("qd", traj.qd[:n]),
                     ("dqd", traj.dqd[:n]), ("ddqd", traj.ddqd[:n]), ("u", r["u"]), ("fault", r["fault"])):
            rows[c].extend(v)
    assert {A.FAULT_FROZEN, A.FAULT_GLITCH_RUN} <= codes
    vec = Vectors(**{c: (tuple(v) if c == "scenario" else np.array(v)) for c, v in rows.items()})
    write_json_atomic(tmp_path / "controller.json", controller(g).config.to_dict())
    res = CliRunner().invoke(app, ["export", str(tmp_path / "controller.json"), "--target", "c", "--out-dir",
                                   str(tmp_path / "c")])
    assert res.exit_code == 0, res.output
    (tmp_path / "vectors.csv").write_text(vec.csv())
    exe = build_replay(tmp_path / "c", "arc", tmp_path / "replay")
    out = subprocess.run([str(exe), str(tmp_path / "vectors.csv")], capture_output=True, text=True)
    assert out.stdout.split() == ["rows", str(3 * n), "max_abs_diff", "0", "unequal", "0", "fault_mismatch", "0"]


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
                              "e_max": g.e_max, "freeze_on_saturation": True, "accel_max": g.accel_max,
                              "y_err": g.y_err, "n_frozen_max": g.n_frozen_max, "u_free": g.u_free}
    assert ControllerConfig.from_dict(doc).gains == g
    assert "runtime" not in controller(axis["raw"]).config.to_dict()  # files without guards keep their checksum
    for field, bad in (("n_reject_max", 0.5), ("dy_max", -1.0), ("e_max", 0.0), ("accel_max", 0.0),
                       ("y_err", -1e-6), ("n_frozen_max", 2.5), ("u_free", math.inf)):
        with pytest.raises(ValueError, match=field):
            dataclasses.replace(g, **{field: bad})
    assert math.isinf(axis["raw"].dy_max)


def test_a_runtime_section_written_before_issue_29_loads_with_those_guards_off(axis):
    """The keys added by issue 29 are optional: a file without them loads, keeps its checksum,
    and runs exactly the guards it names."""
    old = dataclasses.replace(axis["g"], accel_max=math.inf, y_err=0.0, n_frozen_max=math.inf, u_free=0.0)
    doc = controller(old).config.to_dict()
    assert set(doc["runtime"]) == {"dy_max", "dy_fault", "n_reject_max", "e_max", "freeze_on_saturation"}
    back = ControllerConfig.from_dict(doc)
    assert back.gains == old and back.to_dict()["checksum"] == doc["checksum"]
    doc["runtime"]["y_err"] = -1.0  # a present key is checked like any other
    doc.pop("checksum")
    with pytest.raises(ValueError, match="y_err"):
        ControllerConfig.from_dict(doc)


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
