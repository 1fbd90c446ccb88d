"""Which logs are a friction test, and Stribeck dips on friction tests (issue 32, item 4).

Known truth: simulated legs and runs with the curve and the speeds set here.  Real data: the
TRO2021 screw drives (../shared/data/screwdrive-tro2021, Mablekos-Alexiou, da Cruz, Bergeles,
IEEE T-RO 37(4), 2021), whose README tabulates the odd part of drive 3's map, and the ODrive
slow runs (../shared/data/odrive-cogging), whose README gives their speed percentiles.
"""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
from shared_paths import ODRIVE_DIR, TRO2021_DIR

from commission.errors import CommissionError, IdentifiabilityError
from commission.identification import classify_logs, expand_log_paths, identify_files, identify_legs, leg_refusal
from commission.identify.errors import StribeckNotIdentifiableError
from commission.identify.fit import fit_friction_map
from commission.identify.friction import stribeck_friction
from commission.logs import ExcitationLog, load_log

RATE = 1000.0
STEP = 1e-6  # encoder step, m


def _run(q: np.ndarray, name: str, u: np.ndarray | None = None) -> ExcitationLog:
    t = np.arange(q.size) / RATE
    return ExcitationLog.from_arrays(t, np.round(q / STEP) * STEP, np.zeros(q.size) if u is None else u,
                                     source=name)


def _steady(v: float, seconds: float = 3.0, name: str = "leg.csv") -> ExcitationLog:
    t = np.arange(int(seconds * RATE)) / RATE
    return _run(0.01 + v * t, name)


# --------------------------------------------------------------------------- what a leg is

def test_a_constant_speed_run_is_a_leg_and_a_stalled_one_with_jitter_too():
    assert leg_refusal(_steady(0.01)) is None and leg_refusal(_steady(-0.2)) is None
    jitter = 0.2 + STEP * (np.arange(3000) % 2)  # one encoder count back and forth, never going anywhere
    assert leg_refusal(_run(jitter, "stalled.csv")) is None


def test_a_one_direction_run_whose_speed_varies_on_each_cog_is_not_a_leg():
    # An ODrive-like run: the speed swings +-60 % about 0.01 m/s once per 2 mm "cog" (15 cogs in
    # 3.75 s), which the coarse 5 % window (187 samples, about 1.6 mm) averages out.
    x = np.linspace(0.0, 0.03, 30000)
    speed = 0.01 * (1.0 + 0.6 * np.sin(2 * np.pi * x / 0.002))
    t = np.concatenate([[0.0], np.cumsum(np.diff(x) / speed[1:])])
    q = np.interp(np.arange(0.0, t[-1], 1 / RATE), t, x)
    why = leg_refusal(_run(q, "cogging.csv"))
    assert why is not None and why.startswith("its speed varies along the way"), why


def test_runs_that_reverse_or_come_back_are_not_legs():
    t = np.arange(3001) / RATE
    out_and_back = 0.01 * np.minimum(t, 3.0 - t)  # 1.5 s forward, 1.5 s back: mean speed 0 after moving
    assert "mean speed 0" in leg_refusal(_run(out_and_back, "back.csv"))
    return_then_leg = np.where(t < 0.3, 0.05 - 0.2 * t, -0.01 + 0.01 * (t - 0.3))  # a fast return move first
    assert leg_refusal(_run(return_then_leg, "return.csv")).startswith("it reverses")


def test_runs_all_one_way_are_segments_not_a_friction_test_and_a_ripple_pitch_is_not_refused_for_it(
        tmp_path):
    logs = [_steady(v, name=f"run{i}.csv") for i, v in enumerate((0.01, 0.012, 0.015))]
    kind, note = classify_logs(logs)
    assert kind == "segments" and "all forward, not a friction test" in note
    both = logs + [_steady(-v, name=f"n{i}.csv") for i, v in enumerate((0.01, 0.012, 0.015))]
    assert classify_logs(both)[0] == "legs"
    # Through the command's path: the files are fitted as segments, so a ripple pitch is not the
    # friction test's refusal; the segments' own fit then names what a one-way set cannot give.
    paths = []
    for lg in logs:
        path = tmp_path / lg.source
        np.savetxt(path, np.column_stack([lg.t, lg.q, 0.1 + 0.03 * np.sin(2 * np.pi * lg.q / 0.002)]),
                   delimiter=",", header="t,q,u", comments="")
        paths.append(str(path))
    with pytest.raises(CommissionError) as exc:
        identify_files(paths, ripple_pitch=0.002)
    assert "friction test" not in str(exc.value) and "reversals" in str(exc.value), exc.value


