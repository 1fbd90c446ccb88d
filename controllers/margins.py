"""Stability margins of a sampled loop: controller step x linear plant.

Both controllers are linearised the same way, from the very compiled step
that runs on the machine (``arc_step`` or ``pid_step``), by central
differences of the map ``(s_k, y_k) -> (s_{k+1}, c_k)`` about an operating
point at rest (``y = q_d = 0``, ``dq_d = ddq_d = 0``)::

    xc_{k+1} = Ac xc_k + Bc y_k,   c_k = Cc xc_k + Dc y_k      (K(z) = c/y)

What "linearised" means for the nonlinear parts of the ARC:

* **adaptation**: kept, as the linear dynamics of theta_hat at the operating
  point (its gain Gamma tau with phi evaluated at rest: theta_hat3 acts as the
  loop's integral action; at rest the theta1, theta2 updates have no gain);
  theta_hat sits at the point given (the initial estimate, or the plant's own
  value), moved 0.1 % of the box inside so that the projection is inactive;
* **robust terms**: their gains K1, K2 at rest, caps and the v-loop guard
  included (the derivative of K z at z = 0 is K);
* **friction compensation**: left out of both the plant and the controllers:
  Coulomb friction is a discontinuity at rest, and at speed the compensation's
  slope and the friction's cancel.  The PID's compensation acts on the
  measured velocity, so keeping it would add a spurious positive velocity
  feedback of level (2/pi) slope;
* **saturation**: inactive (small signals).

The loop is closed on the plant of :func:`commission.controllers.linear.sampled_plant`
(rigid body or mode, hold and input delay) with ``u_k = c_k``.  The loop
transfer at the plant input is ``L(z) = -K(z) P(z)`` (negative feedback), and
on ``z = exp(j w Ts)``, ``0 < w <= pi/Ts``:

* **gain margin** (dB): the smallest ``-20 log10 |L|`` at a phase crossover
  (angle ``-180 deg``) above the first gain crossover -- how much more loop
  gain the loop takes; negative when a resonance already lifts ``|L|`` above 1
  there;
* **phase margin** (deg): ``180 deg + angle L`` at the first gain crossover,
  the rigid body's (at a lightly damped mode ``|L|`` can cross 1 with any
  phase; the delay, gain and modulus margins cover those crossovers);
* **delay margin** (samples): the smallest ``(PM mod 360 deg) / (w_c Ts)`` over
  the gain crossovers -- the extra input delay the loop takes (a crossover at a
  lightly damped mode can have any phase); for an unstable loop the negative
  of the smallest lag that would have to be removed, so that the margin
  changes sign where stability is lost;
* **modulus margin**: ``min |1 + L|``, the distance of the Nyquist curve to
  -1 (the disk margin that bounds both gain and phase);
* **stable**: every eigenvalue of the closed loop inside the unit circle.

The margins are read off a dense logarithmic frequency grid with the
crossings refined by linear interpolation; eigenvalues decide stability.
"""

from __future__ import annotations

import math
import threading
from collections import OrderedDict
from dataclasses import dataclass, field
from typing import Callable

import numpy as np
from numba import njit

from commission.controllers.arc import (P_FLEVEL, P_GAMMA, P_K1, P_TMAX, P_TMIN, P_TS, S_DYNAMIC, S_THETA,
                                        arc_new_state, arc_reset, arc_step)
from commission.controllers.linear import SampledPlant, discrete_response
from commission.controllers.pid import G_FLEVEL, PID_DYNAMIC, pid_new_state, pid_reset, pid_step

#: Relative step of the central differences (states scaled by their response to 1 um).
_REL_STEP = 1e-4
#: Tolerance on |eigenvalue| - 1 for neutral modes (theta_hat1, theta_hat2 at rest).
NEUTRAL_TOL = 1e-7
#: Time constants of the observer (1/p, p = k1/2) the filters settle for before the Jacobian.
SETTLE_TIME_CONSTANTS = 40.0
#: Points of the frequency grid.
N_FREQ = 6000


