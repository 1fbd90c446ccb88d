"""Linear model of an axis as the sampled controller sees it: u_k -> y_k.

The plant of :mod:`commission.controllers.plant` without its friction, ripple
and offset (a discontinuity and two position-dependent forces that no linear
model holds; the controllers compensate them as feedforward), i.e. the rigid
body ``M s^2 + B s`` or the two-mass mode, behind the actuator's zero-order
hold and the input delay ``tau``.  The discretisation is exact (scipy.signal's
``cont2discrete`` practice: one matrix exponential of an augmented matrix, Van
Loan): with ``tau = (n + f) Ts``, ``0 <= f < 1``::

    x_{k+1} = Phi x_k + G0 u_{k-n} + G1 u_{k-n-1}
    G0 = int_0^{(1-f)Ts} e^{A s} ds B,   G1 = e^{A (1-f) Ts} int_0^{f Ts} e^{A s} ds B
    y_k = C x_k

(the modified z-transform).  Its frequency response is the one a spectral
estimate from the sampled command and encoder readings measures, aliasing and
the hold included, which is why :mod:`commission.identify.frf` fits modes and
delay with it, and the stability margins (:mod:`commission.controllers.margins`)
close the loop on it.
"""

from __future__ import annotations

import functools
import math
import threading
from dataclasses import dataclass

import numpy as np
from numba import njit
from scipy.linalg import expm, matrix_balance, schur

from commission.controllers.plant import (P_B, P_DELAY, P_M, P_MODE2_DAMPING, P_MODE2_HZ, P_MODE2_LOAD_SIDE,
                                          P_MODE2_RATIO, P_MODE_DAMPING, P_MODE_HZ, P_MODE_LOAD_SIDE,
                                          P_MODE_RATIO, plant_vector)


