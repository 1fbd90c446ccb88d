"""The legacy commissioning run's reference: the friction ladder's legs (:class:`Leg`), the sampled
reference (:class:`Reference`) and the plan that builds it (:class:`ExcitationPlan`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, fields
from typing import Any

import numpy as np

from commission.synth.truth import _check_finite


@dataclass(frozen=True)
class Leg:
    """One constant-velocity leg of the friction ladder.

    Attributes
    ----------
    start, stop : float
        Time window of the constant-velocity part, s.
    velocity : float
        Reference velocity, m/s (signed).
    x_start : float
        Reference position at ``start``, m.
    """

    start: float
    stop: float
    velocity: float
    x_start: float


@dataclass(frozen=True)
class Reference:
    """A sampled reference trajectory and where its parts are.

    The arrays are what the synthetic loop tracks (:func:`commission.synth.simulation.simulate_excitation`
    feeds ``q``, ``qd``, ``qdd`` forward); the windows are kept beside them so that a test can
    read each fit's segment of the log by time, without re-deriving the plan's schedule.

    Attributes
    ----------
    t : ndarray
        Sample times ``k / sample_rate``, s.
    q, qd, qdd : ndarray
        Reference position (m), velocity (m/s), acceleration (m/s^2).
    legs : tuple of Leg
        The friction-ladder legs, in time order.
    multisine : tuple of float
        ``(start, stop)`` of the multisine segment, s.
    injection : tuple of (float, float)
        ``(start, stop)`` of each constant-velocity leg that carries the broadband
        injection, s (empty without one).
    """

    t: np.ndarray
    q: np.ndarray
    qd: np.ndarray
    qdd: np.ndarray
    legs: tuple[Leg, ...]
    multisine: tuple[float, float]
    injection: tuple[tuple[float, float], ...] = ()


# A segment is (kind, t0, T, args); x0 is the position at t0.
_HOLD, _RAMP, _CRUISE, _MULTISINE = 0, 1, 2, 3


@dataclass(frozen=True)
class ExcitationPlan:
    """Design of a commissioning excitation run (reference and loop).

    The run is: dwell; friction ladder; move to the middle of the travel;
    multisine; move back to 0; dwell; and, with ``injection_s > 0``, a
    broadband injection: a leg forward and one back at ``injection_velocity``,
    each cruising ``injection_s / 2`` seconds with a PRBS added to the command
    (the way drive vendors' frequency-response tools record one: the axis
    moves slowly so that friction keeps one sign, and the feedback loop stays
    closed), then a dwell.  The travel used is ``[0, travel]``.

    Parameters
    ----------
    travel : float
        Usable stroke from the start position 0, m.
    v_min, v_max : float
        Slowest and fastest ladder speed, m/s.
    n_speeds : int
        Number of ladder speeds, spaced geometrically from ``v_min`` to ``v_max``.
    leg_travel : float
        Target travel of each constant-velocity leg, m (a few ripple pitches,
        so that fast legs average over ripple).  The leg time is
        ``clip(leg_travel / v, leg_min_time, leg_max_time)``.
    leg_min_time, leg_max_time : float
        Bounds of the constant-velocity time per leg, s.
    ladder_accel : float
        Peak acceleration of the ramps into and out of a leg, m/s^2.
    ramp_min_time : float
        Shortest ramp, s (slow legs ramp gently, not in one sample).
    dwell : float
        Standstill between legs and at both ends of the run, s.
    ms_freqs : tuple of float
        Multisine line frequencies, Hz.
    ms_duration : float
        Multisine segment length including its tapers, s.
    ms_taper : float
        Smooth fade in and out of the multisine, s.
    ms_accel : float
        Peak reference acceleration of the multisine, m/s^2.
    ms_amplitude : float
        Largest excursion of the multisine from the middle of the travel, m.
    move_accel : float
        Peak acceleration of the point-to-point moves, m/s^2.
    bandwidth_hz : float
        Design bandwidth of the PID, Hz (``Kp = M_g w^2``, ``Kd = 2 zeta M_g w``).
    damping : float
        Design damping ratio ``zeta`` of the PID.
    integral_hz : float
        Integral corner, Hz (``Ki = Kp * 2 pi integral_hz``; small, for offset and ripple).
    guess_factor : float
        The loop's rough knowledge of the axis: gains and the feedforward
        ``M_g qdd_ref + B_g qd_ref + fc_g (2/pi) atan(900 qd_ref)`` use
        ``guess_factor`` times the true M, B and fc (as a datasheet guess).
    substeps : int
        Plant sub-steps per sample (zero-order hold).
    injection_s : float
        Total cruise time carrying the broadband injection, s (0: none; the run
        and its log are then exactly those without the option).
    injection_accel : float
        Amplitude of the injected PRBS as an acceleration of the guessed mass,
        m/s^2: the command gets ``+-guess_factor M injection_accel`` (u-unit),
        one maximal-length-sequence bit per sample (flat spectrum up to Nyquist).
    injection_velocity : float
        Speed of the two injection legs, m/s.
    """

    travel: float = 0.3
    v_min: float = 0.001
    v_max: float = 0.25
    n_speeds: int = 9
    leg_travel: float = 0.06
    leg_min_time: float = 0.5
    leg_max_time: float = 1.5
    ladder_accel: float = 2.0
    ramp_min_time: float = 0.1
    dwell: float = 0.15
    ms_freqs: tuple[float, ...] = (1.0, 2.0, 3.0, 5.0, 8.0, 13.0, 20.0)
    ms_duration: float = 12.0
    ms_taper: float = 0.5
    ms_accel: float = 20.0
    ms_amplitude: float = 0.04
    move_accel: float = 4.0
    bandwidth_hz: float = 40.0
    damping: float = 0.8
    integral_hz: float = 4.0
    guess_factor: float = 0.8
    substeps: int = 10
    injection_s: float = 0.0
    injection_accel: float = 20.0
    injection_velocity: float = 0.1

    def __post_init__(self) -> None:
        nums = {f.name: getattr(self, f.name) for f in fields(self) if f.name != "ms_freqs"}
        _check_finite("ExcitationPlan", **nums)
        for name in ("travel", "v_min", "leg_travel", "leg_min_time", "ladder_accel",
                     "ms_duration", "ms_accel", "ms_amplitude", "move_accel",
                     "bandwidth_hz", "damping", "guess_factor"):
            if not getattr(self, name) > 0:
                raise ValueError(f"ExcitationPlan: {name} must be > 0, got {getattr(self, name)!r}")
        for name in ("injection_accel", "injection_velocity"):
            if not getattr(self, name) > 0:
                raise ValueError(f"ExcitationPlan: {name} must be > 0, got {getattr(self, name)!r}")
        for name in ("ramp_min_time", "dwell", "integral_hz", "ms_taper", "injection_s"):
            if getattr(self, name) < 0:
                raise ValueError(f"ExcitationPlan: {name} must be >= 0, got {getattr(self, name)!r}")
        if self.v_max < self.v_min:
            raise ValueError(f"ExcitationPlan: v_max={self.v_max} < v_min={self.v_min}")
        if self.leg_max_time < self.leg_min_time:
            raise ValueError(f"ExcitationPlan: leg_max_time={self.leg_max_time} < leg_min_time={self.leg_min_time}")
        if int(self.n_speeds) != self.n_speeds or self.n_speeds < 1:
            raise ValueError(f"ExcitationPlan: n_speeds must be a positive integer, got {self.n_speeds!r}")
        if int(self.substeps) != self.substeps or self.substeps < 1:
            raise ValueError(f"ExcitationPlan: substeps must be a positive integer, got {self.substeps!r}")
        freqs = np.asarray(self.ms_freqs, dtype=float)
        if freqs.ndim != 1 or freqs.size == 0 or not np.all(np.isfinite(freqs)) or np.any(freqs <= 0):
            raise ValueError(f"ExcitationPlan: ms_freqs must be positive frequencies, got {self.ms_freqs!r}")
        if 2 * self.ms_taper > self.ms_duration:
            raise ValueError(f"ExcitationPlan: 2 * ms_taper = {2 * self.ms_taper} exceeds ms_duration = {self.ms_duration}")
        if 2 * self.ms_amplitude > self.travel:
            raise ValueError(f"ExcitationPlan: 2 * ms_amplitude = {2 * self.ms_amplitude} exceeds travel = {self.travel}")
        object.__setattr__(self, "ms_freqs", tuple(float(f) for f in freqs))
        # Derived, not fields: the piecewise reference (segments), legs, multisine window.
        object.__setattr__(self, "_segments", self._build_segments())

    # -- design ------------------------------------------------------------

    @property
    def speeds(self) -> np.ndarray:
        """Ladder speeds, m/s (geometric from ``v_min`` to ``v_max``)."""
        return np.geomspace(self.v_min, self.v_max, int(self.n_speeds))

    @property
    def duration(self) -> float:
        """Length of the whole run, s."""
        kind, t0, T, _ = self._segments[-1]
        return t0 + T

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready form of the plan fields."""
        d = {f.name: getattr(self, f.name) for f in fields(self)}
        d["ms_freqs"] = list(self.ms_freqs)
        return d

    def _ramp_time(self, dv: float, accel: float) -> float:
        # Cosine velocity blend: peak acceleration = pi |dv| / (2 T).
        return max(self.ramp_min_time, math.pi * abs(dv) / (2.0 * accel))

    def _build_segments(self) -> tuple:
        segs: list[tuple] = []
        t = 0.0
        x = 0.0

        def add(kind: int, T: float, args: tuple) -> None:
            nonlocal t, x
            segs.append((kind, t, T, (x,) + args))
            if kind == _RAMP:
                v0, v1 = args
                x += v0 * T + (v1 - v0) * T / 2.0
            elif kind == _CRUISE:
                x += args[0] * T
            t += T

        def move(x_to: float) -> None:
            # Rest-to-rest cosine-velocity move of distance D: peak velocity D / Tr.
            D = x_to - x
            if D == 0.0:
                return
            Tr = max(self.ramp_min_time, math.sqrt(math.pi * abs(D) / (2.0 * self.move_accel)))
            vm = D / Tr
            if abs(vm) > self.v_max:  # cap the speed, cruise the rest
                vm = math.copysign(self.v_max, D)
                Tr = self._ramp_time(vm, self.move_accel)
                add(_RAMP, Tr, (0.0, vm))
                add(_CRUISE, (x_to - x - vm * Tr / 2.0) / vm, (vm,))
                add(_RAMP, Tr, (vm, 0.0))
            else:
                add(_RAMP, Tr, (0.0, vm))
                add(_RAMP, Tr, (vm, 0.0))

        legs: list[Leg] = []
        if self.dwell > 0:
            add(_HOLD, self.dwell, ())
        for v in self.speeds:
            v = float(v)
            Tr = self._ramp_time(v, self.ladder_accel)
            Tc = min(max(self.leg_travel / v, self.leg_min_time), self.leg_max_time)
            room = self.travel / v - Tr  # the two ramps cover v * Tr together
            if Tc > room:
                if room < self.leg_min_time:
                    raise ValueError(
                        f"ExcitationPlan: ladder speed {v:.6g} m/s needs "
                        f"{v * (Tr + self.leg_min_time):.6g} m of travel for a {self.leg_min_time} s leg; "
                        f"travel is {self.travel} m")
                Tc = room
            for s in (1.0, -1.0):
                add(_RAMP, Tr, (0.0, s * v))
                legs.append(Leg(start=t, stop=t + Tc, velocity=s * v, x_start=x))
                add(_CRUISE, Tc, (s * v,))
                add(_RAMP, Tr, (s * v, 0.0))
                if self.dwell > 0:
                    add(_HOLD, self.dwell, ())
            x = 0.0  # the pair returns exactly to 0; drop round-off
        centre = self.travel / 2.0
        move(centre)
        if self.dwell > 0:
            add(_HOLD, self.dwell, ())
        ms_start = t
        add(_MULTISINE, self.ms_duration, (self._multisine_scale(),))
        ms_stop = t
        if self.dwell > 0:
            add(_HOLD, self.dwell, ())
        move(0.0)
        if self.dwell > 0:
            add(_HOLD, self.dwell, ())
        injection: list[tuple[float, float]] = []
        if self.injection_s > 0:
            v = self.injection_velocity
            Tr = self._ramp_time(v, self.ladder_accel)
            Tc = self.injection_s / 2.0
            if v * (Tr + Tc) > self.travel:
                raise ValueError(f"ExcitationPlan: the injection legs need {v * (Tr + Tc):.6g} m of travel "
                                 f"(injection_velocity {v} m/s for injection_s / 2 = {Tc} s); travel is {self.travel} m")
            for sgn in (1.0, -1.0):
                add(_RAMP, Tr, (0.0, sgn * v))
                injection.append((t, t + Tc))
                add(_CRUISE, Tc, (sgn * v,))
                add(_RAMP, Tr, (sgn * v, 0.0))
                add(_HOLD, max(self.dwell, 1e-3), ())
        object.__setattr__(self, "_injection", tuple(injection))
        object.__setattr__(self, "_legs", tuple(legs))
        object.__setattr__(self, "_ms_window", (ms_start, ms_stop))
        return tuple(segs)

    # -- multisine ---------------------------------------------------------

    def _multisine_unit(self, tau: np.ndarray, scale: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Tapered multisine (excursion, velocity, acceleration) at local times ``tau``.

        Lines have equal velocity amplitude ``scale`` (m/s) and Schroeder
        phases (low crest factor, deterministic).
        """
        f = np.asarray(self.ms_freqs)
        K = f.size
        k = np.arange(1, K + 1)
        phi = -np.pi * k * (k - 1) / K
        w = 2.0 * np.pi * f
        A = scale / w
        arg = np.multiply.outer(tau, w) + phi
        S, C = np.sin(arg), np.cos(arg)
        s = S @ A
        sd = C @ (A * w)
        sdd = -(S @ (A * w * w))
        # Quintic fade (zero slope and curvature at both ends) keeps q_ref C2.
        T, Tt = self.ms_duration, self.ms_taper
        env = np.ones_like(tau)
        denv = np.zeros_like(tau)
        ddenv = np.zeros_like(tau)
        if Tt > 0:
            for mask, r, sgn in ((tau < Tt, tau / Tt, 1.0), (tau > T - Tt, (T - tau) / Tt, -1.0)):
                r = np.clip(r[mask], 0.0, 1.0)
                env[mask] = r**3 * (10 - 15 * r + 6 * r**2)
                denv[mask] = sgn * 30 * r**2 * (1 - r) ** 2 / Tt
                ddenv[mask] = (60 * r - 180 * r**2 + 120 * r**3) / Tt**2
        x = env * s
        v = denv * s + env * sd
        a = ddenv * s + 2 * denv * sd + env * sdd
        return x, v, a

    def _multisine_scale(self) -> float:
        # Scale so the peak acceleration is ms_accel and the excursion at most
        # ms_amplitude, on a fixed 10 kHz grid (independent of the sample rate).
        tau = np.arange(0.0, self.ms_duration, 1e-4)
        x, v, a = self._multisine_unit(tau, 1.0)
        return min(self.ms_accel / np.max(np.abs(a)), self.ms_amplitude / np.max(np.abs(x)))

    # -- sampling ----------------------------------------------------------

    def reference(self, sample_rate: float) -> Reference:
        """Sample the reference on ``t = k / sample_rate``, ``k = 0 .. floor(duration * rate)``.

        Parameters
        ----------
        sample_rate : float
            Hz.

        Returns
        -------
        Reference
        """
        if not (math.isfinite(sample_rate) and sample_rate > 0):
            raise ValueError(f"reference: sample_rate must be > 0, got {sample_rate!r}")
        n = int(math.floor(self.duration * sample_rate + 1e-9)) + 1
        t = np.arange(n) / sample_rate
        q = np.zeros(n)
        qd = np.zeros(n)
        qdd = np.zeros(n)
        edges = np.array([s[1] for s in self._segments] + [np.inf])
        idx = np.searchsorted(edges, t, side="right") - 1
        idx = np.clip(idx, 0, len(self._segments) - 1)
        for i, (kind, t0, T, args) in enumerate(self._segments):
            m = idx == i
            if not np.any(m):
                continue
            tau = np.minimum(t[m] - t0, T)
            x0 = args[0]
            if kind == _HOLD:
                q[m] = x0
            elif kind == _CRUISE:
                vv = args[1]
                q[m] = x0 + vv * tau
                qd[m] = vv
            elif kind == _RAMP:
                v0, v1 = args[1], args[2]
                dv = v1 - v0
                r = np.pi * tau / T
                q[m] = x0 + v0 * tau + dv * (tau / 2.0 - T / (2.0 * np.pi) * np.sin(r))
                qd[m] = v0 + dv * (1.0 - np.cos(r)) / 2.0
                qdd[m] = dv * np.pi / (2.0 * T) * np.sin(r)
            else:
                xs, vs_, as_ = self._multisine_unit(tau, args[1])
                q[m], qd[m], qdd[m] = x0 + xs, vs_, as_
        return Reference(t=t, q=q, qd=qd, qdd=qdd, legs=self._legs, multisine=self._ms_window,
                         injection=self._injection)

    def injection_signal(self, t: np.ndarray) -> np.ndarray:
        """Unit PRBS (+-1) on the injection legs and 0 elsewhere, at the sample times ``t`` (s).

        One bit per sample of a maximal-length sequence (``scipy.signal.max_len_seq``,
        deterministic), continued from one leg to the next.
        """
        from scipy.signal import max_len_seq

        out = np.zeros(t.size)
        masks = [(t >= a) & (t < b) for a, b in self._injection]
        n = sum(int(np.count_nonzero(m)) for m in masks)
        if n == 0:
            return out
        bits = max_len_seq(max(int(math.ceil(math.log2(n + 1))), 4))[0][:n]
        seq = 2.0 * bits.astype(float) - 1.0
        i = 0
        for m in masks:
            k = int(np.count_nonzero(m))
            out[m] = seq[i:i + k]
            i += k
        return out