@dataclass(frozen=True)
class LinearController:
    """``K(z)``: ``xc+ = Ac xc + Bc y``, ``c = Cc xc + Dc y`` (u-unit per m)."""

    Ac: np.ndarray
    Bc: np.ndarray
    Cc: np.ndarray
    Dc: float
    Ts: float
    _responses: dict = field(default_factory=dict, init=False, repr=False, compare=False)

    def frequency_response(self, f_hz: np.ndarray) -> np.ndarray:
        """``K`` at ``z = exp(j 2 pi f Ts)``, u-unit per m (the compiled back-substitution of
        :func:`commission.controllers.linear.discrete_response`: a search evaluates it for every
        candidate).

        Kept per grid (the last :data:`RESPONSES_KEPT`, read-only): one gain set's linearisation
        at its initial estimate meets the identified plant's margins, the evidence bound and the
        box check (:func:`linearize_arc` returns the same object to each), which then share it.
        """
        f = np.ascontiguousarray(f_hz, dtype=np.float64)
        key = (f.shape, f.tobytes())
        with _cache_lock:
            hit = self._responses.get(key)
        if hit is not None:
            return hit
        r = discrete_response(self.Ac, self.Bc, self.Cc, self.Dc, self.Ts, f, compiled=True)
        r.setflags(write=False)
        with _cache_lock:
            if len(self._responses) >= RESPONSES_KEPT:
                self._responses.pop(next(iter(self._responses)))
            self._responses[key] = r
        return r


#: Frequency grids whose response a :class:`LinearController` keeps.
RESPONSES_KEPT = 4
#: Linearisations :func:`linearize_arc` keeps (the last ones asked for: the checks of one
#: candidate ask for the same few several times).
LINEARISATIONS_KEPT = 32
_cache_lock = threading.Lock()
_arc_linearisations: "OrderedDict[bytes, LinearController]" = OrderedDict()


@njit(cache=True, nogil=True)
def _perturbed(s0, idx, j, h):
    """The point one central difference steps to: ``(s, y)`` = ``(s0, 0)`` moved by ``h``.

    Input ``y`` for ``j < 0``, else state ``idx[j]``; ``s`` is a fresh copy of ``s0`` (the
    step runs in place).  Compiled, so that :func:`_arc_jacobian` calls it inside its
    loop; :func:`_jacobian` calls the same function from Python, so both linearisations
    step by the very same rule.
    """
    s = s0.copy()
    y = 0.0
    if j < 0:
        y = h
    else:
        s[idx[j]] += h
    return s, y


def _jacobian(step: Callable, p: np.ndarray, s0: np.ndarray, dyn: tuple[int, ...], scale: np.ndarray,
              h_y: float) -> LinearController:
    n = len(dyn)
    Ac, Bc, Cc = np.empty((n, n)), np.empty(n), np.empty(n)
    Dc = 0.0
    idx = np.array(dyn)

    def run(j: int, h: float) -> tuple[np.ndarray, float]:
        s, y = _perturbed(s0, idx, j, h)
        c = step(p, s, y, 0.0, 0.0, 0.0)
        return s[idx], c

    for j in range(-1, n):
        h = h_y if j < 0 else _REL_STEP * scale[j]
        sp, cp = run(j, h)
        sm, cm = run(j, -h)
        ds, dc = (sp - sm) / (2 * h), (cp - cm) / (2 * h)
        if j < 0:
            Bc[:], Dc = ds, dc
        else:
            Ac[:, j], Cc[j] = ds, dc
    return LinearController(Ac=Ac, Bc=Bc.reshape(-1, 1), Cc=Cc.reshape(1, -1), Dc=float(Dc), Ts=float(p[0]))