def continuous_model(plant_p: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Continuous state space ``(A, B, C)`` of the plant's linear part, force in u-unit, position in m.

    Rigid: states (x, v).  With a mode: (x1, v1, x2, v2), the motor side
    first; with a second mode also (x3, v3).  ``C`` picks the position the encoder reads
    (the same masses, springs and dampers as :func:`commission.controllers.plant.plant_step`).
    """
    M, Bv = float(plant_p[P_M]), float(plant_p[P_B])
    if plant_p[P_MODE_HZ] <= 0:
        return (np.array([[0.0, 1.0], [0.0, -Bv / M]]), np.array([[0.0], [1.0 / M]]), np.array([[1.0, 0.0]]))
    two = plant_p[P_MODE2_HZ] > 0
    r = float(plant_p[P_MODE_RATIO])
    r2 = float(plant_p[P_MODE2_RATIO]) if two else 0.0
    m1 = (1.0 - r - r2) * M
    loads = [(r * M, (1.0 - r) * M, float(plant_p[P_MODE_HZ]), float(plant_p[P_MODE_DAMPING]))]
    if two:
        loads.append((r2 * M, (1.0 - r2) * M, float(plant_p[P_MODE2_HZ]), float(plant_p[P_MODE2_DAMPING])))
    n = 2 + 2 * len(loads)
    A = np.zeros((n, n))
    A[0, 1] = 1.0
    A[1, 1] = -Bv / m1
    for i, (m, rest, f, zeta) in enumerate(loads):
        mu = rest * m / M
        w = 2.0 * math.pi * f
        k, c = w * w * mu, 2.0 * zeta * w * mu
        j = 2 + 2 * i
        A[1, 0] -= k / m1
        A[1, 1] -= c / m1
        A[1, j] += k / m1
        A[1, j + 1] += c / m1
        A[j, j + 1] = 1.0
        A[j + 1, 0], A[j + 1, 1], A[j + 1, j], A[j + 1, j + 1] = k / m, c / m, -k / m, -c / m
    Bm = np.zeros((n, 1))
    Bm[1, 0] = 1.0 / m1
    C = np.zeros((1, n))
    if two and plant_p[P_MODE2_LOAD_SIDE] > 0.5:
        C[0, 4] = 1.0
    else:
        C[0, 2 if plant_p[P_MODE_LOAD_SIDE] > 0.5 else 0] = 1.0
    return A, Bm, C


def structural_modes(plant_p: np.ndarray) -> list[tuple[float, float]]:
    """The plant's structural modes as coupled: ``[(frequency_hz, damping), ...]``, lowest first.

    The poles of :func:`continuous_model` other than the rigid body's pair: with two modes
    hanging on the motor side, these differ a little from the appendages' own ``mode_hz`` and
    ``mode2_hz``, and they are what a measured frequency response shows.
    """
    if plant_p[P_MODE_HZ] <= 0:
        return []
    A, _, _ = continuous_model(plant_p)
    poles = np.linalg.eigvals(A)
    tiny = 1e-6 * float(np.max(np.abs(poles)))  # the rigid body's double pole at 0 (and -B/M) is not a mode
    osc = sorted((p for p in poles if p.imag > tiny), key=lambda p: abs(p))
    return [(abs(p) / (2.0 * math.pi), -p.real / abs(p)) for p in osc]


def _hold(A: np.ndarray, B: np.ndarray, t: float) -> tuple[np.ndarray, np.ndarray]:
    """``(e^{A t}, int_0^t e^{A s} ds B)`` from one exponential of the augmented matrix."""
    n, m = B.shape
    aug = np.zeros((n + m, n + m))
    aug[:n, :n] = A * t
    aug[:n, n:] = B * t
    E = expm(aug)
    return E[:n, :n], E[:n, n:]


def discrete_response(A: np.ndarray, B: np.ndarray, C: np.ndarray, D: float, Ts: float,
                      f_hz: np.ndarray, *, compiled: bool = False) -> np.ndarray:
    """``C (zI - A)^-1 B + D`` of a single-input single-output discrete system at ``z = exp(j 2 pi f Ts)``.

    ``A`` is balanced (a diagonal similarity, scipy.linalg.matrix_balance: the linearised ARC's
    states span fifteen decades of scale) and reduced once to complex Schur form
    ``T = U^H A U`` (unitary); ``(zI - T) x = U^H B`` is then a triangular system, solved at
    every frequency at once by back-substitution: O(n^2) array operations over the grid
    instead of a dense LU per frequency, or with ``compiled`` the same back-substitution in
    compiled loops (:func:`_triangular_response`: no temporaries over the grid and no BLAS
    threads; the same values to rounding, the products summed in another order).  The controllers' responses,
    computed for every candidate of a search, take the compiled loop
    (:meth:`commission.controllers.margins.LinearController.frequency_response`); the plants'
    keep the array form, so that identification's fits, which use them, give the same figures
    to the last bit as before (tests/test_margins.py holds both to the dense solve;
    docs/robustness.md has the timing).  The balancing matters: the unitary reduction's
    rounding is relative to the largest entry, which without it swamps the small ones.  An
    eigen-decomposition would not do: the linearised ARC has near-repeated poles at z = 1.
    """
    f = np.atleast_1d(np.asarray(f_hz, dtype=float))
    z = _unit_circle(f, Ts) if compiled else np.exp(1j * 2.0 * np.pi * f * Ts)
    A = np.asarray(A, dtype=float)
    b = np.asarray(B, dtype=float)[:, 0]
    c = np.asarray(C, dtype=float)[0]
    n = A.shape[0]
    if n == 0:
        return np.full(z.shape, complex(D))
    Ab, (scale, _) = matrix_balance(A, permute=False, separate=True)
    T, U = schur(Ab.astype(complex), output="complex")
    bt = U.conj().T @ (b / scale)
    ct = (c * scale) @ U
    if compiled:
        return _triangular_response(np.ascontiguousarray(T), bt, ct, complex(D), z)
    x = np.empty((z.size, n), dtype=complex)
    for k in range(n - 1, -1, -1):  # (z - T_kk) x_k - sum_{j>k} T_kj x_j = bt_k
        r = bt[k] + x[:, k + 1:] @ T[k, k + 1:] if k < n - 1 else np.full(z.size, bt[k])
        x[:, k] = r / (z - T[k, k])
    return x @ ct + D


#: The last grids' ``z = exp(j 2 pi f Ts)`` (:func:`_unit_circle`), keyed by the grid's bits and Ts.
_Z_KEPT = 4
_z_cache: dict = {}
_z_lock = threading.Lock()


def _unit_circle(f: np.ndarray, Ts: float) -> np.ndarray:
    """``exp(j 2 pi f Ts)`` of the grid ``f`` (Hz), read-only, computed once per grid and period.

    A search evaluates every candidate's controller on the same grid, and the complex
    exponential of the whole grid is a visible part of each response (docs/scaling.md).  The
    same expression as before, so the same values.
    """
    key = (f.shape, f.tobytes(), float(Ts))
    with _z_lock:
        hit = _z_cache.get(key)
    if hit is not None:
        return hit
    z = np.exp(1j * 2.0 * np.pi * f * Ts)
    z.setflags(write=False)
    with _z_lock:
        if len(_z_cache) >= _Z_KEPT:
            _z_cache.pop(next(iter(_z_cache)))
        _z_cache[key] = z
    return z


#: Frequencies :func:`_triangular_response` carries through the whole back-substitution at a time.
TRI_BLOCK = 256


@njit(cache=True, nogil=True)
def _triangular_response(T, bt, ct, D, z):
    """``ct (zI - T)^-1 bt + D`` for upper-triangular ``T`` at every ``z``, by back-substitution.

    ``(z - T_kk) x_k - sum_{j>k} T_kj x_j = bt_k``, k from the last state up; at each frequency
    the sums run in the same order (j up from k + 1, then k up for the output), but each step
    sweeps a block of :data:`TRI_BLOCK` frequencies in a contiguous inner loop (compiled: no
    temporaries, no BLAS threads), the block's states staying in the first-level cache through
    the whole substitution.  Every frequency's operations are the same whatever the block.

    The complex values are held as separate real and imaginary arrays, and the products,
    sums and quotients are written out as numba's complex arithmetic computes them (the
    product ``(ac - bd) + i(ad + bc)``, the quotient by CPython's ``_Py_c_quot``): the same
    values to the last bit as the complex-typed loop, in loops the compiler vectorises.
    """
    n = T.shape[0]
    nf = z.size
    out = np.empty(nf, dtype=np.complex128)
    xr = np.empty((n, TRI_BLOCK))
    xi = np.empty((n, TRI_BLOCK))
    zr = np.empty(TRI_BLOCK)
    zi = np.empty(TRI_BLOCK)
    orr = np.empty(TRI_BLOCK)
    oi = np.empty(TRI_BLOCK)
    for i0 in range(0, nf, TRI_BLOCK):
        nb = min(TRI_BLOCK, nf - i0)
        for i in range(nb):
            zr[i] = z[i0 + i].real
            zi[i] = z[i0 + i].imag
        for k in range(n - 1, -1, -1):
            ar = xr[k]
            ai = xi[k]
            b = bt[k]
            for i in range(nb):
                ar[i] = b.real
                ai[i] = b.imag
            for j in range(k + 1, n):
                t = T[k, j]
                tr = t.real
                ti = t.imag
                br = xr[j]
                bi = xi[j]
                for i in range(nb):  # x_k += T_kj x_j
                    ar[i] = ar[i] + (tr * br[i] - ti * bi[i])
                    ai[i] = ai[i] + (tr * bi[i] + ti * br[i])
            dr = T[k, k].real
            di = T[k, k].imag
            for i in range(nb):
                if zr[i] - dr == 0.0 and zi[i] - di == 0.0:
                    raise ZeroDivisionError("complex division by zero")
            for i in range(nb):  # x_k /= z - T_kk (CPython's _Py_c_quot, as numba divides)
                er = zr[i] - dr
                ei = zi[i] - di
                pr = ar[i]
                pi = ai[i]
                if abs(er) >= abs(ei):
                    ratio = ei / er
                    den = er + ei * ratio
                    ar[i] = (pr + pi * ratio) / den
                    ai[i] = (pi - pr * ratio) / den
                elif abs(ei) >= abs(er):
                    ratio = er / ei
                    den = er * ratio + ei
                    ar[i] = (pr * ratio + pi) / den
                    ai[i] = (pi * ratio - pr) / den
                else:  # a NaN in the denominator
                    ar[i] = np.nan
                    ai[i] = np.nan
        for i in range(nb):
            orr[i] = D.real
            oi[i] = D.imag
        for k in range(n):  # out += x_k ct_k
            c = ct[k]
            cr = c.real
            ci = c.imag
            ar = xr[k]
            ai = xi[k]
            for i in range(nb):
                orr[i] = orr[i] + (ar[i] * cr - ai[i] * ci)
                oi[i] = oi[i] + (ar[i] * ci + ai[i] * cr)
        for i in range(nb):
            out[i0 + i] = complex(orr[i], oi[i])
    return out


@dataclass(frozen=True)
class SampledPlant:
    """The plant's linear part sampled at ``Ts`` behind a hold and an input delay (module docstring).

    Attributes
    ----------
    Phi, G0, G1 : ndarray
        ``x_{k+1} = Phi x_k + G0 u_{k-n} + G1 u_{k-n-1}``.
    C : ndarray, shape (1, nx)
        Output row, ``y_k = C x_k`` (position, m).
    n : int
        Whole samples of the delay, samples.
    Ts : float
        Sample period, s.
    """

    Phi: np.ndarray
    G0: np.ndarray
    G1: np.ndarray
    C: np.ndarray
    n: int
    Ts: float

    def frequency_response(self, f_hz: np.ndarray) -> np.ndarray:
        """``Y/U`` at ``z = exp(j 2 pi f Ts)``, m per u-unit (complex, one value per frequency)."""
        A, B, C = self.state_space()
        return discrete_response(A, B, C, 0.0, self.Ts, f_hz)

    def state_space(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """A delay-free realisation ``(A, B, C)`` with the past commands as extra states.

        States ``[x, u_{k-1}, ..., u_{k-n-1}]``; ``y_k = C x_k`` has no direct
        feedthrough, so the loop can be closed on it without an algebraic loop.
        Built once per plant (read-only arrays): the margin checks close a loop on the same
        plant for every candidate.
        """
        return self._realisation

    @functools.cached_property
    def _realisation(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        nx = self.Phi.shape[0]
        nb = self.n + 1  # u_{k-1} .. u_{k-n-1}
        A = np.zeros((nx + nb, nx + nb))
        B = np.zeros((nx + nb, 1))
        A[:nx, :nx] = self.Phi
        # u_{k-n} enters through G0 and u_{k-n-1} through G1
        if self.n == 0:
            B[:nx, 0] += self.G0[:, 0]
        else:
            A[:nx, nx + self.n - 1] += self.G0[:, 0]
        A[:nx, nx + self.n] += self.G1[:, 0]
        B[nx, 0] = 1.0  # u_k becomes u_{(k+1)-1}
        for j in range(1, nb):
            A[nx + j, nx + j - 1] = 1.0
        C = np.zeros((1, nx + nb))
        C[0, :nx] = self.C[0]
        for a in (A, B, C):
            a.setflags(write=False)
        return A, B, C


def sampled_plant(plant_p: np.ndarray, Ts: float, extra_delay: float = 0.0) -> SampledPlant:
    """Sample the plant's linear part at ``Ts`` (zero-order hold) with its input delay.

    Parameters
    ----------
    plant_p : ndarray, shape (NP,)
        Plant vector; ``P_DELAY`` (s) is the input delay.
    Ts : float
        Sample period, s.
    extra_delay : float
        More input delay, in samples (fractional allowed), on top of the plant's.
    """
    if not (Ts > 0 and math.isfinite(Ts)):
        raise ValueError(f"sampled_plant: Ts must be a positive period in s, got {Ts}")
    tau = float(plant_p[P_DELAY]) / Ts + float(extra_delay)
    if not (tau >= 0 and math.isfinite(tau)):
        raise ValueError(f"sampled_plant: the input delay must be >= 0 samples, got {tau}")
    n = int(math.floor(tau + 1e-9))
    f = tau - n
    if f < 1e-9:
        f = 0.0
    A, B, C = continuous_model(plant_p)
    Phi_a, G_a = _hold(A, B, (1.0 - f) * Ts)
    if f > 0:
        _, G_b = _hold(A, B, f * Ts)
        G1 = Phi_a @ G_b
    else:
        G1 = np.zeros_like(G_a)
    Phi = Phi_a @ _hold(A, B, f * Ts)[0] if f > 0 else Phi_a
    return SampledPlant(Phi=Phi, G0=G_a, G1=G1, C=C, n=n, Ts=float(Ts))


def rigid_frequency_response(M: float, B: float, Ts: float, f_hz: np.ndarray) -> np.ndarray:
    """Sampled frequency response of the rigid body ``1/(M s^2 + B s)`` (no delay), m per u-unit."""
    return sampled_plant(plant_vector(M, max(B, 0.0)), Ts).frequency_response(f_hz)
