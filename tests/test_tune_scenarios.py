"""The scenario matrix shared by tune and validate."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from commission.controllers.plant import (P_B, P_DELAY, P_FC, P_FS, P_M, P_MODE_DAMPING, P_MODE_HZ, P_MODE_LOAD_SIDE,
                                          P_MODE_RATIO, P_OFFSET, P_RIPPLE_AMP, P_RIPPLE_PITCH)
from commission.controllers.trajectory import back_and_forth, sinusoid
from commission.paper import reference_identification
from commission.scenarios import (
    case1_trajectory,
    case2_trajectory,
    corner_scenarios,
    payload_scenarios,
    force_range,
    identified_plant,
    offset_scenarios,
    plant_substeps,
    resolve_quantization,
    scenario_matrix,
    tuning_scenarios,
    viscous_range,
)
from commission.spec import default_spec, spec_from_mapping


ref_ident = reference_identification


def test_plant_substeps_keep_the_papers_plant_step():
    # 10 sub-steps at and below 2.5 kHz (the paper table's 40 us at 2.5 kHz); above, the fewest that keep
    # the plant step <= 40 us
    assert [plant_substeps(fs) for fs in (1000.0, 2000.0, 2500.0, 4000.0, 5000.0, 10000.0)] == [10, 10, 10, 7, 5, 3]
    for fs in np.geomspace(2500.0, 20000.0, 41)[1:]:
        n = plant_substeps(float(fs))
        assert 1.0 / (fs * n) <= 4e-5 * (1 + 1e-9) < 1.0 / (fs * (n - 1))


def test_default_envelope_gives_the_papers_cases():
    spec = default_spec()
    c1, c2 = case1_trajectory(spec), case2_trajectory(spec)
    assert (c1.amplitude, c1.omega, c1.duration) == (pytest.approx(0.05), pytest.approx(4.0), 10.0)
    assert c2.duration == pytest.approx(8.0)  # 6 moves of 0.983 s + 2.1 s at rest
    ref = sinusoid(10.0, spec.period, amplitude=0.05, omega=4.0)
    got = c1.render(spec.period)
    assert np.array_equal(got.qd, ref.qd) and np.array_equal(got.ddqd, ref.ddqd)
    assert np.array_equal(c2.render(spec.period).qd, back_and_forth(8.0, spec.period).qd)


def test_envelope_scaling_respects_limits():
    spec = spec_from_mapping({"trajectory": {"v_max": 0.2, "a_max": 1.0, "travel": 0.1}})
    c1 = case1_trajectory(spec)
    assert c1.amplitude * c1.omega <= 0.2 * spec.v_max + 1e-12
    assert c1.amplitude * c1.omega ** 2 <= spec.a_max / 15 + 1e-12
    assert c1.duration >= 4 * 2 * math.pi / c1.omega - 1e-9
    tr = case2_trajectory(spec).render(spec.period)
    assert np.max(np.abs(tr.dqd)) <= spec.v_max * 1.001
    assert np.max(tr.qd) == pytest.approx(spec.travel, abs=1e-4)


def test_matrix_contents():
    ident = ref_ident()
    spec = default_spec()
    sc = scenario_matrix(ident, spec, rng=np.random.default_rng(0), n_monte_carlo=8)
    names = [s.name for s in sc]
    # 12 fixed, one more sample of delay on each trajectory (rigid plant: no mode variants), 8 Monte-Carlo
    assert len(sc) == 12 + 2 + 8 and len(set(names)) == len(names)
    by = {s.name: s for s in sc}
    base = identified_plant(ident)
    assert np.array_equal(by["case1/nominal"].plant, base)
    assert by["case1/payload_light"].plant[P_M] == pytest.approx(1 / 50.0)
    assert by["case2/payload_heavy"].plant[P_M] == pytest.approx(1 / 8.3)
    for k in (P_B, P_FC, P_FS):
        assert by["case1/friction_low"].plant[k] == pytest.approx(0.8 * base[k])
        assert by["case1/friction_high"].plant[k] == pytest.approx(1.2 * base[k])
    d = by["case1/disturbance"].disturbance
    # Assumption-1 size delta_d M = 0.5 V, on 2.2 s .. 7.2 s of the 10 s run (paper Set 3)
    assert (d.amplitude, d.t_on, d.t_off) == (pytest.approx(0.5), pytest.approx(2.2), pytest.approx(7.2))
    t = np.arange(25000) / 2500.0
    assert np.count_nonzero(d.samples(t)) == 12500
    assert all("tune" in by[n].tags for n in names[:12])
    assert all("robustness" in by[n].tags and "tune" not in by[n].tags for n in names[12:14])
    assert all("monte_carlo" in by[n].tags for n in names[14:])
    for case in ("case1", "case2"):
        late = by[f"{case}/delay+1"].plant
        assert late[P_DELAY] == pytest.approx(spec.period) and np.array_equal(np.delete(late, P_DELAY),
                                                                              np.delete(base, P_DELAY))
    assert all(s.quantization == 1e-6 for s in sc)


def test_monte_carlo_is_seeded_and_inside_the_box():
    ident = ref_ident()
    spec = default_spec()
    a = scenario_matrix(ident, spec, rng=np.random.default_rng(5), n_monte_carlo=64)
    b = scenario_matrix(ident, spec, rng=np.random.default_rng(5), n_monte_carlo=64)
    c = scenario_matrix(ident, spec, rng=np.random.default_rng(6), n_monte_carlo=64)
    a, b, c = ([s for s in m if "monte_carlo" in s.tags] for m in (a, b, c))
    pa = np.stack([s.plant for s in a])
    assert np.array_equal(pa, np.stack([s.plant for s in b]))
    assert not np.array_equal(pa, np.stack([s.plant for s in c]))
    th = np.column_stack([1 / pa[:, P_M], pa[:, P_B] / pa[:, P_M], -pa[:, P_OFFSET] / pa[:, P_M]])
    lo, hi = np.array(ident.theta.min), np.array(ident.theta.max)
    assert np.all(th >= lo - 1e-9) and np.all(th <= hi + 1e-9)
    d_lo, d_hi = force_range(ident)
    assert (d_lo, d_hi) == (pytest.approx(-1.0), pytest.approx(1.0))  # +-50 m/s^2 at M = 0.02
    assert np.all(np.abs(pa[:, P_OFFSET]) <= 1.0 + 1e-12)
    # a payload adds mass only: B stays in the range the box admits at every mass
    b_lo, b_hi = viscous_range(ident)
    assert np.all((pa[:, P_B] >= b_lo - 1e-12) & (pa[:, P_B] <= b_hi + 1e-12))
    # the draws spread over the box (not stuck at a point)
    assert np.ptp(th[:, 0]) > 0.7 * (hi[0] - lo[0]) and np.ptp(pa[:, P_OFFSET]) > 1.4
    assert {s.trajectory.kind for s in a} == {"case1", "case2"}


def test_tuning_set_adds_the_corners():
    ident = ref_ident()
    spec = default_spec()
    ts = tuning_scenarios(ident, spec, rng=np.random.default_rng(0))
    corners = corner_scenarios(ident, spec)
    offsets = offset_scenarios(ident, spec)
    payloads = payload_scenarios(ident, spec)
    assert [s.name for s in ts] == [s.name for s in scenario_matrix(ident, spec, rng=np.random.default_rng(0),
                                                                     n_monte_carlo=0)
                                     if "tune" in s.tags or "robustness" in s.tags] + \
        [s.name for s in corners] + [s.name for s in offsets] + [s.name for s in payloads]
    assert len(corners) == 16 and len(offsets) == 4 and len(payloads) == 6
    # interior payloads: geometric steps from the identified mass to the heaviest, nothing else changed
    base = identified_plant(ident)
    m0, m_heavy = base[P_M], 1 / ident.theta.min[0]
    for s in payloads:
        k = float(s.name.rsplit("/", 1)[1])
        assert s.plant[P_M] == pytest.approx(m0 * (m_heavy / m0) ** k)
        assert np.array_equal(np.delete(s.plant, P_M), np.delete(base, P_M))
    assert sorted(float(s.name.rsplit("/", 1)[1]) for s in payloads) == [0.25] * 2 + [0.5] * 2 + [0.75] * 2
    # the largest-force plants: identified mass, force at both ends of force_range, inside the box
    base = identified_plant(ident)
    lo, hi = np.array(ident.theta.min), np.array(ident.theta.max)
    for s in offsets:
        assert np.array_equal(np.delete(s.plant, P_OFFSET), np.delete(base, P_OFFSET))
        th3 = -s.plant[P_OFFSET] / s.plant[P_M]
        assert lo[2] <= th3 <= hi[2]
    assert sorted(s.plant[P_OFFSET] for s in offsets) == [pytest.approx(-1.0)] * 2 + [pytest.approx(1.0)] * 2
    m = sorted({s.plant[P_M] for s in corners})
    assert m == [pytest.approx(1 / 50.0), pytest.approx(1 / 8.3)]
    assert sorted({s.plant[P_OFFSET] for s in corners}) == [pytest.approx(-1.0), pytest.approx(1.0)]


def test_ident_extras_feed_ripple_and_quantization():
    ident = ref_ident(model={"ripple_amp": {"value": -0.01, "std": 0.001}, "ripple_pitch": 0.03},
                      encoder={"quantization": 5e-8})
    p = identified_plant(ident)
    assert (p[P_RIPPLE_AMP], p[P_RIPPLE_PITCH]) == (0.01, 0.03)
    assert resolve_quantization(ident, default_spec()) == 5e-8
    assert resolve_quantization(ident, spec_from_mapping({"controller": {"quantization": 2e-6}})) == 2e-6
    assert resolve_quantization(ref_ident(), default_spec()) == 1e-6


def test_viscous_range_inverts_the_interval_box():
    # A box built by interval arithmetic from M in [m1, m2], B in [b1, b2]:
    # theta1 in [1/m2, 1/m1], theta2 in [b1/m2, b2/m1]; the range recovers [b1, b2] exactly.
    m1, m2, b1, b2 = 0.02, 0.11, 0.2, 0.33
    ident = ref_ident()
    box = dataclasses.replace(ident.theta, min=(1 / m2, b1 / m2, ident.theta.min[2]),
                              max=(1 / m1, b2 / m1, ident.theta.max[2]))
    lo, hi = viscous_range(dataclasses.replace(ident, theta=box))
    assert (lo, hi) == (pytest.approx(b1, rel=1e-12), pytest.approx(b2, rel=1e-12))
    # the paper's box: B in [2.4 / 8.3, 17.5 / 50]; its corners use these ends, not theta2 * M_heavy
    lo, hi = viscous_range(ident)
    assert (lo, hi) == (pytest.approx(2.4 / 8.3), pytest.approx(17.5 / 50.0))
    corners = corner_scenarios(ident, default_spec())
    assert sorted({round(s.plant[P_B], 12) for s in corners}) == [pytest.approx(lo), pytest.approx(hi)]
    # a box that admits no common B at every mass falls back to the identified B
    tight = dataclasses.replace(ident.theta, min=(8.3, 9.0, -50.0), max=(50.0, 11.0, 50.0))
    assert viscous_range(dataclasses.replace(ident, theta=tight)) == (0.273, 0.273)


def test_mode_and_delay_come_from_the_identification_and_the_spec_overrides_them():
    """ident.json's frequency_response.model gives every scenario plant its mode and delay; [plant] wins."""
    ident = ref_ident(frequency_response={"model": {"mode_hz": 480.0, "mode_damping": 0.05, "mode_ratio": 0.3,
                                                    "mode_load_side": True, "delay_s": 2e-4}})
    spec = default_spec()
    sc = scenario_matrix(ident, spec, rng=np.random.default_rng(0), n_monte_carlo=4)
    for s in sc:
        if s.name.split("/")[-1] not in ("mode_low", "mode_high", "mode_damping_half"):
            assert s.plant[P_MODE_HZ] == 480.0 and s.plant[P_MODE_DAMPING] == 0.05
        assert s.plant[P_MODE_RATIO] == 0.3 and s.plant[P_MODE_LOAD_SIDE] == 1.0
        assert s.plant[P_DELAY] == pytest.approx(2e-4 + (spec.period if s.name.endswith("delay+1") else 0.0))
    by = {s.name: s for s in sc}
    # robustness variants of the mode: frequency x0.8 and x1.2, damping halved, on both trajectories
    for case in ("case1", "case2"):
        assert by[f"{case}/mode_low"].plant[P_MODE_HZ] == pytest.approx(384.0)
        assert by[f"{case}/mode_high"].plant[P_MODE_HZ] == pytest.approx(576.0)
        assert by[f"{case}/mode_damping_half"].plant[P_MODE_DAMPING] == pytest.approx(0.025)
    assert len(sc) == 12 + 2 * 4 + 4
    over = spec_from_mapping({"plant": {"mode_hz": 0.0, "delay_samples": 1.5}})
    p = identified_plant(ident, over)
    assert p[P_MODE_HZ] == 0.0 and p[P_DELAY] == pytest.approx(1.5 / 2500.0)
    assert [s.name for s in scenario_matrix(ident, over, rng=np.random.default_rng(0), n_monte_carlo=0)
            if "robustness" in s.tags] == ["case1/delay+1", "case2/delay+1"]


def test_encoder_noise_is_a_plant_option_drawn_the_same_for_a_scenario_name():
    """[plant] noise_std (or ident.json's encoder.noise_std) reaches every scenario; its draws depend on the name only."""
    ident = ref_ident(encoder={"quantization": 1e-6, "noise_std": 2e-7})
    a = scenario_matrix(ident, default_spec(), rng=np.random.default_rng(0), n_monte_carlo=2)
    assert {s.noise_std for s in a} == {2e-7}
    n1, n2 = a[0].noise(5000), a[1].noise(5000)
    assert np.array_equal(n1, scenario_matrix(ident, default_spec(), rng=np.random.default_rng(9),
                                              n_monte_carlo=0)[0].noise(5000))
    assert not np.array_equal(n1, n2) and np.std(n1) == pytest.approx(2e-7, rel=0.05)
    quiet = scenario_matrix(ident, spec_from_mapping({"plant": {"noise_std": 0.0}}), rng=np.random.default_rng(0),
                            n_monte_carlo=0)
    assert all(s.noise(100) is None for s in quiet)