@njit(cache=True, nogil=True)
def _arc_jacobian(p, s0, idx, scale, h_y, rel_step):
    """:func:`_jacobian` of :func:`arc_step` in one compiled call: ``(Ac, Bc, Cc, Dc)``.

    The same central differences in the same order (the same steps, the same compiled step,
    the same quotients), so the same values to the last bit; only the 2 (n + 1) calls of the
    step from Python and their copies are gone (a box check linearises a dozen times per candidate).
    """
    n = idx.size
    Ac = np.empty((n, n))
    Bc = np.empty(n)
    Cc = np.empty(n)
    Dc = 0.0
    sp = np.empty(n)
    sm = np.empty(n)
    for j in range(-1, n):
        h = h_y if j < 0 else rel_step * scale[j]
        s, y = _perturbed(s0, idx, j, h)
        cp = arc_step(p, s, y, 0.0, 0.0, 0.0)
        for i in range(n):
            sp[i] = s[idx[i]]
        s, y = _perturbed(s0, idx, j, -h)
        cm = arc_step(p, s, y, 0.0, 0.0, 0.0)
        for i in range(n):
            sm[i] = s[idx[i]]
        for i in range(n):
            d = (sp[i] - sm[i]) / (2 * h)
            if j < 0:
                Bc[i] = d
            else:
                Ac[i, j] = d
        dc = (cp - cm) / (2 * h)
        if j < 0:
            Dc = dc
        else:
            Cc[j] = dc
    return Ac, Bc, Cc, Dc


def _scales(step: Callable, p: np.ndarray, s0: np.ndarray, dyn: tuple[int, ...]) -> np.ndarray:
    """Size of each state's response to 1 um of y over a few samples (the difference step's scale)."""
    idx = np.array(dyn)
    s = s0.copy()
    peak = np.abs(s0[idx]) * 1e-3
    for k in range(5):
        step(p, s, 1e-6, 0.0, 0.0, 0.0)
        peak = np.maximum(peak, np.abs(s[idx] - s0[idx]))
    return np.maximum(peak, 1e-18)


@njit(cache=True)
def _settle(p, s, n):
    """``n`` steps of ``arc_step(p, s, 0, 0, 0, 0)`` in place (compiled: a few thousand steps per call)."""
    for _ in range(n):
        arc_step(p, s, 0.0, 0.0, 0.0, 0.0)


def arc_operating_point(p: np.ndarray, theta_hat) -> tuple[np.ndarray, np.ndarray]:
    """The ARC at rest with the estimate ``theta_hat``: ``(p_lin, s)`` to linearise about.

    ``p_lin`` is ``p`` without friction compensation; ``s`` is the state after
    the filters settled at ``y = q_d = 0`` with the estimates held, theta_hat
    moved 0.1 % of the box inside so that the projection is inactive.  From
    there ``arc_step(p_lin, s, 0, 0, 0, 0)`` returns 0 and the response to a
    small ``y`` is the small-signal one :func:`linearize_arc` describes.
    """
    p = np.array(p, dtype=np.float64)
    p[P_FLEVEL] = 0.0
    lo, hi = p[P_TMIN:P_TMIN + 3], p[P_TMAX:P_TMAX + 3]
    th = np.clip(np.asarray(theta_hat, dtype=float), lo + 1e-3 * (hi - lo), hi - 1e-3 * (hi - lo))
    frozen = p.copy()
    frozen[P_GAMMA:P_GAMMA + 3] = 0.0
    s = arc_new_state(p)
    arc_reset(frozen, s, 0.0)
    s[S_THETA:S_THETA + 3] = th
    settle = int(math.ceil(SETTLE_TIME_CONSTANTS / (0.5 * p[P_K1] * p[P_TS])))
    _settle(frozen, s, settle)  # filters (psi, lambda) to their rest values, estimates held
    s[S_THETA:S_THETA + 3] = th
    return p, s


