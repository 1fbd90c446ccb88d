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

This module holds the one definition of the indexes: :class:`Indexes`, the record of one run
(the six indexes, the peak input and whether it diverged) that tune, validate, the gate, the
report and the paper table share; :func:`batch_indexes`, the same records from a batch's
columns; and :data:`INDEX_TABLE` (defined in :mod:`.index_table`, re-exported here), each index's name, label, unit and display scale, from which
tables and file formats take their rows.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numba import njit

from commission.controllers.index_table import (INDEX_NAMES, INDEX_ROWS, INDEX_TABLE,  # noqa: F401 (re-exported)
                                                SCORE_NAMES, IndexRow)

FINAL_WINDOW = 2.0  # s, the paper's e_F window


def _num_or_null(x: float) -> float | None:
    return float(x) if math.isfinite(x) else None


@dataclass(frozen=True)
class Indexes:
    """The Section-4.2 indexes of one run (SI units), its peak input and whether it diverged.

    The one record of a run's performance: tune scores candidates with it, validate records it
    in validation.json, the gate judges it, tuning.json stores it (:meth:`to_dict`).  Indexes
    are NaN when the run diverged.  :func:`indexes` fills only the six indexes (``u_peak``
    NaN: not recorded); :meth:`of_run` and :func:`batch_indexes` give the whole record.

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
    u_peak : float
        Largest ``|u|`` over the recorded samples (also before an abort), u-unit; NaN if
        not recorded.
    diverged : bool
        The run was aborted.
    """

    e_M: float
    e_F: float
    e_rms: float
    u_rms: float
    du_rms: float
    c_u: float
    u_peak: float = math.nan
    diverged: bool = False

    def to_dict(self) -> dict[str, float | bool | None]:
        """The record as tuning.json and validation.json store it: SI numbers, null for NaN or inf."""
        d: dict[str, float | bool | None] = {k: _num_or_null(getattr(self, k)) for k in SCORE_NAMES}
        d["diverged"] = self.diverged
        return d

    @classmethod
    def of_run(cls, ix: "Indexes | None", u_peak: float) -> "Indexes":
        """The record of one run from its six indexes (None: it diverged) and its peak input."""
        if ix is None:
            return cls(*(math.nan,) * len(INDEX_NAMES), u_peak=float(u_peak), diverged=True)
        return cls(ix.e_M, ix.e_F, ix.e_rms, ix.u_rms, ix.du_rms, ix.c_u, float(u_peak), False)


def batch_indexes(idx: np.ndarray, u_peak: np.ndarray, diverged: np.ndarray) -> list[Indexes]:
    """The records of a batch of runs from its columns.

    Parameters
    ----------
    idx : ndarray, shape (m, 6)
        The six indexes per run in :data:`INDEX_NAMES` order (NaN where diverged).
    u_peak : ndarray, shape (m,)
        Peak input per run, u-unit.
    diverged : ndarray of bool, shape (m,)

    Returns
    -------
    list of Indexes
        One per row, the same record :meth:`Indexes.of_run` makes of a single run.
    """
    return [Indexes(*(float(x) for x in idx[i]), float(u_peak[i]), bool(diverged[i])) for i in range(len(idx))]


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
