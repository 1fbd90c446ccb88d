"""``commission.identify.ripple``: the force-ripple pitch found on constant-velocity legs (known-truth legs)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from commission.identify.ripple import LEAST_EXPLAINED, PEAK_OVER_MEDIAN, ripple_periodogram


def legs_of(rng, *, pitch, amp, noise, offsets=(0.3, -0.28, 0.35, -0.33, 0.31, -0.29), step=1e-6,
            phase=0.7, extent=(0.01, 0.02, 0.05, 0.1, 0.15, 0.2), drift=0.0):
    """Legs back and forth over the travel: each leg its own friction level (``offsets``), the ripple
    ``amp sin(2 pi q / pitch + phase)``, white noise, positions on the encoder grid ``step``."""
    legs = []
    for k, (c, ext) in enumerate(zip(offsets, extent)):
        q0 = 0.02 + 0.01 * k
        q = q0 + np.linspace(0.0, ext, 4000)[:: (1 if k % 2 == 0 else -1)]
        q = np.round(q / step) * step
        u = c + amp * np.sin(2 * math.pi * q / pitch + phase) + noise * rng.standard_normal(q.size)
        u += drift * np.linspace(-1.0, 1.0, q.size)  # a transient along the leg (time, not position)
        legs.append((q, u))
    return legs


@pytest.mark.parametrize("pitch", [0.004, 0.03, 0.061])
def test_the_pitch_and_amplitude_are_found_under_the_legs_friction_levels(pitch):
    rng = np.random.default_rng(1)
    r = ripple_periodogram(legs_of(rng, pitch=pitch, amp=0.01, noise=0.01), step=1e-6)
    assert r.pitch == pytest.approx(pitch, rel=0.005)
    assert r.amplitude == pytest.approx(0.01, rel=0.05)
    assert r.peak_over_median >= PEAK_OVER_MEDIAN and r.explained >= LEAST_EXPLAINED
    assert r.n_legs == 6 and r.searched[0] < pitch < r.searched[1]
    assert "found on 6 constant-velocity legs" in r.describe("m")


def test_no_ripple_no_pitch():
    """Friction levels, noise and a slow transient along each leg are not a ripple."""
    rng = np.random.default_rng(2)
    for drift in (0.0, 0.005):
        r = ripple_periodogram(legs_of(rng, pitch=0.03, amp=0.0, noise=0.01, drift=drift), step=1e-6)
        assert r.pitch is None, r
        assert "no pitch stands out" in r.describe("m") and "no ripple fitted" in r.describe("m")


def test_a_ripple_too_small_to_matter_is_left_out():
    """A ripple that stands out of white noise but explains less than LEAST_EXPLAINED of the command's
    variation is not worth a model term."""
    rng = np.random.default_rng(3)
    r = ripple_periodogram(legs_of(rng, pitch=0.03, amp=0.0025, noise=0.01), step=1e-6)
    assert r.peak_over_median >= PEAK_OVER_MEDIAN and r.explained < LEAST_EXPLAINED
    assert r.pitch is None


def test_no_legs_says_so():
    r = ripple_periodogram([], step=1e-6)
    assert r.pitch is None and r.n_legs == 0
    assert "no constant-velocity legs" in r.describe("m")
    assert r.record()["searched"] == [None, None]


@pytest.mark.parametrize("pitch", [0.0023, 0.0061, 0.047])
def test_a_noise_free_ripple_is_explained_whole(pitch):
    """Closed form: on legs holding only their friction levels and the ripple, the ripple of the
    found pitch explains the whole variation about each leg's mean, but for the position bins'
    averaging: a bin of an eighth of the least pitch searched keeps ``sinc(width / pitch)`` of the
    amplitude (numpy's normalised sinc), its square of the power.  The coarse scan reaches these
    pitches after hundreds to thousands of candidates whose sines are carried from one candidate to
    the next: a carry that drifts puts the peak on the wrong candidate, and the pitch and these
    figures (from the exact refinement around it) miss."""
    rng = np.random.default_rng(4)
    r = ripple_periodogram(legs_of(rng, pitch=pitch, amp=0.01, noise=0.0), step=1e-6)
    kept = float(np.sinc(r.searched[0] / 8.0 / pitch))
    assert r.pitch == pytest.approx(pitch, rel=2e-3)
    assert r.explained == pytest.approx(kept ** 2, abs=3e-4)
    assert r.amplitude == pytest.approx(0.01 * kept, rel=3e-4)