def linearize_arc(p: np.ndarray, theta_hat) -> LinearController:
    """Linearise the packed ARC ``p`` at rest with the estimate ``theta_hat`` (module docstring).

    A pure function of its arguments, so the last :data:`LINEARISATIONS_KEPT` are kept (keyed
    by the exact bits of ``p`` and ``theta_hat``) and the same object is returned again: a
    search's margin, evidence and box checks of one candidate linearise it at the same
    estimates, and share the frequency responses too (:meth:`LinearController.frequency_response`).
    """
    key = np.ascontiguousarray(p, dtype=np.float64).tobytes() + np.asarray(theta_hat, dtype=np.float64).tobytes()
    with _cache_lock:
        hit = _arc_linearisations.get(key)
        if hit is not None:
            _arc_linearisations.move_to_end(key)
            return hit
    pl, s = arc_operating_point(p, theta_hat)
    Ac, Bc, Cc, Dc = _arc_jacobian(pl, s, np.array(S_DYNAMIC, dtype=np.int64), _scales(arc_step, pl, s, S_DYNAMIC),
                                   1e-9, _REL_STEP)
    lin = LinearController(Ac=Ac, Bc=Bc.reshape(-1, 1), Cc=Cc.reshape(1, -1), Dc=float(Dc), Ts=float(pl[0]))
    for a in (lin.Ac, lin.Bc, lin.Cc):
        a.setflags(write=False)
    with _cache_lock:
        _arc_linearisations[key] = lin
        while len(_arc_linearisations) > LINEARISATIONS_KEPT:
            _arc_linearisations.popitem(last=False)
    return lin


def linearize_pid(p: np.ndarray) -> LinearController:
    """Linearise the packed PID ``p`` at rest, its friction compensation left out (module docstring)."""
    p = np.array(p, dtype=np.float64)
    p[G_FLEVEL] = 0.0
    s = pid_new_state(p)
    pid_reset(p, s, 0.0)
    return _jacobian(pid_step, p, s, PID_DYNAMIC, np.full(len(PID_DYNAMIC), 1e-6), 1e-9)


@dataclass(frozen=True)
class Margins:
    """Stability margins of one loop (module docstring for the definitions).

    Attributes
    ----------
    gain_margin_db : float
        dB (inf: no phase crossover above the first gain crossover).
    phase_margin_deg : float
        Degrees (inf: no gain crossover).
    delay_margin_samples : float
        Extra input delay the loop takes, samples (inf: no gain crossover).
    modulus_margin : float
        ``min |1 + L|``, dimensionless.
    crossover_hz : float
        First gain crossover, Hz (nan: none).
    spectral_radius : float
        Largest closed-loop eigenvalue modulus, dimensionless.
    stable : bool
        The closed loop is stable: spectral radius below 1 (up to ``NEUTRAL_TOL`` for the neutral modes).
    """

    gain_margin_db: float
    phase_margin_deg: float
    delay_margin_samples: float
    modulus_margin: float
    crossover_hz: float
    spectral_radius: float
    stable: bool

    def to_dict(self) -> dict:
        def num(x: float) -> float | None:
            return float(x) if math.isfinite(x) else None

        return {"gain_margin_db": num(self.gain_margin_db), "phase_margin_deg": num(self.phase_margin_deg),
                "delay_margin_samples": num(self.delay_margin_samples), "modulus_margin": num(self.modulus_margin),
                "crossover_hz": num(self.crossover_hz), "spectral_radius": float(self.spectral_radius),
                "stable": bool(self.stable)}


def frequency_grid(Ts: float, n: int = N_FREQ) -> np.ndarray:
    """Logarithmic grid from 1e-4 of the rate to just below Nyquist, Hz."""
    fn = 0.5 / Ts
    return np.geomspace(fn * 2e-4, fn * (1 - 1e-6), n)


def loop_response(ctrl: LinearController, plant: SampledPlant, f_hz: np.ndarray,
                  plant_response: np.ndarray | None = None, ctrl_response: np.ndarray | None = None) -> np.ndarray:
    """``L = -K P`` at the plant input, dimensionless.

    ``plant_response`` (optional) is ``plant.frequency_response(f_hz)`` computed once for a
    plant that many controllers are checked on; ``ctrl_response`` likewise
    ``ctrl.frequency_response(f_hz)`` for a controller checked on many plants.
    """
    P = plant.frequency_response(f_hz) if plant_response is None else plant_response
    K = ctrl.frequency_response(f_hz) if ctrl_response is None else ctrl_response
    return -K * P


