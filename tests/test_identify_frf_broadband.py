"""Broadband detection (:func:`commission.identify.frf.broadband_segments`) against known segments.

The positive cases are synthetic commands whose injection is placed by construction; the negative
case is a real log without any injection (a TRO2021 start-stop run at 24 Hz, whose 8-sample blocks
scatter to twice their median by chance).
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy import signal

from commission.identify.frf import BLOCK_S, broadband_segments


def _command(fs: float, ratio: float, seed: int = 0, duration: float = 10.0) -> tuple[np.ndarray, tuple[float, float]]:
    """A holding loop's noise-driven command (white) with an injection from 4 s to 7 s whose high-passed RMS
    is ``ratio`` times the background's; a slow ramp stands for the motion."""
    rng = np.random.default_rng(seed)
    n = int(duration * fs)
    t = np.arange(n) / fs
    u = rng.standard_normal(n) + 5.0 * np.sin(2 * np.pi * 0.5 * t)
    sos = signal.butter(4, fs / 10.0, "highpass", fs=fs, output="sos")
    bg = np.sqrt(np.mean(signal.sosfiltfilt(sos, rng.standard_normal(n)) ** 2))
    inj = rng.standard_normal(n)
    hp_inj = np.sqrt(np.mean(signal.sosfiltfilt(sos, inj) ** 2))
    on = (t >= 4.0) & (t < 7.0)
    # The high-passed RMS of background + injection is ratio x the background's.
    u[on] += inj[on] * bg * np.sqrt(ratio ** 2 - 1.0) / hp_inj
    return u, (4.0, 7.0)


@pytest.mark.parametrize("fs", [2_000.0, 20_000.0])
def test_an_injection_2_4_times_the_background_is_found_on_long_blocks(fs):
    u, (a, b) = _command(fs, 2.4)
    segs = broadband_segments(u, fs)
    assert len(segs) == 1
    i0, i1 = segs[0]
    # The edge blocks are left out: the segment lies inside the injection, within two blocks of its ends.
    assert a * fs <= i0 <= (a + 2 * BLOCK_S) * fs and (b - 2 * BLOCK_S) * fs <= i1 <= b * fs


def test_a_background_step_of_1_5_is_no_injection():
    u, _ = _command(20_000.0, 1.5)
    assert broadband_segments(u, 20_000.0) == []


def test_short_blocks_keep_the_stricter_factor():
    """At 1 kHz (100-sample blocks) an injection 2.4 x the background is not enough; 4 x is."""
    assert broadband_segments(_command(1_000.0, 2.4)[0], 1_000.0) == []
    assert len(broadband_segments(_command(1_000.0, 4.0)[0], 1_000.0)) == 1


def test_a_real_log_without_injection_has_no_segment():
    from shared_paths import TRO2021_DIR
    from commission.logs import load_log

    log = load_log(TRO2021_DIR / "driveNo3" / "start_stop" / "10.csv")
    fs = 1.0 / float(np.median(np.diff(log.t)))
    assert broadband_segments(np.asarray(log.u), fs) == []
