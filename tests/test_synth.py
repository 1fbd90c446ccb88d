"""Synthetic excitation logs (commission.synth) and the bundled sample data."""

from __future__ import annotations

import importlib.util
import json
import math
from pathlib import Path

import h5py
import numpy as np
import pytest

from commission.errors import DataError, UsageError
from commission.jsonio import sha256_file
from commission.synth import (
    AxisTruth,
    ExcitationPlan,
    RANDOM_RATES,
    excitation_plan,
    loop_gains,
    random_axis,
    rigid_random_axis,
    simulate_excitation,
    write_log_csv,
    write_log_h5,
)
from commission.synth.simulation import _closed_loop

SAMPLE_DIR = Path(__file__).resolve().parents[1] / "sample_data"

# Close to the paper's Y axis (V units); 0.5 um encoder with a little noise.
AXIS = AxisTruth(M=0.032, B=0.25, fc=0.10, fs=0.12, vs=0.01, xi=2.0, offset=0.01,
                 ripple_amp=0.01, ripple_pitch=0.03, lsb=0.5e-6, sample_rate=2500.0,
                 noise_std=0.1e-6)
PLAN = ExcitationPlan()


@pytest.fixture(scope="module")
def log() -> dict[str, np.ndarray]:
    return simulate_excitation(AXIS, PLAN, np.random.default_rng(7))