def closed_loop_radius(ctrl: LinearController, plant: SampledPlant, gain: float = 1.0) -> float:
    """Spectral radius of the closed loop ``u = gain * c`` (> 1: unstable)."""
    Ap, Bp, Cp = plant.state_space()
    n_p, n_c = Ap.shape[0], ctrl.Ac.shape[0]
    A = np.zeros((n_p + n_c, n_p + n_c))
    A[:n_p, :n_p] = Ap + gain * ctrl.Dc * (Bp @ Cp)
    A[:n_p, n_p:] = gain * (Bp @ ctrl.Cc)
    A[n_p:, :n_p] = ctrl.Bc @ Cp
    A[n_p:, n_p:] = ctrl.Ac
    return float(np.max(np.abs(np.linalg.eigvals(A))))


def _crossings(x: np.ndarray) -> np.ndarray:
    """Fractional indices where ``x`` changes sign."""
    i = np.nonzero(np.sign(x[:-1]) * np.sign(x[1:]) < 0)[0]
    return i + x[i] / (x[i] - x[i + 1])


def _at(a: np.ndarray, fi: float) -> float:
    i = min(int(fi), a.size - 2)
    return float(a[i] + (fi - i) * (a[i + 1] - a[i]))


@njit(cache=True)
def _unwrap_into(p, up):
    """``up[:] = numpy.unwrap(p)`` of a 1-D float64 array (period 2 pi), the same operations in the same order."""
    n = p.size
    if n == 0:
        return
    period = 2.0 * math.pi
    hi = period / 2
    lo = -hi
    up[0] = p[0]
    acc = 0.0
    for i in range(1, n):
        dd = p[i] - p[i - 1]
        corr = 0.0
        if not abs(dd) < hi:  # numpy zeroes the correction of every smaller step: no modulo there
            ddmod = (dd - lo) % period + lo
            if ddmod == lo and dd > 0:
                ddmod = hi
            corr = ddmod - dd
        acc += corr
        up[i] = p[i] + acc


@njit(cache=True)
def _unwrap(p):
    """``numpy.unwrap(p)`` of a 1-D float64 array (period 2 pi), the same operations in the same order."""
    up = np.empty(p.size)
    _unwrap_into(p, up)
    return up


@njit(cache=True)
def _unwrap_rows(p):
    """:func:`_unwrap` of every row of a 2-D float64 array (the loops of :func:`loop_margins_batch`)."""
    up = np.empty_like(p)
    for r in range(p.shape[0]):
        _unwrap_into(p[r], up[r])
    return up


@njit(cache=True)
def _phase_crossover_gain_margin(phase, k, mag_db, first_gc):
    """``(found, gm)``: the smallest ``-mag_db`` at a phase crossover above ``first_gc`` (dB).

    The crossovers of ``phase = -pi + 2 pi kk`` for every branch ``kk`` that ``k`` holds
    (ascending), located and interpolated as :func:`_crossings` and :func:`_at` do, in one
    compiled pass over the grid per branch instead of an array expression per branch.
    """
    n = phase.size
    kmin = k.min()
    m = int(k.max() - kmin) + 1
    present = np.zeros(m, dtype=np.bool_)
    for i in range(n):
        present[int(k[i] - kmin)] = True
    found = False
    best = math.inf
    for j in range(m):
        if not present[j]:
            continue
        off = 2 * math.pi * (kmin + j)
        for i in range(n - 1):
            x0 = phase[i] + math.pi - off
            x1 = phase[i + 1] + math.pi - off
            if (x0 > 0.0 and x1 < 0.0) or (x0 < 0.0 and x1 > 0.0):
                c = i + x0 / (x0 - x1)
                if c > first_gc:
                    ii = min(int(c), n - 2)
                    v = -(mag_db[ii] + (c - ii) * (mag_db[ii + 1] - mag_db[ii]))
                    if not found:
                        best = v
                        found = True
                    elif v < best:
                        best = v
    return found, best


