"""Cogging from a slow run: the ODrive data (../shared/data/odrive-cogging, Gerry Chen's ODrive fork,
github.com/gchenfc/ODrive at 54611550, analysis/cogging_torque), a rotary motor logged by host polling.

The run `slow_0.03revps/nocomp_0` turns one revolution at 0.03 rev/s; its current carries the
motor's cogging, whose largest component is the 7th harmonic per revolution (the README's spectrum
of the quasi-static map: 0.87 A).  The log has irregular time stamps (``--resample``) and no usable
acceleration (M is not identified, the rest is).  The reference is a direct static least-squares fit
of the same samples, written here independently of the tool.
"""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
from shared_paths import ODRIVE_DIR
from typer.testing import CliRunner

from commission.cli.main import app

h5py = pytest.importorskip("h5py")
RUN = ODRIVE_DIR / "slow_0.03revps" / "nocomp_0.npy"
pytestmark = pytest.mark.skipif(not RUN.is_file(), reason="ODrive data not present")
runner = CliRunner()
PITCH_7 = 2 * math.pi / 7  # rad: the 7th harmonic per revolution


def _samples():
    t, counts, iq = np.load(RUN)
    keep = t > 0.5  # README: the first 0.5 s is not part of the test
    return t[keep] - t[keep][0], counts[keep] * 2 * math.pi / 8192, iq[keep]


@pytest.fixture(scope="module")
def log_h5(tmp_path_factory):
    t, q, iq = _samples()
    path = tmp_path_factory.mktemp("odrive") / "nocomp_0.h5"
    with h5py.File(path, "w") as f:
        f["t"], f["q"], f["u"] = t, q, iq
        f.attrs["q_unit"], f.attrs["u_unit"] = "rad", "A"
    return path


def _static_fit(harmonics, which=0):
    """Amplitude (A) and phase (rad) of harmonic ``harmonics[which]`` in iq = c + sum_k a_k sin(k q) + b_k cos(k q)."""
    _, q, iq = _samples()
    X = np.column_stack([np.ones_like(q)] + [f(k * q) for k in harmonics for f in (np.sin, np.cos)])
    c, *_ = np.linalg.lstsq(X, iq, rcond=None)
    a, b = c[1 + 2 * which], c[2 + 2 * which]
    return math.hypot(a, b), math.atan2(b, a)


def test_irregular_time_stamps_are_refused_naming_resample(log_h5, tmp_path):
    res = runner.invoke(app, ["identify", str(log_h5), "--out", str(tmp_path / "i.json")])
    assert res.exit_code == 2
    assert "non-uniform sampling" in res.output and "--resample HZ" in " ".join(res.output.split())
    assert not (tmp_path / "i.json").exists()


def test_the_7th_cogging_harmonic_matches_a_static_fit_of_the_same_data(log_h5, tmp_path):
    out = tmp_path / "i.json"
    res = runner.invoke(app, ["identify", str(log_h5), "--resample", "400", "--ripple-pitch", repr(PITCH_7),
                              "--out", str(out)])
    assert res.exit_code == 0, res.output
    doc = json.loads(out.read_text())
    amp, phase = doc["model"]["ripple_amp"]["value"], doc["model"]["ripple_phase"]["value"]
    for harmonics in ([7], [7, 14, 28]):
        ref_amp, ref_phase = _static_fit(harmonics)
        assert amp == pytest.approx(ref_amp, rel=0.05), harmonics
        assert abs(phase - ref_phase) < 0.05, harmonics
    assert amp == pytest.approx(0.868, rel=0.05)  # the figure the issue quotes for a static fit
    # rotary units, and the mass (inertia) reported as not identified rather than passed on
    assert doc["units"] == {"q": "rad", "u": "A"} and doc["source"]["resampled_hz"] == 400.0
    assert doc["parameters"]["M"] is None and "acceleration" in doc["not_identified"]["M"]
    assert doc["theta"] is None and "frequency_response" not in doc
    # the one-direction run leaves fc and the offset collinear, and half the current unexplained: flagged, with figures
    warnings = " ".join(doc["warnings"])
    assert "fit: relative error 0.55" in warnings and "fc = " in warnings and "not determined by this log" in warnings


def test_a_fixed_inertia_is_kept_and_gives_theta(log_h5, tmp_path):
    out = tmp_path / "i.json"
    res = runner.invoke(app, ["identify", str(log_h5), "--resample", "400", "--ripple-pitch", repr(PITCH_7),
                              "--fix", "M=0.002", "--out", str(out)])
    assert res.exit_code == 0, res.output
    doc = json.loads(out.read_text())
    assert doc["parameters"]["M"] == {"value": 0.002, "std": 0.0} and doc["not_identified"] == {}
    assert doc["theta"]["nominal"][0] == pytest.approx(500.0)
    assert doc["model"]["ripple_amp"]["value"] == pytest.approx(0.868, rel=0.05)


def test_several_harmonics_of_one_period_each_match_the_static_fit(log_h5, tmp_path):
    out = tmp_path / "i.json"
    harmonics = (7, 14, 28)
    pitches = [repr(2 * math.pi / k) for k in harmonics]
    res = runner.invoke(app, ["identify", str(log_h5), "--resample", "400", "--out", str(out),
                              *[a for p in pitches for a in ("--ripple-pitch", p)]])
    assert res.exit_code == 0, res.output
    found = json.loads(out.read_text())["model"]["ripple_harmonics"]
    assert [h["pitch"] for h in found] == pytest.approx([2 * math.pi / k for k in harmonics])
    # The 28th harmonic is where the speed itself ripples most (the motor nearly stalls on each cog):
    # the tool's model has a B qd term, which takes part of it, and the static fit has none. Adding a
    # velocity column to the static fit moves its 28th from 0.476 A to 0.435 A (the tool: 0.430 A), and
    # leaves the 7th and 14th within 1 %: those are held to 5 % and 0.05 rad, the 28th to 15 % and 0.1 rad.
    tolerance = {7: (0.05, 0.05), 14: (0.05, 0.05), 28: (0.15, 0.1)}
    for i, h in enumerate(found):
        ref_amp, ref_phase = _static_fit(harmonics, i)
        rel, rad = tolerance[harmonics[i]]
        assert h["amp"]["value"] == pytest.approx(ref_amp, rel=rel), harmonics[i]
        assert abs(math.remainder(h["phase"]["value"] - ref_phase, 2 * math.pi)) < rad, harmonics[i]


def test_run_takes_identify_s_options_and_stops_at_tune_naming_the_missing_inertia(log_h5, tmp_path):
    out = tmp_path / "run"
    res = runner.invoke(app, ["run", str(log_h5), "--resample", "400", "--ripple-pitch", repr(PITCH_7),
                              "--out-dir", str(out)])
    assert res.exit_code == 2
    assert "$.parameters.M: not identified" in res.output
    assert not out.exists() or not any(out.iterdir())  # nothing half-written
