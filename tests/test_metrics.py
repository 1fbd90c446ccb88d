"""Section-4.2 indexes on signals whose indexes are known in closed form."""

import math

import numpy as np
import pytest

from commission.controllers.metrics import Indexes, indexes

TS = 1e-3


def grid(T):
    return np.arange(int(round(T / TS))) * TS


def test_sinusoid_over_whole_periods():
    # e = A sin(w t) over an integer number of periods: rms = A/sqrt(2), max = A.
    t = grid(10.0)
    A, w = 3e-6, 2 * math.pi * 2.0
    e = A * np.sin(w * t)
    u = np.full_like(t, 0.4)
    r = indexes(t, e, u)
    assert isinstance(r, Indexes)
    assert r.e_rms == pytest.approx(A / math.sqrt(2), rel=1e-9)
    assert r.e_M == pytest.approx(A, rel=1e-6)
    assert r.e_F == pytest.approx(A, rel=1e-6)
    # Constant input: rms is the constant, no increments.
    assert r.u_rms == pytest.approx(0.4, rel=1e-12)
    assert r.du_rms == 0.0 and r.c_u == 0.0


def test_alternating_input_chatter():
    # u = +a, -a, +a, ...: every increment is 2a, so du_rms = 2a and c_u = 2.
    t = grid(1.0)
    a = 0.3
    u = a * (-1.0) ** np.arange(t.size)
    r = indexes(t, np.zeros_like(t), u)
    assert r.u_rms == pytest.approx(a, rel=1e-12)
    assert r.du_rms == pytest.approx(2 * a, rel=1e-12)
    assert r.c_u == pytest.approx(2.0, rel=1e-12)
    assert r.e_M == 0.0 and r.e_rms == 0.0


def test_ramp_input_increment_and_rms():
    # u_k = c k: increments all c; rms = c sqrt(sum k^2 / N) = c sqrt((N-1)(2N-1)/6).
    t = grid(2.0)
    N, c = t.size, 1e-3
    u = c * np.arange(N)
    r = indexes(t, np.zeros(N), u)
    assert r.du_rms == pytest.approx(c, rel=1e-12)
    assert r.u_rms == pytest.approx(c * math.sqrt((N - 1) * (2 * N - 1) / 6), rel=1e-12)


def test_final_window_is_last_two_seconds():
    t = grid(10.0)  # t[-1] = 9.999 s: the window is t >= 7.999 s
    e = np.full_like(t, 1e-6)
    e[np.searchsorted(t, 5.0)] = -50e-6  # transient spike: counts for e_M, not e_F
    k_edge = np.searchsorted(t, t[-1] - 2.0 - 1e-12)  # first sample inside the window
    e[k_edge] = 7e-6
    e[k_edge - 1] = 9e-6  # just before the window
    r = indexes(t, e, np.ones_like(t))
    assert r.e_M == pytest.approx(50e-6)
    assert r.e_F == pytest.approx(7e-6)
    r1 = indexes(t, e, np.ones_like(t), final_window=2.0 + TS)
    assert r1.e_F == pytest.approx(9e-6)


def test_zero_input_gives_nan_chatter_index():
    t = grid(1.0)
    r = indexes(t, np.zeros_like(t), np.zeros_like(t))
    assert r.u_rms == 0.0 and math.isnan(r.c_u)


def test_bad_samples_are_named():
    t = grid(1.0)
    e = np.zeros_like(t)
    e[17] = np.nan
    with pytest.raises(ValueError, match="e: sample 17 is nan"):
        indexes(t, e, np.zeros_like(t))
    with pytest.raises(ValueError, match="need 1000 samples"):
        indexes(t, np.zeros(999), np.zeros_like(t))