def test_a_mixed_set_is_fitted_as_segments_and_the_note_says_which_file_is_which():
    t = np.arange(3000) / RATE
    sweep = _run(0.01 * np.sin(2 * np.pi * 2 * t), "sweep.csv")
    kind, note = classify_logs([_steady(0.01, name="a.csv"), sweep, _steady(-0.01, name="b.csv")])
    assert kind == "segments"
    assert "not constant-speed legs: sweep.csv (sweep.csv: it reverses" in note
    assert note.endswith("; constant-speed legs: a.csv, b.csv")


@pytest.mark.skipif(not (ODRIVE_DIR / "slow_0.03revps").is_dir(), reason="ODrive data not present")
def test_the_odrive_slow_runs_are_not_a_friction_test():
    # README: all one way at 0.03 rev/s, the uncompensated runs nearly stalling on each cog, the
    # crosstalk runs swinging both ways (p10 -0.29, p90 0.33 rev/s): segments of one axis.
    logs = [load_log(p, mapping={"t": "0", "q": "1", "u": "2"}, q_unit="rad")
            for p in expand_log_paths([str(ODRIVE_DIR / "slow_0.03revps")])]
    kind, note = classify_logs(logs)
    assert kind == "segments" and "nocomp_0.npy" in note and "crosstalk_nocomp_0.npy" in note
    assert leg_refusal(logs[-1]).startswith("its speed varies along the way")  # nocomp_0: p10 -0.001 rev/s


@pytest.mark.skipif(not (ODRIVE_DIR / "slow_0.10revps").is_dir(), reason="ODrive data not present")
def test_a_folder_of_converted_odrive_runs_gets_its_ripple_not_the_friction_test_refusal(tmp_path):
    # The case: slow one-way runs converted as the README says (t > 0.5 s, q = counts * 2 pi / 8192
    # rad, u = Iq in A), given as a folder with --ripple-pitch: fitted as segments of one axis.
    h5py = pytest.importorskip("h5py")
    from typer.testing import CliRunner

    from commission.cli.main import app

    qs, us = [], []
    for k in range(3):
        t, counts, iq = np.load(ODRIVE_DIR / "slow_0.10revps" / f"nocomp_{k}.npy")
        keep = t > 0.5
        q = counts[keep] * 2 * math.pi / 8192
        with h5py.File(tmp_path / f"nocomp_{k}.h5", "w") as f:
            f["t"], f["q"], f["u"] = t[keep] - t[keep][0], q, iq[keep]
            f.attrs["q_unit"], f.attrs["u_unit"] = "rad", "A"
        qs.append(q)
        us.append(iq[keep])
    out = tmp_path / "out" / "i.json"
    res = CliRunner().invoke(app, ["identify", str(tmp_path), "--resample", "400", "--ripple-pitch",
                                   repr(2 * math.pi / 7), "--out", str(out)])
    assert res.exit_code == 0, res.output
    doc = json.loads(out.read_text())
    assert doc["warnings"][0].startswith("the 3 logs are fitted together as segments of one axis; not constant-speed "
                                         "legs: nocomp_0.h5, nocomp_1.h5, nocomp_2.h5")
    # The 7th harmonic against a static least-squares fit of the same samples, written here: the tool's model
    # also has B qd, and on these runs the speed itself ripples on each cog (README), hence 10 %.
    q, iq = np.concatenate(qs), np.concatenate(us)
    X = np.column_stack([np.ones_like(q), np.sin(7 * q), np.cos(7 * q)])
    c = np.linalg.lstsq(X, iq, rcond=None)[0]
    assert doc["model"]["ripple_amp"]["value"] == pytest.approx(math.hypot(c[1], c[2]), rel=0.1)


# --------------------------------------------------------------------------- Stribeck dips

SPEEDS = (0.004, 0.008, 0.015, 0.03, 0.05, 0.1, 0.2, 0.3, 0.5)  # m/s, each run both ways


def _map(dip: bool, seed: int = 3):
    """Legs in pairs, with a direction-dependent part that rises at the slowest legs (as drive 3's does)."""
    v = np.array([s * d for s in SPEEDS for d in (1.0, -1.0)])
    odd = 0.27 * v + (stribeck_friction(v, 0.10, 0.13, 0.01, 1.0) if dip else 0.10 * np.sign(v))
    even = 0.02 + 0.03 * np.exp(-np.abs(v) / 0.01)
    rng = np.random.default_rng(seed)
    return v, odd + even + 0.002 * rng.standard_normal(v.size), odd


