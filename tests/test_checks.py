"""Pre-fit data checks (commission.checks)."""

from __future__ import annotations

import math
import pathlib
import re
import tempfile

import h5py
import numpy as np
import pytest
from shared_paths import EMPS_DIR
from hypothesis import given, settings
from hypothesis import strategies as st

from commission.checks import check_log
from commission.identify.signals import encoder_grid
from commission.errors import DataError, UsageError
from commission.logs import ExcitationLog, load_log

EMPS = EMPS_DIR
EMPS_GAIN = 35.15065188248547
needs_emps = pytest.mark.skipif(not (EMPS / "DATA_EMPS.mat").exists(), reason="EMPS data not present")

FS = 1000.0
LSB = 1e-6  # encoder step of the synthetic logs [m]


def arrays(n: int = 2000, fs: float = FS, seed: int = 0) -> dict[str, np.ndarray]:
    """A plausible log: cosine move quantized to 1 um, noisy sine command."""
    rng = np.random.default_rng(seed)
    t = np.arange(n) / fs
    q_ref = 0.1 * (1 - np.cos(2 * np.pi * 0.5 * t))
    q = np.round(q_ref / LSB) * LSB
    u = np.sin(2 * np.pi * 0.5 * t) + 0.05 * rng.standard_normal(n)
    return {"t": t, "q": q, "u": u, "q_ref": q_ref}


def make(a: dict[str, np.ndarray], source: str = "log.h5") -> ExcitationLog:
    return ExcitationLog.from_arrays(a["t"], a["q"], a["u"], a.get("q_ref"), source=source)


# --------------------------------------------------------------------------- #
# Passing logs and their report
# --------------------------------------------------------------------------- #
def test_good_log_report():
    a = arrays()
    rep = check_log(make(a))
    assert rep.source == "log.h5"
    assert rep.n == 2000
    assert rep.sample_rate == pytest.approx(FS, rel=1e-12)
    assert rep.duration == pytest.approx(2.0, rel=1e-12)
    assert rep.dt_max_deviation < 1e-9 and rep.dt_relative_std < 1e-9  # arange/fs: rounding only
    assert rep.quantization_step == pytest.approx(LSB, rel=1e-9)
    # The smallest observed move may be several counts; it is a whole number of them.
    counts = rep.apparent_resolution / LSB
    assert counts >= 1 and counts == pytest.approx(round(counts), abs=1e-6)
    assert rep.q_range == (a["q"].min(), a["q"].max())
    assert rep.u_range == (a["u"].min(), a["u"].max())
    assert rep.u_rail_fraction == 0.0
    assert rep.warnings == ()


def test_missing_q_ref_is_a_warning_not_an_error():
    a = arrays()
    del a["q_ref"]
    rep = check_log(make(a))
    assert rep.warnings == ("q_ref absent: tracking error cannot be reported",)


@needs_emps
def test_emps_report_matches_readme():
    log = load_log(EMPS / "DATA_EMPS.mat", mapping={"q": "qm", "u": "vir", "q_ref": "qg"}, input_gain=EMPS_GAIN)
    rep = check_log(log)
    assert rep.n == 24841
    assert rep.sample_rate == pytest.approx(1000.0, rel=1e-4)
    assert rep.dt_max_deviation < 1e-4  # t is stored with ~1e-8 s rounding
    assert rep.quantization_step == pytest.approx(5e-8, rel=1e-9)  # README: encoder LSB 5e-8 m
    assert rep.apparent_resolution == pytest.approx(5e-8, rel=1e-6)
    assert (round(rep.u_range[0], 1), round(rep.u_range[1], 1)) == (-152.0, 145.5)  # README force range
    assert rep.warnings == ()


@needs_emps
def test_emps_pulses_is_not_on_a_grid():
    log = load_log(EMPS / "DATA_EMPS_PULSES.mat", mapping={"q": "qm", "u": "vir"}, input_gain=EMPS_GAIN)
    rep = check_log(log)
    assert rep.quantization_step is None  # README: qm not on the 5e-8 grid (resampled)
    assert rep.apparent_resolution < 5e-8
    assert (round(rep.u_range[0], 1), round(rep.u_range[1], 1)) == (-279.0, 317.6)
    assert any(w.startswith("q is not on a regular grid (smallest nonzero |dq| = 4.58e-09 m)") for w in rep.warnings)


# --------------------------------------------------------------------------- #
# Non-finite samples
# --------------------------------------------------------------------------- #
@pytest.mark.parametrize("channel, value, word", [
    ("q", math.nan, "NaN"), ("u", math.inf, "+inf"), ("t", -math.inf, "-inf"), ("q_ref", math.nan, "NaN"),
])
def test_non_finite_sample_is_named(channel, value, word):
    a = arrays()
    a[channel][1234] = value
    with pytest.raises(DataError, match=rf"^sample_x\.h5: channel {channel}: sample 1234 is {re.escape(word)}$"):
        check_log(make(a, "sample_x.h5"))
    a[channel][1500] = value
    with pytest.raises(DataError, match=rf"sample 1234 is {re.escape(word)} \(2 non-finite samples in all\)$"):
        check_log(make(a, "sample_x.h5"))


