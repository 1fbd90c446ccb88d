"""The band a recording of the plan will back, predicted before the machine time is spent."""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any, Mapping

import numpy as np

from commission.excite.limits import ExciteSpec
from commission.excite.plan import Plan, loop_gains_for, mass_bracket
from commission.excite.plan_files import injection_ranges
from commission.identify.frf.settings import MEASURABLE_SNR

#: Encoder assumed when ``[axis] encoder_step`` is not given: a 1 um (or 1 urad) scale, q-unit.
ASSUMED_ENCODER_STEP = 1e-6
#: The target band is this many times ``[evidence] first_mode_hz`` (must show 1 of issue 31).
MODE_BAND_FACTOR = 1.5


@dataclass(frozen=True)
class BandPrediction:
    """The band a recording of the plan is expected to back, before it is run (:func:`predict_band`).

    The prediction runs identify's own band rule on an expected coherence (the plan's
    injection against the encoder floor through the rigid model), so that a plan too short
    or too weak for its target is said before machine time is spent on it.

    Attributes
    ----------
    f_hz : ndarray
        identify's analysis bins over the injection windows, Hz.
    coherence : ndarray
        Expected coherence u -> q per bin (1).
    band_hz : (float, float) or None
        The band of :func:`commission.identify.frf.backed_band` on the expected coherence, Hz.
    n_averages : int
        Welch windows identify will average.
    resolution_hz : float
        Bin spacing, Hz.
    mass : float
        Mass of the rigid model predicted on, u s^2/q.
    encoder_step, encoder_noise : float
        The encoder floor used, q-unit (step, rms noise).
    step_given, noise_given : bool
        ``[axis] encoder_step`` / ``encoder_noise`` was given (False: the assumed value).
    floor_psd : float
        One-sided density of the floor, q^2/Hz.
    target_hz : float or None
        The band's top that is needed, Hz (None: no target set).
    target_source : str or None
        What set it: ``"evidence.band_hz"`` or ``"1.5 x evidence.first_mode_hz"``.
    remedies : mapping
        When the band misses the target: what would reach it (:func:`predict_band`); empty
        otherwise.
    """

    f_hz: np.ndarray
    coherence: np.ndarray
    band_hz: tuple[float, float] | None
    n_averages: int
    resolution_hz: float
    mass: float
    encoder_step: float
    encoder_noise: float
    step_given: bool
    noise_given: bool
    floor_psd: float
    target_hz: float | None = None
    target_source: str | None = None
    remedies: Mapping[str, Any] = field(default_factory=dict)

    @property
    def top_hz(self) -> float:
        """Top of the predicted band, Hz (0: none)."""
        return float(self.band_hz[1]) if self.band_hz is not None else 0.0

    @property
    def short(self) -> bool:
        """The predicted band falls short of the target."""
        return self.target_hz is not None and self.top_hz < self.target_hz

    def to_dict(self, q_unit: str, u_unit: str) -> dict[str, Any]:
        """plan.json's ``predicted_band`` (additive key)."""
        return {
            "band_hz": list(self.band_hz) if self.band_hz is not None else None,
            "target_hz": self.target_hz, "target_source": self.target_source, "short": self.short,
            "n_averages": int(self.n_averages), "resolution_hz": self.resolution_hz, "mass": self.mass,
            "encoder_step": self.encoder_step, "encoder_noise": self.encoder_noise,
            "encoder_step_assumed": not self.step_given, "encoder_noise_assumed": not self.noise_given,
            "floor_psd": self.floor_psd, "remedies": dict(self.remedies),
            "rule": "expected coherence of the closed-loop H1 estimate >= BAND_COHERENCE (identify's band rule, "
                    "commission.identify.frf.backed_band) on the rigid model of [axis] mass",
            "units": {"band_hz": "Hz", "target_hz": "Hz", "resolution_hz": "Hz", "mass": f"{u_unit} s^2/{q_unit}",
                      "encoder_step": q_unit, "encoder_noise": f"{q_unit} rms", "floor_psd": f"{q_unit}^2/Hz"},
        }


def _nominal_mass(spec: ExciteSpec) -> float:
    if spec.mass is not None:
        return float(spec.mass)
    light, heavy = mass_bracket(spec)
    return math.sqrt(light * heavy)