def loop_margins(ctrl: LinearController, plant: SampledPlant, f_hz: np.ndarray | None = None,
                 plant_response: np.ndarray | None = None, ctrl_response: np.ndarray | None = None) -> Margins:
    """Margins of the loop ``ctrl`` x ``plant`` (module docstring).

    ``plant_response``: ``plant.frequency_response(f_hz)``, ``ctrl_response``:
    ``ctrl.frequency_response(f_hz)``, when already computed.
    """
    if f_hz is None:
        f_hz = frequency_grid(plant.Ts)
    L = loop_response(ctrl, plant, f_hz, plant_response, ctrl_response)
    mag_db = 20 * np.log10(np.maximum(np.abs(L), 1e-300))
    phase = _unwrap(np.ascontiguousarray(np.angle(L)))
    return _margins_of(f_hz, plant.Ts, mag_db, phase, closed_loop_radius(ctrl, plant), _crossings(mag_db),
                       float(np.abs(1 + L).min()))


def _margins_of(f_hz: np.ndarray, Ts: float, mag_db: np.ndarray, phase: np.ndarray, radius: float,
                gc: np.ndarray, modulus: float, w: np.ndarray | None = None, k: np.ndarray | None = None,
                finite: bool | None = None) -> Margins:
    """:class:`Margins` of one loop from its ``mag_db`` (dB) and unwrapped ``phase``
    (rad) on ``f_hz``, its closed-loop spectral ``radius``, the gain crossovers ``gc`` (fractional
    grid indices, :func:`_crossings` of ``mag_db``) and ``min |1 + L|`` (:func:`loop_margins` and
    :func:`loop_margins_batch` share it, so both give the same values).  ``w`` (``2 pi f_hz``), ``k``
    (the phase's branches) and ``finite`` (``phase`` all finite), when already computed for many loops."""
    if w is None:
        w = 2 * np.pi * f_hz
    pm = np.array([math.remainder(_at(phase, g) + math.pi, 2 * math.pi) for g in gc])
    wc = np.array([_at(w, g) for g in gc])
    # phase crossovers: phase = -pi (mod 2 pi), on every branch the unwrapped phase visits
    if k is None:
        k = np.round((phase + math.pi) / (2 * math.pi))
    first_gc = gc.min() if gc.size else -1.0
    if (np.all(np.isfinite(phase)) if finite is None else finite):
        has_gm, gm = _phase_crossover_gain_margin(phase, k, mag_db, float(first_gc))
    else:  # a non-finite response: the array form (np.unique sorts NaN branches out)
        pc = []
        for kk in np.unique(k):
            pc.extend(_crossings(phase + math.pi - 2 * math.pi * kk).tolist())
        gm_vals = [-_at(mag_db, c) for c in pc if c > first_gc]
        has_gm, gm = bool(gm_vals), (min(gm_vals) if gm_vals else math.inf)
    stable = radius < 1.0 + NEUTRAL_TOL
    if not gc.size:
        dm = math.inf
    elif stable:  # the extra lag that brings a crossover's phase to -180 deg
        dm = float((np.mod(pm, 2 * math.pi) / (wc * Ts)).min())
    else:  # signed: the lag that would have to be removed
        dm = -float((np.mod(-pm, 2 * math.pi) / (wc * Ts)).min())
    return Margins(gain_margin_db=float(gm) if has_gm else math.inf,
                   phase_margin_deg=float(np.degrees(pm[np.argmin(gc)])) if gc.size else math.inf,
                   delay_margin_samples=dm,
                   modulus_margin=modulus,
                   crossover_hz=float(_at(f_hz, gc.min())) if gc.size else math.nan,
                   spectral_radius=radius, stable=bool(stable))