@settings(max_examples=40, deadline=None)
@given(
    data=st.data(),
    n=st.integers(2, 3000),
    channel=st.sampled_from(["t", "q", "u", "q_ref"]),
    value=st.sampled_from([math.nan, math.inf, -math.inf]),
)
def test_injected_non_finite_is_reported_at_its_index(data, n, channel, value):
    k = data.draw(st.integers(0, n - 1), label="k")
    later = data.draw(st.lists(st.integers(k, n - 1), max_size=3), label="later")
    a = arrays(n)
    a[channel][[k, *later]] = value
    # Through a file, so the loader must carry the bad value to the check unchanged.
    with tempfile.TemporaryDirectory() as d:
        path = pathlib.Path(d) / "inj.h5"
        with h5py.File(path, "w") as f:
            for name, arr in a.items():
                f[name] = arr
        log = load_log(path)
    with pytest.raises(DataError) as info:
        check_log(log)
    word = "NaN" if math.isnan(value) else ("+inf" if value > 0 else "-inf")
    assert str(info.value).startswith(f"{path}: channel {channel}: sample {k} is {word}")


# --------------------------------------------------------------------------- #
# Time base
# --------------------------------------------------------------------------- #
def test_repeated_time_stamp():
    a = arrays()
    a["t"][17] = a["t"][16]
    with pytest.raises(DataError, match=r"^log\.h5: channel t: not strictly increasing at index 17 "
                                        r"\(t\[17\]=0\.016 <= t\[16\]=0\.016\)$"):
        check_log(make(a))


@settings(max_examples=40, deadline=None)
@given(data=st.data(), n=st.integers(3, 3000), back=st.floats(0.0, 5.0))
def test_non_increasing_perturbation_is_reported_at_its_index(data, n, back):
    k = data.draw(st.integers(1, n - 1), label="k")
    a = arrays(n)
    a["t"][k] = a["t"][k - 1] - back / FS  # at or before the previous sample
    with pytest.raises(DataError) as info:
        check_log(make(a))
    msg = str(info.value)
    assert msg.startswith(f"log.h5: channel t: not strictly increasing at index {k} ")
    assert f"(t[{k}]={float(a['t'][k])!r} <= t[{k - 1}]={float(a['t'][k - 1])!r})" in msg


def test_overflowing_time_step():
    a = arrays(600)
    a["t"][300:] = np.linspace(1e308, 1.5e308, 300)
    a["t"][:300] = np.linspace(-1.5e308, -1e308, 300)
    with pytest.raises(DataError, match=r"^log\.h5: channel t: step t\[300\]-t\[299\] overflows \(t\[300\]=1e\+308\)$"):
        check_log(make(a))


def test_dropped_sample_breaks_uniformity():
    a = arrays()
    a = {name: np.delete(arr, 700) for name, arr in a.items()}
    with pytest.raises(DataError, match=r"^log\.h5: channel t: non-uniform sampling at index 700: "
                                        r"t\[700\]-t\[699\] = 0\.002 s is 100 % off the median step 0\.001 s "
                                        r"\(tolerance 1 %; max deviation 100 %, relative std"):
        check_log(make(a))


def test_small_jitter_passes_and_is_reported():
    # 2000 steps alternating 1 ms * (1 +- 0.4 %): median 1 ms, max deviation 0.4 %, std 0.4 %.
    n = 2001
    dt = 1e-3 * (1 + 0.004 * (-1.0) ** np.arange(n - 1))
    a = arrays(n)
    a["t"] = np.concatenate(([0.0], np.cumsum(dt)))
    rep = check_log(make(a))
    assert rep.dt_max_deviation == pytest.approx(0.004, rel=1e-6)
    assert rep.dt_relative_std == pytest.approx(0.004, rel=1e-3)
    assert rep.sample_rate == pytest.approx(1000.0, rel=1e-9)
    # The last quarter of the steps 2 % slow: the median becomes 1.004 ms, so they
    # are (1.020 - 1.004) / 1.004 = 1.59 % off it, first at sample 1501.
    dt[1500:] = 1.02e-3
    a["t"] = np.concatenate(([0.0], np.cumsum(dt)))
    with pytest.raises(DataError, match=r"non-uniform sampling at index 1501: .* is 1\.59 % off the median step 0\.001004 s"):
        check_log(make(a))
    check_log(make(a), dt_tolerance=0.02)  # a looser tolerance accepts it


# --------------------------------------------------------------------------- #
# Length, motion, excitation
# --------------------------------------------------------------------------- #
@pytest.mark.parametrize("n, fs, msg", [
    (499, 1000.0, r"499 samples over 0\.499 s"),
    (900, 1000.0, r"900 samples over 0\.9 s"),
    (1, 1000.0, r"1 samples over 0 s"),
])
def test_too_short(n, fs, msg):
    with pytest.raises(DataError, match=rf"^log\.h5: log too short: {msg}; identification needs at least "
                                        r"500 samples and 1 s"):
        check_log(make(arrays(n, fs)))