def test_a_dip_with_a_rising_even_part_is_fitted_and_the_curve_follows_the_odd_part():
    v, F, odd = _map(dip=True)
    mf = fit_friction_map(v, F, friction="stribeck")
    p = {k: val for k, (val, _) in mf.parameters.items()}
    curve = p["B"] * v + stribeck_friction(v, p["fc"], p["fs"], p["vs"], p["xi"])
    assert np.max(np.abs(curve - odd)) < 3 * 0.002  # within three noise levels of the true odd part
    assert p["fc"] == pytest.approx(0.10, abs=0.005) and p["fs"] > p["fc"] + 0.01
    # the offset is the mean of the even parts, its std their spread over sqrt(pairs)
    even = 0.02 + 0.03 * np.exp(-np.array(SPEEDS) / 0.01)
    assert p["offset"] == pytest.approx(even.mean(), abs=0.002)
    assert mf.parameters["offset"][1] == pytest.approx(np.std(even, ddof=1) / 3, rel=0.2)


def test_a_map_without_a_dip_is_refused_with_the_f_test_figures():
    v, F, _ = _map(dip=False)
    with pytest.raises(StribeckNotIdentifiableError, match=r"no Stribeck dip shows .*F = [\d.e+-]+, p = [\d.e+-]+"):
        fit_friction_map(v, F, friction="stribeck", speed_unit="rad/s")


tro = pytest.mark.skipif(not TRO2021_DIR.is_dir(), reason="TRO2021 data not present")


def _drive(n: int) -> list[str]:
    return expand_log_paths([str(TRO2021_DIR / f"driveNo{n}" / "steady_state" / "0.096kg")])


@tro
def test_drive_3s_dip_is_fitted_and_its_curve_matches_the_readme_odd_part():
    out = identify_legs(_drive(3))
    assert out.fit.friction == "stribeck"
    p = {k: val for k, (val, _) in out.fit.parameters.items()}
    rpm = math.pi / 30  # rad/s
    # README, drive 3's odd part of the map: 15.30 % at 1 rpm, 13.90 % at 8 rpm.
    for speed, ref in ((1.0, 15.30), (8.0, 13.90)):
        w = speed * rpm
        value = p["B"] * w + float(stribeck_friction(np.array([w]), p["fc"], p["fs"], p["vs"], p["xi"])[0])
        assert value == pytest.approx(ref, rel=0.02), (speed, value)
    warnings = " ".join(out.ident.extra["warnings"])
    assert "extrapolated below the slowest legs" in warnings and "rad/s" in warnings


@tro
def test_a_refused_dip_names_the_folder_and_the_slowest_legs_not_the_first_file():
    fast = [f for f in _drive(3) if int(f.rsplit("/", 1)[1].lstrip("n")[:-4]) >= 10]
    with pytest.raises(IdentifiabilityError) as exc:
        identify_legs(fast, friction="stribeck")
    text = str(exc.value)
    folder = str(TRO2021_DIR / "driveNo3" / "steady_state" / "0.096kg")
    assert text.startswith(f"{folder} ({len(fast)} logs): ") and "\n" not in text
    assert "slowest legs: forward n10.csv at 1.05 rad/s" in text and "backward 10.csv at -1.05 rad/s" in text
    out = identify_legs(_drive(2))  # no dip (README): Coulomb, the warning names the same way
    assert out.fit.friction == "coulomb"
    assert any("no Stribeck dip shows" in w and "slowest legs: forward n10.csv" in w
               for w in out.ident.extra["warnings"])


def test_a_stribeck_curve_the_speeds_never_reach_is_unidentifiable_without_a_numpy_warning():
    """Every speed 50-100 x the top of the vs box (Coulomb friction only, known truth): the Stribeck
    column vanishes at the optimum, the covariance is inf/nan (no spread can be told), and the fit
    says so through its std alone, with no RuntimeWarning on the user's console."""
    import warnings

    from commission.identify.friction import fit_separable, stribeck_shape_derivatives
    rng = np.random.default_rng(1)  # a draw whose optimum lands where the covariance overflows
    v = np.concatenate([rng.uniform(0.5, 1.0, 200), -rng.uniform(0.5, 1.0, 200)])
    y = 0.3 * np.sign(v) + 0.01 * rng.standard_normal(v.size)
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # any numpy RuntimeWarning fails the test
        fit = fit_separable(np.column_stack([np.sign(v), v]), ("fc", "B"),
                            lambda vs, xi: stribeck_shape_derivatives(v, vs, xi)[0],
                            lambda vs, xi: stribeck_shape_derivatives(v, vs, xi)[1:], y, vs_bounds=(0.001, 0.01))
    assert not np.all(np.isfinite(fit.std))  # no spread can be told for the curve's parameters
    assert math.isclose(fit.value[fit.names.index("fc")], 0.3, abs_tol=0.01)
