"""Performance indexes of Section 4.2 of Xu & Yao (2001).

On a uniformly sampled record ``e_k, u_k`` (k = 0..N-1, period Ts):

* ``e_M   = max_k |e_k|``                                   (transient)
* ``e_F   = max |e_k|`` over ``t_k >= t_{N-1} - final_window``  (final accuracy;
  the paper's last 2 s)
* ``e_rms = sqrt(mean e_k^2)``, ``u_rms = sqrt(mean u_k^2)``  (the integrals
  ``(1/T_f) int e^2 dt`` by the rectangle rule on the samples)
* ``du_rms = sqrt(mean (u_k - u_{k-1})^2)`` over the N-1 increments, eq. (54)
* ``c_u = du_rms / u_rms``                                   (chattering)

``c_u`` is NaN when ``u_rms == 0`` (undefined); no paper scenario has that.
The kernel is compiled so that the batch simulator can call it per scenario.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numba import njit

FINAL_WINDOW = 2.0  # s, the paper's e_F window


@dataclass(frozen=True)
class Indexes:
    """The Section-4.2 indexes of one run (SI units).

    Attributes
    ----------
    e_M : float
        Maximum absolute tracking error, m.
    e_F : float
        Maximum absolute tracking error over the final window, m.
    e_rms : float
        RMS tracking error, m.
    u_rms : float
        RMS input, u-unit.
    du_rms : float
        RMS of the input increments (54), u-unit.
    c_u : float
        ``du_rms / u_rms``, dimensionless.
    """

    e_M: float
    e_F: float
    e_rms: float
    u_rms: float
    du_rms: float
    c_u: float

    def as_dict(self) -> dict[str, float]:
        """The six indexes by name, SI units."""
        return {"e_M": self.e_M, "e_F": self.e_F, "e_rms": self.e_rms,
                "u_rms": self.u_rms, "du_rms": self.du_rms, "c_u": self.c_u}


@njit(cache=True)
def indexes_kernel(e, u, t_last, Ts, n, final_window):
    """Indexes of the first ``n`` samples of ``e`` (m) and ``u`` (u-unit).

    ``t_k = t_last - (n-1-k) Ts``; the final window is ``t_k >= t_last - final_window``.
    Returns ``(e_M, e_F, e_rms, u_rms, du_rms, c_u)``.
    """
    t_from = t_last - final_window - 1e-9 * Ts
    eM = 0.0
    eF = 0.0
    se = 0.0
    su = 0.0
    sdu = 0.0
    for k in range(n):
        ae = abs(e[k])
        if ae > eM:
            eM = ae
        if t_last - (n - 1 - k) * Ts >= t_from and ae > eF:
            eF = ae
        se += e[k] * e[k]
        su += u[k] * u[k]
        if k > 0:
            d = u[k] - u[k - 1]
            sdu += d * d
    e_rms = math.sqrt(se / n)
    u_rms = math.sqrt(su / n)
    du_rms = math.sqrt(sdu / (n - 1)) if n > 1 else 0.0
    c_u = du_rms / u_rms if u_rms > 0.0 else math.nan
    return eM, eF, e_rms, u_rms, du_rms, c_u


def indexes(t: np.ndarray, e: np.ndarray, u: np.ndarray, *,
            final_window: float = FINAL_WINDOW) -> Indexes:
    """Section-4.2 indexes of a uniformly sampled record.

    Parameters
    ----------
    t : ndarray, shape (N,)
        Uniform sample times, s.
    e : ndarray, shape (N,)
        Tracking error, m.
    u : ndarray, shape (N,)
        Input, u-unit.
    final_window : float
        Length of the final window of ``e_F``, s (paper: 2).

    Returns
    -------
    Indexes
    """
    t, e, u = (np.ascontiguousarray(a, dtype=np.float64) for a in (t, e, u))
    for name, a in (("t", t), ("e", e), ("u", u)):
        if a.ndim != 1:
            raise ValueError(f"{name}: expected a 1-D array, got shape {a.shape}")
        bad = np.flatnonzero(~np.isfinite(a))
        if bad.size:
            raise ValueError(f"{name}: sample {bad[0]} is {a[bad[0]]}")
    n = t.shape[0]
    if e.shape[0] != n or u.shape[0] != n:
        raise ValueError(f"e, u: need {n} samples like t, got {e.shape[0]} and {u.shape[0]}")
    if n < 2:
        raise ValueError(f"t: need at least 2 samples, got {n}")
    Ts = (t[-1] - t[0]) / (n - 1)
    if not Ts > 0:
        raise ValueError(f"t: not increasing (t[0]={t[0]}, t[-1]={t[-1]})")
    if not final_window >= 0:
        raise ValueError(f"final_window: must be >= 0 s, got {final_window}")
    return Indexes(*(float(x) for x in indexes_kernel(e, u, float(t[-1]), float(Ts), n, float(final_window))))