def test_length_limits_are_parameters():
    check_log(make(arrays(500, 400.0)))  # 500 samples over 1.25 s: enough
    check_log(make(arrays(200)), min_samples=100, min_duration=0.1)
    with pytest.raises(DataError, match=r"at least 3000 samples and 5 s"):
        check_log(make(arrays(2000)), min_samples=3000, min_duration=5.0)


def test_constant_position_and_command():
    a = arrays()
    a["q"][:] = 0.25
    with pytest.raises(DataError, match=r"^log\.h5: channel q: constant \(all 2000 samples = 0\.25 m\); the axis never moved$"):
        check_log(make(a))
    a = arrays()
    a["u"][:] = 0.5
    with pytest.raises(DataError, match=r"^log\.h5: channel u: constant command \(all 2000 samples = 0\.5\); "
                                        r"nothing excites the axis$"):
        check_log(make(a))


def test_saturated_command_names_rails_and_first_index():
    # A 1 Hz sine of amplitude 1.3 clipped at +-1: closed-form fraction at the rails
    # 1 - (2/pi) asin(1/1.3) = 44 %, first clipped sample at t = asin(1/1.3) / (2 pi).
    a = arrays(4000)
    u = np.clip(1.3 * np.sin(2 * np.pi * 1.0 * a["t"]), -1.0, 1.0)
    a["u"] = u
    first = math.ceil(math.asin(1 / 1.3) / (2 * math.pi) * FS)
    fraction = 1 - 2 / math.pi * math.asin(1 / 1.3)
    with pytest.raises(DataError) as info:
        check_log(make(a))
    msg = str(info.value)
    assert msg.startswith("log.h5: channel u: saturated: ")
    assert f"max u = 1.0: " in msg and f"samples from index {first};" in msg and "min u = -1.0: " in msg
    pct = float(re.search(r"\(([\d.]+) %\) sit at the rails", msg).group(1))
    assert pct == pytest.approx(100 * fraction, abs=0.2)
    assert msg.endswith("limit 5 %")


def test_near_saturation_is_a_warning_and_short_repeats_do_not_count():
    a = arrays()
    top = a["u"].max() + 0.1
    a["u"][1000:1040] = top  # one flat top: 2 % of 2000 samples
    rep = check_log(make(a))
    assert rep.u_rail_fraction == pytest.approx(0.02)
    assert any(w.startswith("u near saturation: 2 % of samples at the rails (max u = ") for w in rep.warnings)
    a = arrays()
    a["u"][100:102] = a["u"].max() + 0.1  # a run of 2 < saturation_min_run
    assert check_log(make(a)).u_rail_fraction == 0.0
    assert check_log(make(a), saturation_min_run=2).u_rail_fraction == pytest.approx(0.001)


def test_designed_square_wave_is_not_saturation():
    a = arrays()
    a["u"] = np.where(np.sin(2 * np.pi * 2.0 * a["t"]) >= 0, 1.0, -1.0)
    rep = check_log(make(a))
    assert rep.u_rail_fraction == 0.0
    assert any("u takes only 2 distinct values" in w for w in rep.warnings)


def test_threshold_arguments_are_validated():
    log = make(arrays())
    with pytest.raises(UsageError, match=r"min_samples: expected at least 2, got 1"):
        check_log(log, min_samples=1)
    with pytest.raises(UsageError, match=r"check thresholds"):
        check_log(log, saturation_fraction=1.5)


# --------------------------------------------------------------------------- #
# Encoder resolution
# --------------------------------------------------------------------------- #
def test_resolution_finds_a_step_that_never_occurs_alone():
    # Moves only by 2 or 3 counts: the smallest |dq| is 2 LSB, the grid is 1 LSB.
    rng = np.random.default_rng(3)
    counts = np.cumsum(rng.choice([2, 3, -2, -3, 0], size=1000))
    q = 0.123456 + counts * 2.5e-7
    step, apparent = encoder_grid(q)
    assert step == pytest.approx(2.5e-7, rel=1e-9)
    assert apparent == pytest.approx(5e-7, rel=1e-9)


def test_resolution_of_continuous_and_constant_data():
    rng = np.random.default_rng(4)
    q = np.cumsum(rng.standard_normal(1000)) * 1e-6
    step, apparent = encoder_grid(q)
    assert step is None and apparent == np.abs(np.diff(q)).min()
    step, apparent = encoder_grid(np.full(10, 0.1))
    assert step is None and math.isnan(apparent)
    # Steps at floating-point resolution are rounding noise, not an encoder.
    q = 0.1 + np.array([0, 1, 0, 2, 1]) * np.spacing(0.1)
    assert encoder_grid(q)[0] is None


def test_resolution_survives_unit_conversion():
    counts = np.round(50 * np.sin(np.linspace(0, 6, 3000)) * 1e3)  # +-50 mm in 1 um counts
    q = (counts * 1e-3) / 1e3  # written in mm, loaded as metres
    step, _ = encoder_grid(q)
    assert step == pytest.approx(1e-6, rel=1e-9)