def _injection_psd(plan: Plan) -> tuple[np.ndarray, np.ndarray, int]:
    """identify's bins, the injection's one-sided density on them (u^2/Hz) and the number of windows."""
    from scipy import signal

    from commission.identify.frf import RESOLUTION_HZ

    fs = plan.spec.sample_rate
    ranges = injection_ranges({"segments": [g.to_dict() for g in plan.segments]}, plan.t)
    nper = int(round(fs / RESOLUTION_HZ))
    while nper > 32 and sum(max(0, 1 + ((b - a) - nper) // (nper - nper // 2)) for a, b in ranges) < 8:
        nper //= 2  # as identify.frf.frequency_response: at least 8 windows in all
    step = nper - nper // 2
    acc, n_avg, f = 0.0, 0, None
    for a, b in ranges:
        if b - a < nper:
            continue
        k = 1 + (b - a - nper) // step
        f, p = signal.welch(plan.u_inject[a:b], fs=fs, window="hann", nperseg=nper, noverlap=nper // 2,
                            detrend="linear")
        acc = acc + k * p
        n_avg += k
    if f is None:
        return np.zeros(0), np.zeros(0), 0
    keep = (f > 0) & (f < fs / 2.0)
    return f[keep], np.asarray(acc)[keep] / n_avg, n_avg


def expected_coherence(f_hz: np.ndarray, psd_inject: np.ndarray, floor_psd: float, M: float, B: float,
                       gains: tuple[float, float, float], fs: float, n_averages: int
                       ) -> tuple[np.ndarray, np.ndarray]:
    """Expected coherence of identify's H1 estimate u -> q in the holding loop, and its ratio to the model.

    Returns ``(gamma^2, R)`` per bin: ``R = E[H1] / P`` with
    ``E[H1] = (P Pii - conj(C) Pnn) / (Pii + |C|^2 Pnn)``, which tends to ``-1 / C`` where the
    loop's answer to the noise dominates the command (coherent, but not the plant: identify's band
    rule ends the band there by the model's disagreement, and so does the prediction).

    The encoder's reading is ``q_m = P u + n`` (``n``: its noise and quantization, white, one-sided
    density ``floor_psd``); the recorded command is ``u = S u_i - C S n`` with ``S = 1 / (1 + C P)``,
    ``C`` the holding loop's PID (derivative on the backward difference, as the drive's and the
    simulator's) and ``P`` the rigid body behind the zero-order hold.  Then
    ``gamma^2 = |P Pii - conj(C) Pnn|^2 / ((Pii + |C|^2 Pnn)(|P|^2 Pii + Pnn))``: the loop's answer to
    the noise is in ``u`` too, which lowers the coherence below the open-loop SNR / (1 + SNR).  The
    Welch estimate over ``n_averages`` windows is biased up by about ``(1 - gamma^2)^2 / n`` (Carter,
    Knapp & Nuttall 1973): the only place where the injection's duration enters.  A bin whose
    position PSD ``|S|^2 (|P|^2 Pii + Pnn)`` stays below ``MEASURABLE_SNR`` times ``Pnn`` gets 0, as
    identify's estimate gives it (:func:`commission.identify.frf.estimate`).
    """
    from commission.controllers.linear import rigid_frequency_response

    T = 1.0 / fs
    P = rigid_frequency_response(M, B, T, f_hz)
    z1 = np.exp(-2j * np.pi * f_hz * T)
    kp, kd, ki = gains
    C = kp + kd * (1.0 - z1) / T + ki * T / (1.0 - z1)
    Pii, Pnn = np.asarray(psd_inject, float), float(floor_psd)
    num = np.abs(P * Pii - np.conj(C) * Pnn) ** 2
    den = (Pii + np.abs(C) ** 2 * Pnn) * (np.abs(P) ** 2 * Pii + Pnn)
    with np.errstate(divide="ignore", invalid="ignore"):
        g2 = np.where(den > 0, num / den, 0.0)
    g2 = np.clip(np.nan_to_num(g2), 0.0, 1.0)
    # identify's estimate zeroes a bin whose position PSD |S|^2 (|P|^2 Pii + Pnn) stays below
    # MEASURABLE_SNR times the floor (the reading is the noise there); so does the prediction.
    with np.errstate(divide="ignore", invalid="ignore"):
        Pqq = (np.abs(P) ** 2 * Pii + Pnn) / np.abs(1.0 + C * P) ** 2
    measurable = np.nan_to_num(Pqq) >= MEASURABLE_SNR * Pnn
    with np.errstate(divide="ignore", invalid="ignore"):
        R = (P * Pii - np.conj(C) * Pnn) / ((Pii + np.abs(C) ** 2 * Pnn) * P)
    R = np.where(np.isfinite(R), R, 0.0)
    g2 = np.clip(g2 + (1.0 - g2) ** 2 / max(int(n_averages), 1), 0.0, 1.0)
    return np.where(measurable, g2, 0.0), R


def predict_band(plan: Plan) -> BandPrediction:
    """The band a recording of ``plan`` will back, from its injection's spectrum against the encoder floor.

    The injection's density is taken on the bins identify will use (its resolution, its windows:
    :func:`injection_ranges`), the response on the rigid model of the nominal mass (``[axis] mass``,
    else the geometric mean of :func:`mass_bracket`) in the holding loop of ``[drive]``, the floor
    ``(encoder_noise^2 + encoder_step^2 / 12) * 2 / sample_rate`` (white up to Nyquist); the expected
    coherence and the expected estimate over the model (:func:`expected_coherence`) go through
    identify's own band rule (:func:`commission.identify.frf.backed_band`).  A structural mode is not
    in the model: above a motor-side mode the motor moves more than the rigid body (the band is then
    a little higher), below an anti-resonance less.

    When ``[evidence] band_hz`` or ``first_mode_hz`` sets a target the band misses, ``remedies`` holds
    what would reach it, each computed the same way: the injection's amplitude factor (and the
    ``a_max`` of the injection segment that allows it), the encoder floor's factor (the step and
    noise), and the band of a four times longer injection.
    """
    from commission.identify.frf import backed_band

    s = plan.spec
    fs = s.sample_rate
    step = s.encoder_step if s.encoder_step is not None else ASSUMED_ENCODER_STEP
    noise = s.encoder_noise if s.encoder_noise is not None else 0.0
    floor = (noise * noise + step * step / 12.0) * 2.0 / fs
    M = _nominal_mass(s)
    B = s.viscous or 0.0
    gains = loop_gains_for(s, M)
    f, Pii, n_avg = _injection_psd(plan)

    def predicted(scale_inj: float = 1.0, scale_floor: float = 1.0, n: int = n_avg):
        g2, R = expected_coherence(f, Pii * scale_inj, floor * scale_floor, M, B, gains, fs, n)
        return g2, (backed_band(f, R, g2) if f.size else None)

    def top(scale_inj: float = 1.0, scale_floor: float = 1.0, n: int = n_avg) -> tuple[np.ndarray, float]:
        g2, band = predicted(scale_inj, scale_floor, n)
        return g2, (float(band[1]) if band is not None else 0.0)

    g2, band = predicted()
    band_t = (float(band[0]), float(band[1])) if band is not None else None
    target, source = None, None
    if s.target_band_hz is not None:
        target, source = float(s.target_band_hz), "evidence.band_hz"
    if s.first_mode_hz is not None and (target is None or MODE_BAND_FACTOR * s.first_mode_hz > target):
        target, source = MODE_BAND_FACTOR * float(s.first_mode_hz), f"{MODE_BAND_FACTOR:g} x evidence.first_mode_hz"
    if target is not None:
        target = min(target, float(f[-1])) if f.size else target
    remedies: dict[str, Any] = {}
    reached = band_t[1] if band_t is not None else 0.0
    if target is not None and reached < target and f.size:
        def solve(fun) -> float | None:
            lo, hi = 0.0, math.log(1e6)
            if fun(math.exp(hi)) < target:
                return None
            for _ in range(40):
                mid = 0.5 * (lo + hi)
                lo, hi = (mid, hi) if fun(math.exp(mid)) < target else (lo, mid)
            return math.exp(hi)
        k_amp = solve(lambda k: top(scale_inj=k * k)[1])
        k_floor = solve(lambda k: top(scale_floor=1.0 / (k * k))[1])
        inj = next((g for g in plan.segments if g.name == "injection"), None)
        amp = float(inj.info.get("amplitude", 0.0)) if inj is not None else 0.0
        remedies = {
            "injection_amplitude_factor": k_amp,
            "injection_amplitude": amp * k_amp if k_amp is not None else None,
            "a_max_for_injection": s.a_max * k_amp if k_amp is not None else None,
            "encoder_floor_factor": (1.0 / k_floor) if k_floor is not None else None,
            "encoder_step": step / k_floor if k_floor is not None else None,
            "encoder_noise": noise / k_floor if k_floor is not None else None,
            "longer_injection_s": 4.0 * s.plan["injection_s"],
            "longer_injection_band_top_hz": top(n=4 * n_avg)[1],
        }
    return BandPrediction(f, g2, band_t, int(n_avg), float(f[1] - f[0]) if f.size > 1 else math.nan, M,
                          step, noise, s.encoder_step is not None, s.encoder_noise is not None, floor,
                          target, source, remedies)


def band_lines(plan: Plan) -> list[str]:
    """What ``excite`` prints about the band its plan will back: the prediction, what was assumed, and a
    warning with the remedies (figures from :func:`predict_band`) when it falls short of the target."""
    pr = plan.prediction
    if pr is None:
        return []
    s = plan.spec
    q, u = s.q_unit, s.u_unit
    assumed = []
    if not pr.step_given:
        assumed.append(f"encoder_step {pr.encoder_step:g} {q}")
    if not pr.noise_given:
        assumed.append(f"encoder_noise {pr.encoder_noise:g} {q} rms")
    enc = f"encoder step {pr.encoder_step:.3g} {q}, noise {pr.encoder_noise:.3g} {q} rms"
    band = (f"{pr.band_hz[0]:.4g} - {pr.band_hz[1]:.4g} Hz" if pr.band_hz is not None else "no band")
    out = [f"predicted band the recording will back: {band} (expected coherence >= 0.8 on {pr.resolution_hz:.3g} Hz "
           f"bins, {pr.n_averages} windows; rigid model M = {pr.mass:.4g} {u} s^2/{q}; {enc})"]
    if assumed:
        out.append(f"note: assumed {', '.join(assumed)} ([axis] keys not given); give them for a sharper prediction")
    if pr.target_hz is None:
        out.append("note: no target band ([evidence] target_hz or first_mode_hz): the band is not checked")
    elif pr.short:
        r = pr.remedies
        ways = []
        if r.get("injection_amplitude_factor") is not None:
            room = s.u_max - (s.friction or 0.0)
            within = (f"within u_max {s.u_max:g} {u}" if r["injection_amplitude"] <= room else
                      f"beyond u_max {s.u_max:g} {u} less friction: not reachable by the injection alone")
            ways.append(f"an injection {r['injection_amplitude_factor']:.3g} times larger "
                        f"({r['injection_amplitude']:.4g} {u}: a_max >= {r['a_max_for_injection']:.4g} {q}/s^2 "
                        f"for the injection segment, {within})")
        if r.get("encoder_floor_factor") is not None:
            ways.append(f"an encoder floor {1 / r['encoder_floor_factor']:.3g} times lower (step "
                        f"{r['encoder_step']:.3g} {q}, noise {r['encoder_noise']:.3g} {q} rms)")
        top4 = r.get("longer_injection_band_top_hz")
        if top4 is not None:
            helps = "helps" if top4 >= pr.target_hz else ("barely helps" if top4 > pr.top_hz else "does not help")
            ways.append(f"a 4 times longer injection ({r['longer_injection_s']:g} s) reaches {top4:.4g} Hz: {helps}")
        out.append(f"warning: the plan is predicted to back the model up to {pr.top_hz:.4g} Hz, short of "
                   f"{pr.target_hz:.4g} Hz ({pr.target_source}); to reach it: " + "; ".join(ways))
    else:
        out.append(f"the predicted band reaches the target {pr.target_hz:.4g} Hz ({pr.target_source})")
    return out


# --------------------------------------------------------------------------- the limits.toml sketch