def closed_loop_radii(ctrls: list[LinearController], realisations: list[tuple[np.ndarray, np.ndarray, np.ndarray]]
                      ) -> np.ndarray:
    """Spectral radii of the loops ``u = c`` of ``ctrls[i]`` closed on ``realisations[i]`` (a plant's
    :meth:`~commission.controllers.linear.SampledPlant.state_space`), dimensionless.

    :func:`closed_loop_radius` (``gain`` 1) of each pair, with the matrices of equal size stacked
    into one call of ``numpy.linalg.eigvals`` (which runs the same LAPACK routine on each matrix of a
    stack): a box check closes some eighty loops per gain set, and the wrapper's fixed cost per call
    was a visible share of them.
    """
    out = np.empty(len(ctrls))
    groups: dict[int, list[int]] = {}
    for i, (c, ss) in enumerate(zip(ctrls, realisations)):
        groups.setdefault(ss[0].shape[0] + c.Ac.shape[0], []).append(i)
    for size, idx in groups.items():
        A = np.zeros((len(idx), size, size))
        for j, i in enumerate(idx):
            c, (Ap, Bp, Cp) = ctrls[i], realisations[i]
            n_p = Ap.shape[0]
            A[j, :n_p, :n_p] = Ap + c.Dc * (Bp @ Cp)  # gain 1: the same entries as closed_loop_radius's
            A[j, :n_p, n_p:] = Bp @ c.Cc
            A[j, n_p:, :n_p] = c.Bc @ Cp
            A[j, n_p:, n_p:] = c.Ac
        out[idx] = np.abs(np.linalg.eigvals(A)).max(axis=1)
    return out


def loop_margins_batch(ctrl_responses: list[np.ndarray], plant_responses: list[np.ndarray], f_hz: np.ndarray,
                       Ts: float, radii: np.ndarray) -> list[Margins]:
    """:func:`loop_margins` of many loops on one grid at once, the same values to the last bit.

    Loop ``i`` is the controller with response ``ctrl_responses[i]`` (``K``, u-unit per m) on the
    plant with ``plant_responses[i]`` (``P``, m per u-unit), both on ``f_hz`` (Hz), period ``Ts``
    (s), closed-loop spectral radius ``radii[i]`` (:func:`closed_loop_radii`).  The responses,
    magnitudes, phases and crossings of all loops are computed as ``(loops, frequencies)``
    arrays, element by element as :func:`loop_margins` computes each row (the same ufuncs on
    contiguous rows; the minima are exact whatever the order), so that a box check's thirty-odd
    loops per gain set pay numpy's fixed cost per call once, not once per loop.
    """
    n, nf = len(ctrl_responses), f_hz.size
    if n == 0:
        return []
    L = np.empty((n, nf), dtype=complex)
    for i, (K, P) in enumerate(zip(ctrl_responses, plant_responses)):
        np.negative(K, out=L[i])
        np.multiply(L[i], P, out=L[i])
    mag_db = 20 * np.log10(np.maximum(np.abs(L), 1e-300))
    phase = _unwrap_rows(np.ascontiguousarray(np.angle(L)))
    modulus = np.abs(1 + L).min(axis=1)
    # gain crossovers of every row: _crossings, the sign changes found over the whole array
    rows, cols = np.nonzero(np.sign(mag_db[:, :-1]) * np.sign(mag_db[:, 1:]) < 0)
    x0, x1 = mag_db[rows, cols], mag_db[rows, cols + 1]
    gc_all = cols + x0 / (x0 - x1)
    bounds = np.searchsorted(rows, np.arange(n + 1))
    w = 2 * np.pi * f_hz
    k = np.round((phase + math.pi) / (2 * math.pi))
    finite = np.isfinite(phase).all(axis=1)
    return [_margins_of(f_hz, Ts, mag_db[i], phase[i], float(radii[i]), gc_all[bounds[i]:bounds[i + 1]],
                        float(modulus[i]), w, k[i], bool(finite[i])) for i in range(n)]