def _load_generator():
    spec = importlib.util.spec_from_file_location("make_sample_data", SAMPLE_DIR / "make_sample_data.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def _leg_velocities(t: np.ndarray, q: np.ndarray, leg, settle: float = 0.1, chunk: float = 0.1):
    """Mean velocity of a leg after ``settle`` s, and the velocities of its ``chunk``-s pieces (m/s)."""
    m = (t >= leg.start + settle) & (t <= leg.stop)
    tt, qq = t[m], q[m]
    mean = (qq[-1] - qq[0]) / (tt[-1] - tt[0])
    k = int(round(chunk / (tt[1] - tt[0])))
    pieces = (qq[k::k] - qq[:-k:k][: qq[k::k].size]) / (tt[k::k] - tt[:-k:k][: tt[k::k].size])
    return mean, pieces


# --------------------------------------------------------------------------- truth


def test_truth_dict_round_trip_and_units():
    d = AXIS.to_dict()
    assert AxisTruth.from_dict(json.loads(json.dumps(d))) == AXIS
    assert d["parameters"]["M"] == {"value": 0.032, "unit": "V s^2/m"}
    assert d["parameters"]["vs"]["unit"] == "m/s"
    n = AxisTruth(M=1.0, B=0.0, fc=0.0, fs=0.0, vs=0.01, xi=2.0, u_unit="N")
    assert n.to_dict()["parameters"]["B"]["unit"] == "N s/m"


@pytest.mark.parametrize("bad, field", [({"M": 0.0}, "M"), ({"lsb": -1e-6}, "lsb"),
                                        ({"vs": float("nan")}, "vs"), ({"u_unit": "W"}, "u_unit")])
def test_truth_rejects_bad_values_naming_the_field(bad, field):
    kw = dict(M=0.03, B=0.2, fc=0.1, fs=0.12, vs=0.01, xi=2.0) | bad
    with pytest.raises(ValueError, match=field):
        AxisTruth(**kw)


def test_rigid_random_axis_is_reproducible_and_in_range():
    a = [rigid_random_axis(np.random.default_rng(s)) for s in range(40)]
    assert a[3] == rigid_random_axis(np.random.default_rng(3))
    assert len({x.M for x in a}) == 40  # really random
    for x in a:
        assert 0.01 <= x.M <= 0.2 and 3 <= x.B / x.M <= 30
        assert 1.0 <= x.fc / x.M <= 6.0 and 1.1 <= x.fs / x.fc <= 1.6
        assert 0.003 <= x.vs <= 0.03 and 0.05e-6 <= x.lsb <= 1e-6
        assert x.sample_rate in (1000.0, 2000.0, 2500.0, 4000.0, 5000.0)
        assert x.noise_std <= 0.3 * x.lsb
    assert {x.sample_rate for x in a} == {1000.0, 2000.0, 2500.0, 4000.0, 5000.0}
    assert rigid_random_axis(np.random.default_rng(0), sample_rate=3000.0).sample_rate == 3000.0



#: Seeds swept by the widened generator's range test (cheap: draws only, no simulation).
RANGE_SEEDS = range(400)


def test_a_two_mode_truth_round_trips_through_json():
    two = AxisTruth(**{**AXIS.__dict__, "mode_hz": 300.0, "mode_ratio": 0.3, "mode2_hz": 900.0,
                       "mode2_damping": 0.04, "mode2_ratio": 0.1, "mode2_load_side": True, "input_gain": 25.0})
    d = json.loads(json.dumps(two.to_dict()))
    assert d["parameters"]["mode2_hz"] == {"value": 900.0, "unit": "Hz"}
    assert d["parameters"]["input_gain"] == {"value": 25.0, "unit": "N/V"}
    assert AxisTruth.from_dict(d) == two
    assert "mode2_hz" not in AXIS.to_dict()["parameters"]  # a one-mode truth reads as before
    with pytest.raises(ValueError, match="mode2_hz"):
        AxisTruth(**{**AXIS.__dict__, "mode2_hz": 900.0})  # a second mode needs a first


def test_random_axis_draws_stay_within_the_stated_ranges():
    """Issue 30's spread of real machines: every draw of seeds 0-399 is within the documented ranges."""
    a = [random_axis(np.random.default_rng(s)) for s in RANGE_SEEDS]
    assert a[7] == random_axis(np.random.default_rng(7))
    for x in a:
        assert 0.3 <= x.mass_kg <= 300.0
        assert x.u_unit in ("V", "N")
        if x.u_unit == "V":
            assert x.u_max == 10.0
        else:
            assert x.input_gain == 1.0
        assert 20.0 <= x.u_max / x.M <= 200.0 * (1 + 1e-12)  # peak acceleration at the rail, m/s^2
        assert 3 <= x.B / x.M <= 30 and 1.0 <= x.fc / x.M <= 6.0 and 1.1 <= x.fs / x.fc <= 1.6
        assert 0.05e-6 <= x.lsb <= 1e-6 and 0.0 <= x.noise_std <= x.lsb  # noise up to 1 count rms
        assert x.sample_rate in RANDOM_RATES and 1000.0 <= x.sample_rate <= 20000.0
        assert 0.0 <= x.delay * x.sample_rate <= 2.0  # 0-2 samples
        for f, z, r in ((x.mode_hz, x.mode_damping, x.mode_ratio), (x.mode2_hz, x.mode2_damping, x.mode2_ratio)):
            if f > 0:
                assert 200.0 <= f <= 2000.0 and 0.01 <= z <= 0.08 and 0.05 <= r <= 0.5
        if x.mode2_hz > 0:
            assert x.mode_hz > 0 and x.mode2_hz >= x.mode_hz * (1 - 1e-12)
    # every kind occurs: 0, 1 and 2 modes, both encoder sides, both command units, the rates' ends
    assert {x.n_modes for x in a} == {0, 1, 2}
    assert {x.mode_load_side for x in a if x.n_modes} == {False, True}
    assert {x.mode2_load_side for x in a if x.n_modes == 2} == {False, True}
    assert {x.u_unit for x in a} == {"V", "N"}
    assert {1000.0, 20000.0} <= {x.sample_rate for x in a}
    masses = np.array([x.mass_kg for x in a])
    assert masses.min() < 1.0 and masses.max() > 100.0  # three decades are really covered
    assert max(x.noise_std / x.lsb for x in a) > 0.9 and max(x.delay * x.sample_rate for x in a) > 1.9
    assert random_axis(np.random.default_rng(0), sample_rate=3000.0).sample_rate == 3000.0


def test_heavier_random_axes_have_lower_modes():
    """The first mode falls with the mass: its log-log slope over seeds 0-399 is about -1/3."""
    a = [random_axis(np.random.default_rng(s)) for s in RANGE_SEEDS]
    m = np.array([(x.mass_kg, x.mode_hz) for x in a if x.mode_hz > 0])
    slope = np.polyfit(np.log(m[:, 0]), np.log(m[:, 1]), 1)[0]
    assert -0.45 < slope < -0.2, slope
    light, heavy = m[m[:, 0] < 3.0, 1], m[m[:, 0] > 30.0, 1]
    assert np.median(heavy) < 0.5 * np.median(light)


@pytest.mark.parametrize("seed", [1, 2, 4, 5, 7])
def test_a_widened_random_axis_log_stays_within_its_force_and_travel(seed):
    """Seeds 1 (5 kHz, 457 Hz load-side mode), 2 (10 kHz, N), 4 (202 kg, 2-sample delay, motor-side
    334 Hz mode), 5 (78 kg, two modes at 287 and 585 Hz, encoder on the second load) and 7 (20 kHz,
    22 kg in N): the commissioning loop of :func:`excitation_plan` stays stable and within the
    rail, and the axis moves within the plan's travel."""
    truth = random_axis(np.random.default_rng(seed))
    assert truth.n_modes == {1: 1, 2: 1, 4: 1, 5: 2, 7: 1}[seed]
    plan = excitation_plan(truth)
    d = simulate_excitation(truth, plan, np.random.default_rng(seed + 1000))
    assert np.max(np.abs(d["u"])) < truth.u_max
    assert np.max(np.abs(d["q"] - d["q_ref"])) < 5e-3  # bounded: a stable loop, though a soft one on a mode
    assert -5e-3 < d["q"].min() and d["q"].max() < plan.travel + 5e-3
    ref = plan.reference(truth.sample_rate)
    fast = max(ref.legs, key=lambda leg: abs(leg.velocity))
    mean, _ = _leg_velocities(d["t"], d["q"], fast, settle=0.3)
    assert mean == pytest.approx(fast.velocity, rel=0.05)


# --------------------------------------------------------------------------- plan / reference


def test_plan_ladder_design():
    speeds = PLAN.speeds
    assert speeds[0] == pytest.approx(0.001) and speeds[-1] == pytest.approx(0.25)
    assert np.allclose(speeds[1:] / speeds[:-1], (0.25 / 0.001) ** (1 / 8))
    legs = PLAN.reference(2500.0).legs
    assert len(legs) == 2 * speeds.size
    for fwd, back, v in zip(legs[::2], legs[1::2], speeds):
        # Each speed runs forward, then back over the same stretch of travel
        # (ripple and offset cancel between the two directions).
        assert fwd.velocity == pytest.approx(v) and back.velocity == pytest.approx(-v)
        T = fwd.stop - fwd.start
        assert back.stop - back.start == pytest.approx(T)
        assert back.x_start == pytest.approx(fwd.x_start + v * T)
        assert T >= PLAN.leg_min_time
    # Plenty of legs below 3 vs (Stribeck region of the sample axis) and above.
    assert sum(v < 3 * AXIS.vs for v in speeds) >= 4 and sum(v > 3 * AXIS.vs for v in speeds) >= 3


def test_reference_is_smooth_and_its_derivatives_are_consistent():
    fs = 10_000.0
    r = PLAN.reference(fs)
    T = 1.0 / fs
    assert r.t[-1] == pytest.approx(PLAN.duration, abs=T)
    assert r.q.min() >= -1e-12 and r.q.max() <= PLAN.travel
    # Analytic velocity/acceleration against finite differences of the position.
    assert np.max(np.abs(np.gradient(r.q, T) - r.qd)) < 1e-3
    assert np.max(np.abs(np.gradient(r.qd, T) - r.qdd)) < 0.05
    # Acceleration is continuous (cosine ramps, quintic multisine fade): its
    # largest sample-to-sample step halves when the rate doubles; a jump would not.
    r2 = PLAN.reference(2 * fs)
    ratio = np.max(np.abs(np.diff(r.qdd))) / np.max(np.abs(np.diff(r2.qdd)))
    assert ratio == pytest.approx(2.0, rel=0.05)
    assert r.q[0] == 0.0 and r.q[-1] == pytest.approx(0.0, abs=1e-12)


def test_multisine_reaches_its_design_acceleration_with_reversals():
    r = PLAN.reference(5000.0)
    m = (r.t >= r.multisine[0]) & (r.t <= r.multisine[1])
    assert np.max(np.abs(r.qdd[m])) == pytest.approx(PLAN.ms_accel, rel=0.01)
    assert np.max(np.abs(r.q[m] - PLAN.travel / 2)) <= PLAN.ms_amplitude
    reversals = np.count_nonzero(np.diff(np.sign(r.qd[m][np.abs(r.qd[m]) > 1e-4])) != 0)
    assert reversals > 50


def test_injection_is_appended_and_leaves_the_default_run_alone():
    plain = PLAN.reference(2500.0)
    inj_plan = ExcitationPlan(injection_s=2.0)
    inj = inj_plan.reference(2500.0)
    assert plain.injection == () and ExcitationPlan().to_dict()["injection_s"] == 0.0
    n = plain.t.size
    for k in ("t", "q", "qd", "qdd"):
        assert np.array_equal(getattr(inj, k)[:n], getattr(plain, k)), k  # the same run, then the injection
    assert len(inj.injection) == 2 and inj.injection[0][0] >= plain.t[-1]
    for (a, b), sgn in zip(inj.injection, (1.0, -1.0)):
        assert b - a == pytest.approx(1.0)
        m = (inj.t >= a) & (inj.t < b)
        assert np.allclose(inj.qd[m], sgn * inj_plan.injection_velocity)
    assert inj.q[-1] == pytest.approx(0.0, abs=1e-12) and inj.q.max() <= inj_plan.travel
    prbs = inj_plan.injection_signal(inj.t)
    on = np.zeros(inj.t.size, bool)
    for a, b in inj.injection:
        on |= (inj.t >= a) & (inj.t < b)
    assert set(np.unique(prbs[on])) == {-1.0, 1.0} and np.all(prbs[~on] == 0.0)
    assert abs(prbs[on].mean()) < 0.01  # balanced: no net force
    with pytest.raises(ValueError, match="injection legs need"):
        ExcitationPlan(injection_s=8.0)
    with pytest.raises(ValueError, match="injection_s"):
        ExcitationPlan(injection_s=-1.0)


def test_the_logged_command_carries_the_injection_while_the_axis_keeps_moving():
    plan = ExcitationPlan(n_speeds=3, ms_duration=3.0, injection_s=2.0)
    d = simulate_excitation(AXIS, plan, np.random.default_rng(7))
    ref = plan.reference(AXIS.sample_rate)
    amp = plan.guess_factor * AXIS.M * plan.injection_accel
    for (a, b), sgn in zip(ref.injection, (1.0, -1.0)):
        m = (d["t"] >= a) & (d["t"] < b)
        # The PRBS dominates the sample-to-sample change of the command ...
        du = np.diff(d["u"][m])
        assert np.median(np.abs(du[np.abs(du) > amp])) == pytest.approx(2 * amp, rel=0.1)
        # ... and the axis moves on at the leg's speed without stopping (friction keeps one sign).
        v = np.diff(d["q"][m][::10]) * AXIS.sample_rate / 10
        assert np.all(sgn * v > 0.2 * plan.injection_velocity)
        assert np.mean(v) == pytest.approx(sgn * plan.injection_velocity, rel=0.03)


def test_a_mode_and_a_delay_change_the_log_and_round_trip_as_truth():
    late = AxisTruth(**{**AXIS.__dict__, "mode_hz": 400.0, "mode_damping": 0.05, "mode_ratio": 0.3,
                        "mode_load_side": True, "delay": 0.4e-3})
    d = late.to_dict()
    assert d["parameters"]["mode_load_side"] == {"value": 1.0, "unit": "1"}
    assert d["parameters"]["delay"]["unit"] == "s" and d["parameters"]["mode_hz"]["unit"] == "Hz"
    back = AxisTruth.from_dict(json.loads(json.dumps(d)))
    assert back == late and back.mode_load_side is True
    p = late.plant()
    assert (p[9], p[10], p[11], p[12], p[13]) == (400.0, 0.05, 0.3, 1.0, 0.4e-3)
    with pytest.raises(ValueError, match="mode_ratio"):
        AxisTruth(**{**AXIS.__dict__, "mode_ratio": 1.0})


def test_the_logs_loop_applies_a_fractional_input_delay_inside_the_sample():
    # Open loop (zero gains) on a frictionless unit mass: a one-sample command pulse issued at
    # sample 10 acts from 10 T + tau to 11 T + tau.  With tau = 1.4 T the encoder sees nothing up
    # to sample 11 and 0.5 (0.6 T)^2 at sample 12 (a delay rounded to 1 or 2 samples gives 0.5 T^2 or 0).
    T = 1.0 / 2500.0
    truth = AxisTruth(M=1.0, B=0.0, fc=0.0, fs=0.0, vs=0.01, xi=2.0, lsb=1e-15, sample_rate=2500.0,
                      delay=1.4 * T)
    n = 20
    u_ff = np.zeros(n)
    u_ff[10] = 1.0
    q, u = np.empty(n), np.empty(n)
    z = np.zeros(n)
    _closed_loop(truth.plant(), z, z, u_ff, z, truth.lsb, T, 100, 0.0, 0.0, 0.0, 10.0, q, u)
    assert np.array_equal(u, u_ff)  # the log holds the command as issued, not as applied
    assert np.all(q[:12] == 0.0)
    t = np.arange(n) * T
    ts, te = 10 * T + 1.4 * T, 11 * T + 1.4 * T
    exact = np.where(t < ts, 0.0, np.where(t < te, 0.5 * (t - ts) ** 2, 0.5 * T**2 + T * (t - te)))
    # Semi-implicit Euler at T/100 leads by half a sub-step: within 2 % of T^2 of the exact path.
    assert np.max(np.abs(q - exact)) < 0.02 * T**2
    assert q[12] == pytest.approx(0.5 * (0.6 * T) ** 2, rel=0.05)


def test_plan_rejects_a_leg_that_does_not_fit_the_travel():
    with pytest.raises(ValueError, match=r"ladder speed 0.773395 m/s needs 0.856475 m of travel for a 0.5 s leg; travel is 0.3 m"):
        ExcitationPlan(v_max=2.0)
    with pytest.raises(ValueError, match="v_max"):
        ExcitationPlan(v_min=0.01, v_max=0.005)


# --------------------------------------------------------------------------- simulation


def test_same_seed_same_log_and_the_seed_matters(log):
    again = simulate_excitation(AXIS, PLAN, np.random.default_rng(7))
    for k in log:
        assert np.array_equal(log[k], again[k]), k
    other = simulate_excitation(AXIS, PLAN, np.random.default_rng(8))
    assert not np.array_equal(log["q"], other["q"])


def test_log_satisfies_the_contract(log):
    assert list(log) == ["t", "q", "u", "q_ref"]
    n = log["t"].size
    assert n == int(math.floor(PLAN.duration * AXIS.sample_rate + 1e-9)) + 1
    for k, a in log.items():
        assert a.dtype == np.float64 and a.shape == (n,) and np.all(np.isfinite(a)), k
    dt = np.diff(log["t"])
    assert log["t"][0] == 0.0 and np.all(dt > 0)
    assert np.allclose(dt, 1.0 / AXIS.sample_rate, rtol=1e-9, atol=0)
    counts = log["q"] / AXIS.lsb
    assert np.max(np.abs(counts - np.round(counts))) < 1e-6
    assert np.max(np.abs(log["u"])) < AXIS.u_max


def test_command_is_clipped_at_the_rail():
    tight = AxisTruth(**{**AXIS.__dict__, "u_max": 0.3})
    d = simulate_excitation(tight, PLAN, np.random.default_rng(0))
    assert np.max(np.abs(d["u"])) == 0.3  # the 20 m/s^2 multisine needs more than 0.3 V


def test_pid_tracks_the_reference(log):
    e = log["q"] - log["q_ref"]
    # 40 Hz loop with feedforward: ~10 um rms, < 0.1 mm peak (at the fast multisine
    # and at break-away); a loop that lost track would be off by millimetres.
    assert np.sqrt(np.mean(e**2)) < 30e-6
    assert np.max(np.abs(e)) < 0.3e-3


def test_ladder_legs_are_steady_at_the_planned_speeds(log):
    legs = PLAN.reference(AXIS.sample_rate).legs
    for leg in legs:
        mean, pieces = _leg_velocities(log["t"], log["q"], leg)
        # Measured mean within 2 % of the plan, and no stick-slip: every
        # 0.1-s piece within 10 % (the slowest leg is 1 mm/s = 200 counts / 0.1 s).
        assert mean == pytest.approx(leg.velocity, rel=0.02), leg
        assert np.all(np.abs(pieces / leg.velocity - 1.0) < 0.10), leg
    # The command on the two legs of a speed differs by twice the friction at
    # that speed (offset and ripple cancel): the Stribeck curve is in the data.
    for fwd, back in zip(legs[::2], legs[1::2]):
        v = fwd.velocity
        uf = log["u"][(log["t"] >= fwd.start + 0.1) & (log["t"] <= fwd.stop)].mean()
        ub = log["u"][(log["t"] >= back.start + 0.1) & (log["t"] <= back.stop)].mean()
        friction = AXIS.B * v + AXIS.fc + (AXIS.fs - AXIS.fc) * math.exp(-abs(v / AXIS.vs) ** AXIS.xi)
        assert (uf - ub) / 2 == pytest.approx(friction, rel=0.03), v


@pytest.mark.parametrize("seed", [11, 12, 13])
def test_random_axes_run_cleanly(seed):
    truth = rigid_random_axis(np.random.default_rng(seed))
    d = simulate_excitation(truth, PLAN, np.random.default_rng(seed))
    assert np.max(np.abs(d["u"])) < truth.u_max
    assert np.max(np.abs(d["q"] - d["q_ref"])) < 0.5e-3
    for leg in PLAN.reference(truth.sample_rate).legs:
        mean, _ = _leg_velocities(d["t"], d["q"], leg)
        assert mean == pytest.approx(leg.velocity, rel=0.03), (truth, leg)


def test_loop_gains_follow_the_design():
    kp, kd, ki = loop_gains(AXIS, PLAN)
    w = 2 * math.pi * PLAN.bandwidth_hz
    Mg = PLAN.guess_factor * AXIS.M
    assert kp == pytest.approx(Mg * w**2) and kd == pytest.approx(2 * PLAN.damping * Mg * w)
    assert ki == pytest.approx(kp * 2 * math.pi * PLAN.integral_hz)


# --------------------------------------------------------------------------- writers


def test_h5_writer_round_trips(tmp_path, log):
    p = tmp_path / "log.h5"
    write_log_h5(p, log, q_unit="m", u_unit="V")
    with h5py.File(p, "r") as f:
        assert sorted(f.keys()) == ["q", "q_ref", "t", "u"]
        assert f.attrs["q_unit"] == "m" and f.attrs["u_unit"] == "V"
        for k in log:
            assert f[k].ndim == 1 and f[k].dtype == np.float64
            assert np.array_equal(f[k][()], log[k]), k
    # Deterministic bytes: the same data written twice gives the same file.
    p2 = tmp_path / "log2.h5"
    write_log_h5(p2, log)
    assert sha256_file(p) == sha256_file(p2)


def test_csv_writer_round_trips(tmp_path, log):
    p = tmp_path / "log.csv"
    write_log_csv(p, log)
    with open(p) as fh:
        assert fh.readline().strip() == "t,q,u,q_ref"
    cols = np.loadtxt(p, delimiter=",", skiprows=1)
    for i, k in enumerate(log):
        assert np.allclose(cols[:, i], log[k], rtol=1e-11, atol=1e-15), k
    assert np.array_equal(cols[:, 0], log["t"])  # k / fs prints and parses exactly
    p2 = tmp_path / "short.csv"
    write_log_csv(p2, {"t": [0.0, 0.001], "q": [0.0, 1e-6], "u": [0.5, -0.25]})
    assert p2.read_text() == "t,q,u\n0,0,0.5\n0.001,1e-06,-0.25\n"


@pytest.mark.parametrize("writer", [write_log_h5, write_log_csv])
@pytest.mark.parametrize("data, msg", [
    ({"t": [0.0, 1.0, 1.0], "q": [0, 0, 0], "u": [0, 0, 0]},
     r"t: not strictly increasing at index 2 \(t\[2\]=1.0 <= t\[1\]=1.0\)"),
    ({"t": [0.0, 1.0, 2.0], "q": [0, np.nan, 0], "u": [0, 0, 0]}, r"q: sample 1 is nan"),
    ({"t": [0.0, 1.0], "q": [0, 0]}, r"required channel 'u'"),
    ({"t": [0.0, 1.0], "q": [0, 0], "u": [0, 0], "v": [0, 0]}, r"unknown channel 'v'"),
    ({"t": [0.0, 1.0], "q": [0, 0, 0], "u": [0, 0]}, r"q: 3 samples, but t has 2"),
    ({"t": [0.0, 1.0], "q": [[0, 0]], "u": [0, 0]}, r"q: expected a 1-D array, got shape \(1, 2\)"),
])
def test_writers_reject_bad_logs_and_write_nothing(tmp_path, writer, data, msg):
    p = tmp_path / ("bad.h5" if writer is write_log_h5 else "bad.csv")
    with pytest.raises(DataError, match=msg):
        writer(p, data)
    assert list(tmp_path.iterdir()) == []


def test_h5_writer_rejects_unknown_units(tmp_path, log):
    with pytest.raises(UsageError, match="q_unit"):
        write_log_h5(tmp_path / "x.h5", log, q_unit="inch")
    with pytest.raises(UsageError, match="u_unit"):
        write_log_h5(tmp_path / "x.h5", log, u_unit="W")
    assert list(tmp_path.iterdir()) == []


# --------------------------------------------------------------------------- bundled sample data


def test_sample_files_match_their_recorded_checksums():
    truth = json.loads((SAMPLE_DIR / "truth.json").read_text())
    assert set(truth["files"]) == {"axis_excitation.h5", "axis_excitation.csv", "plan.json"}
    for name, info in truth["files"].items():
        p = SAMPLE_DIR / name
        assert p.stat().st_size == info["bytes"], name
        assert sha256_file(p) == info["sha256"], name
    assert (SAMPLE_DIR / "axis_excitation.h5").stat().st_size < 3_000_000
    assert (SAMPLE_DIR / "axis_excitation.csv").stat().st_size < 6_000_000  # the CSV is in git
    assert sha256_file(SAMPLE_DIR / "limits.toml") == truth["spec"]["sha256"]


def test_sample_truth_matches_the_generator_and_the_files_agree():
    gen = _load_generator()
    truth = json.loads((SAMPLE_DIR / "truth.json").read_text())
    from commission.excite import load_excite_spec, load_plan_json, plan_run

    assert AxisTruth.from_dict(truth["axis"]) == gen.TRUTH
    # the sample is a recording of the plan that `commission excite` makes from sample_data/limits.toml
    spec = load_excite_spec(SAMPLE_DIR / "limits.toml")
    plan = plan_run(spec)
    plan_d = load_plan_json(SAMPLE_DIR / "plan.json")
    assert plan_d == json.loads(json.dumps(plan.to_dict()))
    assert [(s["name"], s["start_s"], s["stop_s"]) for s in truth["log"]["segments"]] == \
        [(s["name"], s["t_start"], s["t_end"]) for s in plan_d["segments"]]
    # the simulated axis is the one the sample claims: a structural mode and some delay
    assert gen.TRUTH.mode_hz > 0 and gen.TRUTH.delay > 0
    with h5py.File(SAMPLE_DIR / "axis_excitation.h5", "r") as f:
        h5 = {k: f[k][()] for k in ("t", "q", "u", "q_ref")}
        assert f.attrs["u_unit"] == truth["axis"]["u_unit"] and f.attrs["q_unit"] == "m"
    cols = np.loadtxt(SAMPLE_DIR / "axis_excitation.csv", delimiter=",", skiprows=1)
    for i, k in enumerate(("t", "q", "u", "q_ref")):
        assert np.array_equal(cols[:, i], h5[k]), k  # the same numbers in both files
    assert h5["t"].size == truth["log"]["samples"] == plan.t.size
    assert np.allclose(h5["t"], plan.t, rtol=0, atol=1e-9) and np.allclose(h5["q_ref"], plan.q_ref, rtol=1e-10, atol=1e-12)
    assert h5["t"][-1] + 1 / gen.TRUTH.sample_rate == pytest.approx(truth["log"]["duration_s"])
    lsb = gen.TRUTH.lsb
    assert np.max(np.abs(h5["q"] / lsb - np.round(h5["q"] / lsb))) < 1e-6
    # the recording keeps within the limits of limits.toml (0 violations of u, travel, speed)
    T = 1 / gen.TRUTH.sample_rate
    assert np.max(np.abs(h5["u"])) <= spec.u_max
    assert np.max(h5["q"]) - np.min(h5["q"]) <= spec.travel
    assert np.max(np.abs(np.diff(h5["q"]))) / T <= spec.v_max


def _assert_close_tree(a, b, path="$"):
    """Equal JSON trees, floats within 1e-14 relative (strings, ints, keys and lengths exactly)."""
    if isinstance(a, dict):
        assert isinstance(b, dict) and set(a) == set(b), path
        for k in a:
            _assert_close_tree(a[k], b[k], f"{path}.{k}")
    elif isinstance(a, list):
        assert isinstance(b, list) and len(a) == len(b), path
        for i, (x, y) in enumerate(zip(a, b)):
            _assert_close_tree(x, y, f"{path}[{i}]")
    elif isinstance(a, float) and isinstance(b, float):
        assert a == pytest.approx(b, rel=1e-14, abs=0.0), path
    else:
        assert a == b, path


def test_sample_data_regenerates(tmp_path):
    # Rebuild from the script and compare with the committed files, so they
    # cannot drift from the generator.  Bit-identical on one platform; the
    # tolerances allow a libm last-bit difference elsewhere flipping a few
    # encoder counts (a change of parameters or plan moves far more).
    gen = _load_generator()
    new = gen.build(tmp_path)
    old = json.loads((SAMPLE_DIR / "truth.json").read_text())
    # truth.json's derived figures (leg speeds from a geometric ladder) to the last bit or so: a
    # numpy build's pow can differ there
    _assert_close_tree({k: v for k, v in new.items() if k != "files"}, {k: v for k, v in old.items() if k != "files"})
    with h5py.File(SAMPLE_DIR / "axis_excitation.h5", "r") as f_old, \
            h5py.File(tmp_path / "axis_excitation.h5", "r") as f_new:
        a = {k: f_old[k][()] for k in f_old}
        b = {k: f_new[k][()] for k in f_new}
    assert (tmp_path / "plan.json").read_bytes() == (SAMPLE_DIR / "plan.json").read_bytes()
    assert sorted(a) == sorted(b) == ["q", "q_ref", "t", "u"]
    assert np.array_equal(a["t"], b["t"])
    assert np.max(np.abs(a["q_ref"] - b["q_ref"])) < 1e-12
    assert np.max(np.abs(a["q"] - b["q"])) <= 4 * gen.TRUTH.lsb
    assert np.sqrt(np.mean((a["u"] - b["u"]) ** 2)) < 5e-3


# --------------------------------------------------------------------------- random axes recorded with excite

# Development seeds: 27 (1 kHz, V, one mode), 7 (20 kHz, N, one mode: the plan is shortened),
# 3 (8 kHz, N, two modes, encoder on the loads), 0 (5 kHz, V, rigid).
EXCITE_SEEDS = {27: (1000.0, "V", 1), 7: (20000.0, "N", 1), 3: (8000.0, "N", 2), 0: (5000.0, "V", 0)}


@pytest.mark.parametrize("seed", list(EXCITE_SEEDS))
def test_an_excite_planned_random_axis_log_stays_within_rail_and_travel(tmp_path, seed):
    """The plan of `commission excite` from the axis's limits.toml, played on the TRUE axis (modes,
    delay, noise, quantization): the command never reaches the rail (the true loop clips there, so a
    peak below it means no saturation), the axis stays within the stated travel about the start and
    under the stated speed, and a 20 kHz plan is shortened below the sample budget."""
    from commission.synth import EXCITE_MAX_SAMPLES, record_random_axis_log

    rec = record_random_axis_log(seed, tmp_path / "log.h5")
    t = rec.truth
    assert (t.sample_rate, t.u_unit, t.n_modes) == EXCITE_SEEDS[seed]
    assert rec.log == "excite" and rec.requested == "excite"
    lim = rec.limits
    assert lim["limits"]["u_max"] == t.u_max and lim["drive"]["sample_rate"] == t.sample_rate
    assert 0.7 <= lim["axis"]["mass"] / t.M <= 1.4 and lim["axis"]["u_unit"] == t.u_unit
    with h5py.File(tmp_path / "log.h5") as f:
        q, u, tt = f["q"][:], f["u"][:], f["t"][:]
        assert f.attrs["u_unit"] == t.u_unit
    assert q.size == rec.samples <= EXCITE_MAX_SAMPLES
    assert rec.duration_s == pytest.approx(tt[-1] + 1.0 / t.sample_rate)
    assert np.max(np.abs(u)) < t.u_max
    assert np.max(np.abs(q)) <= lim["limits"]["travel"] / 2
    assert np.max(np.abs(np.diff(q))) * t.sample_rate <= lim["limits"]["v_max"]
    assert ("shortened" in rec.note) == (seed == 7)
    if seed == 7:
        assert lim["plan"]["n_speeds"] < 8


@pytest.mark.parametrize("seed", [27, pytest.param(7, marks=pytest.mark.slow)])
def test_identify_finds_the_broadband_segment_of_an_excite_planned_random_axis_log(tmp_path, seed):
    """`identify` on the excite-planned log measures a frequency response on its injection: backed well
    above the legacy run's rigid band (its multisine tops at 20 Hz and its ident.json says 14-22 Hz),
    coherent up to the mode (the injection's cruise keeps friction one-signed, so the response is
    linear), with its delay within 0.2 sample and the true axis's mode within 5 % -- or, where
    the mode sits in the last 2 % below Nyquist (seed 27: 492.7 Hz at 1 kHz), either that or no
    resonance claimed (the best fit on the edge of what the bins can show, reported as rigid).
    Since modes are fitted above Nyquist too (settings.MODE_MAX_NYQUIST), seed 27's fit places
    resonances at 490.6 and 491.1 Hz, within 0.5 % of the mode, and fits the response to its noise.
    (On the slow cruise excite planned before, friction crossing zero damped seed 27's peak down
    to a 484 Hz, zeta 0.062 "resonance" and held the coherence near the mode at 0.65.)"""
    from commission.identification import identify_log
    from commission.synth import record_random_axis_log

    rec = record_random_axis_log(seed, tmp_path / "log.h5")
    t = rec.truth
    fr = identify_log(str(tmp_path / "log.h5"), u_unit=t.u_unit).ident.to_dict()["frequency_response"]
    assert fr["source"] == "broadband"
    assert fr["band_hz"][1] >= 5 * max(ExcitationPlan().ms_freqs)
    f = np.asarray(fr["measured"]["frequency_hz"])
    coh = np.asarray(fr["measured"]["coherence"])
    assert np.min(coh[(f >= 20.0) & (f <= 1.05 * t.mode_hz)]) > 0.9  # up to the mode (the encoder's floor ends it higher)
    res = [m["frequency_hz"] for m in fr["modes"] if m["kind"] == "resonance"]
    if t.mode_hz > 0.98 * t.sample_rate / 2 and not res:
        assert "on the edge of what the data can show" in fr["note"], fr["note"]
    else:
        assert any(abs(f / t.mode_hz - 1) < 0.05 for f in res), (res, t.mode_hz)
    assert fr["delay_samples"] == pytest.approx(t.delay * t.sample_rate, abs=0.2)


def test_a_refused_excite_plan_falls_back_to_the_legacy_log_and_says_so(tmp_path, monkeypatch):
    import commission.synth as synth
    import commission.synth.record as record

    real = record.random_axis_limits

    def too_short(truth, rng):
        d = real(truth, rng)
        return {**d, "limits": {**d["limits"], "travel": 0.0005}}

    monkeypatch.setattr(record, "random_axis_limits", too_short)
    rec = synth.record_random_axis_log(27, tmp_path / "a.h5")
    assert rec.log == "legacy" and rec.requested == "excite" and rec.limits is None
    assert rec.note.startswith("excite refused, legacy log written: ") and "limits.travel" in rec.note
    legacy = synth.record_random_axis_log(27, tmp_path / "b.h5", log="legacy")
    assert legacy.note == "" and legacy.samples == rec.samples
    with h5py.File(tmp_path / "a.h5") as fa, h5py.File(tmp_path / "b.h5") as fb:
        assert np.array_equal(fa["q"][:], fb["q"][:]) and np.array_equal(fa["u"][:], fb["u"][:])
    with pytest.raises(UsageError, match="log: 'prbs' is not one of excite, legacy"):
        synth.record_random_axis_log(27, tmp_path / "c.h5", log="prbs")
    assert not (tmp_path / "c.h5").exists()
