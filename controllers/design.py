"""Gain-design numerics of the output-feedback ARC (Xu & Yao 2001, §3) and its checks.

* :func:`observer_design` -- the observer matrix A0 (10) with a double pole at
  -p: k1 = 2p, k2 = p^2 (the paper: -200 -> 400, 4e4), and the s.p.d.
  solution P of the Lyapunov equation (11) P A0 + A0^T P = -I.
* :func:`theorem1_check` -- the condition of Theorem 1,
  ``c_phi_kr^2 >= w_k w2 / (2 c_theta2_r^2)`` for k = 1, 2 and r = 1..3.
* :func:`discrete_feasibility` -- a numerical check that the *sampled*
  closed loop is stable with margin over the whole theta box.  For each of the
  8 corners of the box the plant is the linear part of the model
  (M = 1/theta1, B = theta2 M, offset = -theta3 M; Coulomb/Stribeck friction,
  ripple, quantization, the output limit and every sign nonlinearity excluded), discretised
  exactly under zero-order hold.  The loop (plant + controller, adaptation on)
  is run along each reference trajectory; at a few points along it the
  one-step map ``(x, v, controller state) -> next`` is linearised by central
  differences.  The theta3 adaptation is part of the linearised state (it is
  the loop's integral action); theta_hat1 and theta_hat2 are frozen at the
  value the run reached there (their regressors vanish at rest, so their modes
  are neutral).  Optionally (``estimate_corners``) theta_hat is also set to
  each of the 8 corners of the box, since the loop gain depends on the
  *estimate* theta_hat1: a stricter, robust version.  The check passes when
  every radius with all estimates frozen is below ``1 - margin`` and every
  radius with the theta3 adaptation in the loop is below 1 (that integral
  mode is slow by design, so no margin is asked of it).  The PID's friction compensation
  F_hat(dq) of (57), a smoothed sign of the measured velocity, is excluded
  with the friction it compensates.

Nothing here imports the pipeline layer: inputs are plain numbers, packed
controller vectors and trajectories.
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass

import numpy as np
from numba import njit
from scipy.linalg import expm, solve_continuous_lyapunov

from commission.controllers import arc as _arc
from commission.controllers import pid as _pid
from commission.controllers.trajectory import Trajectory

KIND_PID = 0
KIND_ARC = 1

#: Controller-state entries that carry dynamics (perturbed in the Jacobian).
#: ARC: eta (2), lambda (2), psi (2), y_prev, u*_prev and theta_hat3, whose adaptation
#: is driven by psi_2 -> k1/k2 != 0 even at rest and acts as the loop's integrator;
#: theta_hat1 and theta_hat2 are frozen (their regressors vanish at rest: neutral modes).
ARC_DYNAMIC_STATES = (_arc.S_ETA, _arc.S_ETA + 1, _arc.S_LAMBDA, _arc.S_LAMBDA + 1,
                      _arc.S_PSI, _arc.S_PSI + 1, _arc.S_YPREV, _arc.S_USPREV, _arc.S_THETA + 2)
#: How many trailing entries of ARC_DYNAMIC_STATES are adaptation states.
ARC_ADAPTATION_STATES = 1
PID_DYNAMIC_STATES = (_pid.S_YPREV, _pid.S_INT)


def _radius(J: np.ndarray) -> float:
    return float(np.max(np.abs(np.linalg.eigvals(J)))) if J.size else 0.0


class DesignError(ValueError):
    """A design input (pole, gain, box) is out of its admissible range."""


# --------------------------------------------------------------------------- observer


@dataclass(frozen=True)
class ObserverDesign:
    """Observer gains of (10) and the Lyapunov matrix of (11).

    Attributes
    ----------
    pole : float
        Magnitude p of the double observer pole -p, rad/s.
    k1 : float
        2p, 1/s.
    k2 : float
        p^2, 1/s^2.
    P : tuple of tuple of float
        2x2 s.p.d. solution of P A0 + A0^T P = -I, s (rows).
    P_eigenvalues : tuple of float
        Eigenvalues of P (ascending), all > 0.
    lyapunov_residual : float
        max |P A0 + A0^T P + I|, a check on the solve.
    discrete_pole : float
        exp(-p Ts) of the exactly sampled filters (double), or NaN when no Ts given.
    """

    pole: float
    k1: float
    k2: float
    P: tuple[tuple[float, float], tuple[float, float]]
    P_eigenvalues: tuple[float, float]
    lyapunov_residual: float
    discrete_pole: float


def observer_matrix(k1: float, k2: float) -> np.ndarray:
    """A0 of (10): [[-k1, 1], [-k2, 0]]."""
    return np.array([[-k1, 1.0], [-k2, 0.0]])


def lyapunov_P(k1: float, k2: float) -> np.ndarray:
    """The s.p.d. P of (11): P A0 + A0^T P = -I (scipy's continuous Lyapunov solver).

    Raises
    ------
    DesignError
        A0 is not Hurwitz (k1 <= 0 or k2 <= 0), so no s.p.d. P exists.
    """
    if not (k1 > 0 and k2 > 0 and math.isfinite(k1) and math.isfinite(k2)):
        raise DesignError(f"observer gains k1={k1}, k2={k2}: A0 is Hurwitz only for k1 > 0, k2 > 0")
    A0 = observer_matrix(k1, k2)
    # solve_continuous_lyapunov(a, q) solves a X + X a^T = q; with a = A0^T: A0^T P + P A0 = -I.
    P = solve_continuous_lyapunov(A0.T, -np.eye(2))
    return 0.5 * (P + P.T)


def observer_design(pole: float, Ts: float | None = None) -> ObserverDesign:
    """Double observer pole at -``pole`` (rad/s): k1 = 2 pole, k2 = pole^2, and P of (11).

    Parameters
    ----------
    pole : float
        Pole magnitude p > 0, rad/s (paper: 200).
    Ts : float, optional
        Sample period, s, to report the sampled pole exp(-p Ts).
    """
    if not (pole > 0 and math.isfinite(pole)):
        raise DesignError(f"observer pole: must be a positive number of rad/s, got {pole}")
    k1, k2 = 2.0 * pole, pole * pole
    P = lyapunov_P(k1, k2)
    A0 = observer_matrix(k1, k2)
    res = float(np.max(np.abs(P @ A0 + A0.T @ P + np.eye(2))))
    ev = np.linalg.eigvalsh(P)
    if not ev[0] > 0:
        raise DesignError(f"observer pole {pole}: Lyapunov P is not positive definite (eigenvalues {ev})")
    return ObserverDesign(pole=float(pole), k1=k1, k2=k2,
                          P=((float(P[0, 0]), float(P[0, 1])), (float(P[1, 0]), float(P[1, 1]))),
                          P_eigenvalues=(float(ev[0]), float(ev[1])), lyapunov_residual=res,
                          discrete_pole=math.exp(-pole * Ts) if Ts else math.nan)


# --------------------------------------------------------------------------- Theorem 1


@dataclass(frozen=True)
class Theorem1Check:
    """The condition of Theorem 1: c_phi_kr^2 >= w_k w2 / (2 c_theta2_r^2), k = 1, 2, r = 1..3.

    Attributes
    ----------
    holds : bool
        Every one of the six inequalities holds.
    ratios : tuple of tuple of float
        ``ratios[k-1][r-1] = c_phi_kr^2 / (w_k w2 / (2 c_theta2_r^2))``, >= 1 where it holds
        (0 when c_theta2_r = 0: the condition cannot hold).
    min_ratio : float
        Smallest ratio.
    """

    holds: bool
    ratios: tuple[tuple[float, float, float], tuple[float, float, float]]
    min_ratio: float


def theorem1_check(w1: float, w2: float, C_phi1, C_phi2, C_theta2) -> Theorem1Check:
    """Check the Theorem-1 condition on diagonal C_phi1, C_phi2, C_theta2 (3 entries each)."""
    ratios = []
    for w_k, C_phi in ((w1, C_phi1), (w2, C_phi2)):
        row = []
        for r in range(3):
            ct = float(C_theta2[r])
            need = w_k * w2 / (2.0 * ct * ct) if ct > 0 else math.inf
            have = float(C_phi[r]) ** 2
            row.append(math.inf if need == 0 else (have / need if math.isfinite(need) else 0.0))
        ratios.append(tuple(row))
    mr = min(min(r) for r in ratios)
    return Theorem1Check(holds=bool(mr >= 1.0), ratios=(ratios[0], ratios[1]), min_ratio=mr)  # type: ignore[arg-type]


def theta2_for_theorem1(w1: float, w2: float, C_phi1, C_phi2, factor: float = 2.0) -> tuple[float, float, float]:
    """Smallest C_theta2 diagonal meeting Theorem 1, times ``factor`` (>= 1) on c_theta2_r^2.

    c_theta2_r^2 >= max_k w_k w2 / (2 c_phi_kr^2).
    """
    out = []
    for r in range(3):
        need = max(w1 * w2 / (2.0 * float(C_phi1[r]) ** 2), w2 * w2 / (2.0 * float(C_phi2[r]) ** 2))
        out.append(math.sqrt(factor * need))
    return (out[0], out[1], out[2])


# --------------------------------------------------------------------------- discrete feasibility


def zoh_plant(M: float, B: float, Ts: float) -> tuple[np.ndarray, np.ndarray]:
    """Exact ZOH discretisation of M qdd = u - B qd: ``[x, v]+ = Phi [x, v] + Gam u``.

    Parameters
    ----------
    M, B : float
        The rigid body's mass, u-unit s^2/m, and viscous coefficient, u-unit s/m.
    Ts : float
        Sample period of the hold, s.
    """
    F = np.zeros((3, 3))
    F[0, 1] = 1.0
    F[1, 1] = -B / M
    F[1, 2] = 1.0 / M
    E = expm(F * Ts)
    return E[:2, :2].copy(), E[:2, 2].copy()


def theta_corners(theta_min, theta_max) -> np.ndarray:
    """The 8 corners of the box, shape (8, 3), in binary order (min, min, min) first."""
    lo, hi = np.asarray(theta_min, float), np.asarray(theta_max, float)
    return np.array([[hi[i] if b[i] else lo[i] for i in range(3)]
                     for b in itertools.product((0, 1), repeat=3)])


@njit(cache=True)
def _ctrl_step(kind, p, s, y, qd, dqd, ddqd):
    if kind == 0:
        return _pid.pid_step(p, s, y, qd, dqd, ddqd)
    return _arc.arc_step(p, s, y, qd, dqd, ddqd)


@njit(cache=True)
def _ctrl_reset(kind, p, s, y0):
    if kind == 0:
        _pid.pid_reset(p, s, y0)
    else:
        _arc.arc_reset(p, s, y0)


@njit(cache=True)
def _one_step(kind, p, s, x, v, qd, dqd, ddqd, phi, gam, offset, u_sat):
    """One sample of the linear loop; ``s`` is updated in place; returns (x, v, u)."""
    u = _ctrl_step(kind, p, s, x, qd, dqd, ddqd)
    if u > u_sat:
        u = u_sat
    elif u < -u_sat:
        u = -u_sat
    f = u - offset
    xn = phi[0, 0] * x + phi[0, 1] * v + gam[0] * f
    vn = phi[1, 0] * x + phi[1, 1] * v + gam[1] * f
    return xn, vn, u


@njit(cache=True)
def _run_to(kind, p, s, qd, dqd, ddqd, phi, gam, offset, u_sat, y0, stops, xs, vs, ss):
    """Run the linear loop from rest at y0; store (x, v, state) before sample ``stops[j]``.

    Returns the number of stops reached (fewer if the loop blew up).
    """
    x = y0
    v = 0.0
    _ctrl_reset(kind, p, s, y0)
    j = 0
    n = qd.shape[0]
    for k in range(n):
        while j < stops.shape[0] and stops[j] == k:
            xs[j] = x
            vs[j] = v
            for i in range(s.shape[0]):
                ss[j, i] = s[i]
            j += 1
        if j >= stops.shape[0]:
            return j
        x, v, _u = _one_step(kind, p, s, x, v, qd[k], dqd[k], ddqd[k], phi, gam, offset, u_sat)
        if not (math.isfinite(x) and math.isfinite(v)) or abs(x) > 1e6:
            return j
    return j


def loop_jacobian(kind: int, p: np.ndarray, s: np.ndarray, x: float, v: float, qd: float, dqd: float,
                  ddqd: float, phi: np.ndarray, gam: np.ndarray, offset: float, u_sat: float,
                  dyn: tuple[int, ...]) -> np.ndarray:
    """Central-difference Jacobian of the one-step map of plant + controller.

    The map takes ``z = [x, v, s[dyn]]`` (m, m/s, controller states) at one
    sample to the same at the next; every other controller entry (theta_hat,
    logged outputs) is held at its value in ``s``.

    Returns
    -------
    numpy.ndarray
        (2 + len(dyn)) square matrix.
    """
    n = 2 + len(dyn)
    z0 = np.concatenate(([x, v], s[list(dyn)]))
    J = np.empty((n, n))

    def f(z: np.ndarray) -> np.ndarray:
        st = s.copy()
        st[list(dyn)] = z[2:]
        xn, vn, _u = _one_step(kind, p, st, z[0], z[1], qd, dqd, ddqd, phi, gam, offset, u_sat)
        return np.concatenate(([xn, vn], st[list(dyn)]))

    for i in range(n):
        h = 1e-7 * max(abs(z0[i]), 1e-5)
        zp, zm = z0.copy(), z0.copy()
        zp[i] += h
        zm[i] -= h
        J[:, i] = (f(zp) - f(zm)) / (2.0 * h)
    return J


@dataclass(frozen=True)
class FeasibilityPoint:
    """Spectral radii of the linearised loop at one corner and one point of one trajectory.

    Attributes
    ----------
    corner : tuple of 3 float
        theta of the plant at the corner.
    trajectory : int
        Index of the trajectory in the list passed to :func:`discrete_feasibility`.
    t : float
        Time of the linearisation point, s.
    rho : float
        Spectral radius with every estimate frozen (``inf`` if the nominal run blew
        up before reaching the point); for the ARC the largest over the theta_hat tried.
    rho_adaptive : float
        The same with the theta3 adaptation in the loop (= ``rho`` for the PID).
    """

    corner: tuple[float, float, float]
    trajectory: int
    t: float
    rho: float
    rho_adaptive: float


@dataclass(frozen=True)
class FeasibilityReport:
    """Result of :func:`discrete_feasibility`.

    The verdict and its evidence together: the worst points say where along which
    trajectory the loop came closest to instability, which is what a failed check
    must show to be acted on.

    Attributes
    ----------
    holds : bool
        Every frozen-estimate radius < 1 - margin and every adaptive radius < 1.
    margin : float
        Required margin of the frozen-estimate loop's spectral radius below 1, -.
    rho_max : float
        Largest frozen-estimate spectral radius found, -.
    worst : FeasibilityPoint
        Where it was found.
    rho_adaptive_max : float
        Largest radius with the theta3 adaptation in the loop, - (its integral mode is
        slow by design, so only < 1 is required).
    worst_adaptive : FeasibilityPoint
        Where that was found.
    points : tuple of FeasibilityPoint
        Every point checked.
    """

    holds: bool
    margin: float
    rho_max: float
    worst: FeasibilityPoint
    rho_adaptive_max: float
    worst_adaptive: FeasibilityPoint
    points: tuple[FeasibilityPoint, ...]


def _stops(traj: Trajectory, n_points: int) -> np.ndarray:
    """Sample indexes to linearise at: peak |dqd|, peak |ddqd|, and evenly spread points (k >= 1)."""
    n = traj.n
    ks = {int(np.argmax(np.abs(traj.dqd))), int(np.argmax(np.abs(traj.ddqd)))}
    extra = max(n_points - 2, 1)
    ks.update(int(k) for k in np.linspace(1, n - 1, extra + 2)[1:-1])
    return np.array(sorted(max(k, 1) for k in ks), dtype=np.int64)


def discrete_feasibility(kind: int, p: np.ndarray, theta_min, theta_max, trajectories: list[Trajectory], *,
                         margin: float = 0.01, n_points: int = 3, y0: float = 0.0,
                         estimate_corners: bool = False) -> FeasibilityReport:
    """Stability with margin of the sampled loop, linearised, at the 8 corners of the theta box.

    Parameters
    ----------
    kind : int
        0 PID (``p`` from ``pid_pack``), 1 ARC (``arc_pack``).
    p : numpy.ndarray
        Packed controller; its sample period is the trajectories'.
    theta_min, theta_max : array_like of 3 float
        The box: theta1 = 1/M (m/(u-unit s^2)), theta2 = B/M (1/s), theta3 = d_n/M (m/s^2).
    trajectories : list of Trajectory
        Reference motions to linearise along.
    margin : float
        Required margin: every spectral radius < 1 - margin.
    n_points : int
        Linearisation points per trajectory (peak speed, peak acceleration, spread).
    estimate_corners : bool
        ARC: also linearise with theta_hat at each of the 8 box corners (the
        radius reported for a point is the largest over the estimates).
    y0 : float
        Start position, m.

    Returns
    -------
    FeasibilityReport
    """
    if not 0 < margin < 1:
        raise DesignError(f"margin: must be in (0, 1), got {margin}")
    p = np.array(p, dtype=np.float64)
    # Linear analysis: the output limit is a large-signal effect (a saturated loop is
    # open, and the plant's integrator then shows as an eigenvalue at 1); excluded.
    p[_arc.P_UMAX if kind == KIND_ARC else _pid.G_UMAX] = math.inf
    if kind == KIND_PID:
        # F_hat(dq) of (57) is a smoothed sign of the measured velocity: excluded with
        # the Coulomb friction it compensates (ARC's F_hat(dq_d) depends on the reference only).
        p[_pid.G_FLEVEL] = 0.0
    dyn = ARC_DYNAMIC_STATES if kind == KIND_ARC else PID_DYNAMIC_STATES
    n_adapt = ARC_ADAPTATION_STATES if kind == KIND_ARC else 0
    new_state = _arc.arc_new_state if kind == KIND_ARC else _pid.pid_new_state
    # ARC: linearise with the estimate the run reached and with theta_hat at each box corner.
    estimates: list[np.ndarray | None] = [None]
    if kind == KIND_ARC and estimate_corners:
        estimates += list(theta_corners(theta_min, theta_max))
    pts: list[FeasibilityPoint] = []
    for th in theta_corners(theta_min, theta_max):
        M = 1.0 / th[0]
        B = th[1] * M
        offset = -th[2] * M
        for j, traj in enumerate(trajectories):
            phi, gam = zoh_plant(M, B, traj.Ts)
            stops = _stops(traj, n_points)
            s = new_state(p)
            xs, vs_ = np.zeros(len(stops)), np.zeros(len(stops))
            ss = np.zeros((len(stops), s.shape[0]))
            reached = _run_to(kind, p, s, traj.qd, traj.dqd, traj.ddqd, phi, gam, offset, math.inf,
                              float(y0), stops, xs, vs_, ss)
            corner = (float(th[0]), float(th[1]), float(th[2]))
            for i, k in enumerate(stops):
                if i >= reached:
                    pts.append(FeasibilityPoint(corner, j, float(traj.t[k]), math.inf, math.inf))
                    continue
                rho, rho_a = 0.0, 0.0
                for est in estimates:
                    st = ss[i].copy()
                    if est is not None:
                        st[_arc.S_THETA:_arc.S_THETA + 3] = est
                    J = loop_jacobian(kind, p, st, xs[i], vs_[i], traj.qd[k], traj.dqd[k], traj.ddqd[k],
                                      phi, gam, offset, math.inf, dyn)
                    if not np.all(np.isfinite(J)):
                        rho = rho_a = math.inf
                        break
                    rho_a = max(rho_a, _radius(J))
                    # frozen estimates: drop the adaptation states (last n_adapt rows and columns)
                    rho = max(rho, _radius(J[:J.shape[0] - n_adapt, :J.shape[0] - n_adapt]))
                pts.append(FeasibilityPoint(corner, j, float(traj.t[k]), rho, rho_a))
    worst = max(pts, key=lambda q: q.rho)
    worst_a = max(pts, key=lambda q: q.rho_adaptive)
    return FeasibilityReport(holds=bool(worst.rho < 1.0 - margin and worst_a.rho_adaptive < 1.0),
                             margin=float(margin), rho_max=worst.rho, worst=worst,
                             rho_adaptive_max=worst_a.rho_adaptive, worst_adaptive=worst_a, points=tuple(pts))
