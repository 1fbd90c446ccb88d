"""Certify only within the evidence: what the log backs, and the loop's robust stability above it.

The log backs the model up to a frequency and no further
(``ident.json`` ``frequency_response.evidence_band_hz``,
:attr:`commission.identify.frf.FrequencyResponse.evidence_band_hz`): without a broadband
segment that is where the reference's content agrees with the rigid body (a few tens of Hz
on a typical commissioning run); with one, where the measured response agrees with the fitted
model, its mode and delay included.  Above it the plant is **unknown**, and a loop whose
bandwidth reaches there rests on nothing but the model's extrapolation: the issue-30 sample's
ARC crossed over at 240 Hz on a log backed to 22 Hz, and failed on the same stage with a
500-Hz structural mode its log could not show.

Uncertainty weight
------------------
The unknown above the band is a multiplicative uncertainty ``P_true = P (1 + Delta W)``,
``|Delta| <= 1``.  What it must cover is an unseen non-collocated (load-side) two-mass mode at
some ``f' >= f_m`` with damping ``zeta' >= zeta``, whose relative error is
``-s^2 / (s^2 + 2 zeta' w' s + w'^2)``: ``x^2 / sqrt((1 - x^2)^2 + (2 zeta' x)^2)``,
``x = f / f'``, rising as ``(f / f')^2`` below the mode (whatever its damping), peaking at
``1 / (2 zeta' sqrt(1 - zeta'^2))`` and tending to 1 (the phase reversal) above it.  The weight
is the envelope of that family (the mode at ``f_m`` below its peak, the peak itself above)::

    |W(f)| = x^2 / sqrt((1 - x^2)^2 + (2 zeta x)^2),  x = f / f_m,   up to x^2 = 1 / (1 - 2 zeta^2)
    |W(f)| = W_inf = 1 / (2 zeta sqrt(1 - zeta^2))                     above

so ``|W|`` rises through 1 at ``f_m / sqrt(2 - 4 zeta^2)`` (about 0.71 ``f_m``) and reaches
``W_inf`` near ``f_m``.  Defaults: ``f_m = EVIDENCE_FACTOR x f_top`` with
:data:`EVIDENCE_FACTOR` = 10 (the lowest mode is taken a decade above the band the log backs)
and ``zeta =`` :data:`ZETA_W` = 0.05 (a stage's first mode is typically damped 0.02-0.1), so
``W_inf`` is about 10; spec.toml's ``[evidence] first_mode_hz`` and ``damping`` replace them when
the user knows the machine (a FE model, the vendor's data).  Under the small-gain theorem a loop
with ``||W T|| < 1`` is stable on every such mode.  Both are assumptions, stated in the report and
``validation.json``; the remedy for their cost is a log that backs a higher band
(``commission excite``).  Where ``|W|`` stays below 1 up to the loop's Nyquist frequency (a
broadband log backed to a good part of it), the bound asks nothing of the loop above the band,
and the report says that the certificate *assumes* that band free of modes
(:attr:`Evidence.assumed_mode_free_hz`).  The relative error is only meaningful away from
Nyquist: the hold's zero at ``z = -1`` sends a rigid body's sampled response to 0 there, where
``|T|`` is about 0 as well.

Robust stability is ``||W T||_inf < 1`` with ``T = L / (1 + L)``, ``L = -K P`` the loop of the
sampled controller's linearisation (:mod:`commission.controllers.margins`) on the identified
plant (``P``: mode and delay included; :func:`commission.robustness.margin_plants`' nominal
plant).  The ARC is checked at both of its linearisation points, the PID once.  ``tune``'s
search holds the ARC's peak below ``1 - `` :data:`SEARCH_ROOM` and its measured modulus margin
(below) above ``1 + SEARCH_ROOM`` times the floor (constraints, like the margin floors) and ``validate``'s gate holds both loops' peaks below 1 (criterion ``margins``): the
PID is the yardstick the ARC is judged against and the fallback a user may deploy, and a
yardstick beyond the evidence certifies nothing either.  A
``frequency_response`` section absent from ident.json (an older file, or an identification not
made from a log) records no evidence: the bound is then not applied, and the report says so.

Measured response
-----------------
Where the log holds a broadband segment, ``frequency_response.measured`` carries the measured
response (at most 200 log-spaced bins with their coherence).  :func:`measured_margins` closes
each loop on it, on the bins with coherence at least
:data:`commission.identify.frf.BAND_COHERENCE`: the modulus margin ``min |1 + L|`` and the
phase margin at a gain crossover that lies among those bins.  The gate holds the measured
modulus margin of the ARC (plus twice its standard error: refused only where the data show the
floor missed) to the same floor as the model's; the PID's is reported, as its model margins are.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Mapping

import numpy as np

from commission.artifacts import Identification
from commission.infra.blas import one_blas_thread
from commission.controllers.arc import ArcGains, arc_pack
from commission.controllers.linear import sampled_plant
from commission.controllers.margins import (NEUTRAL_TOL, LinearController, closed_loop_radius, frequency_grid,
                                            linearize_arc, linearize_pid)
from commission.controllers.pid import PidGains, pid_pack
from commission.controllers.plant import P_B, P_M
from commission.identify.frf import BAND_COHERENCE
from commission.spec import Spec

#: The lowest unseen mode is taken at this factor times the top of the band the log backs, where
#: the log's coherent data end with the band (nothing measured above it).
EVIDENCE_FACTOR = 10.0
#: Least damping of the unseen mode (dimensionless).
ZETA_W = 0.05
#: Plateau of |W|: the peak relative error of a mode damped ZETA_W.
W_INF = 1.0 / (2.0 * ZETA_W * math.sqrt(1.0 - ZETA_W ** 2))
#: The search holds the ARC's peak |W T| below 1 minus this (room for validate's own grid).
SEARCH_ROOM = 0.05


@dataclass(frozen=True)
class MeasuredResponse:
    """The measured response of ident.json's ``frequency_response.measured``.

    Kept beside the model so that a loop's margins are also read on what the log showed
    (:func:`measured_margins`), not only on the fit's extrapolation; the file's magnitude and
    phase (deg) are joined into one complex response on loading.

    Attributes
    ----------
    f_hz : ndarray
        Frequencies of the measured bins, Hz.
    H : ndarray, complex
        Measured response from u to q at those bins, q-unit per u-unit.
    coherence : ndarray
        Magnitude-squared coherence of each bin, dimensionless (0-1).
    n_averages : int
        Welch windows averaged (ident.json's ``frequency_response.n_averages``).
    """

    f_hz: np.ndarray
    H: np.ndarray
    coherence: np.ndarray
    n_averages: int = 1


@dataclass(frozen=True)
class Evidence:
    """What the certificate rests on (module docstring).

    Attributes
    ----------
    source : str
        ``"broadband"`` (a broadband segment; the fitted model is backed), ``"whole_log"`` (no
        broadband content; the rigid body is backed) or ``"none"`` (ident.json records no
        frequency response: no bound applied).
    band_hz : (float, float) or None
        The band the log backs, Hz.
    factor : float
        The lowest unseen mode over the band's top.
    damping : float
        The least damping of that mode.
    measured : MeasuredResponse or None
    coherent_up_to_hz : float
        Highest coherent bin of the log's response, Hz (nan: not recorded).  Above the band's top
        it means the log's own data contradict the model there (:func:`departs_above_band`).
    factor_basis : str
        Why :attr:`factor` is what it is: ``"default"`` (:data:`EVIDENCE_FACTOR`),
        ``"departure"`` (the data depart from the model at the band's top,
        :func:`departure_factor`) or ``"spec"`` (``[evidence] first_mode_hz``).
    nyquist_hz : float
        Half the loop's sample rate, Hz (nan: not known, no spec given): the top of every
        frequency the sampled loop acts on, so the top of what the bound can weigh
        (:attr:`assumed_mode_free_hz`).
    """

    source: str
    band_hz: tuple[float, float] | None
    factor: float = EVIDENCE_FACTOR
    damping: float = ZETA_W
    measured: MeasuredResponse | None = None
    coherent_up_to_hz: float = math.nan
    factor_basis: str = "default"
    nyquist_hz: float = math.nan

    @property
    def applies(self) -> bool:
        """The weight bounds the loop (a backed band is known)."""
        return self.band_hz is not None

    @property
    def top_hz(self) -> float:
        """Top of the backed band, Hz (nan: none)."""
        return float(self.band_hz[1]) if self.band_hz is not None else math.nan

    @property
    def mode_hz(self) -> float:
        """``f_m``: the lowest unseen mode, Hz."""
        return self.factor * self.top_hz

    @property
    def w_inf(self) -> float:
        """The plateau: the peak relative error ``1 / (2 zeta sqrt(1 - zeta^2))`` of a mode."""
        z = self.damping
        return 1.0 / (2.0 * z * math.sqrt(1.0 - z * z))

    @property
    def unity_hz(self) -> float:
        """Where ``|W| = 1``: ``f_m / sqrt(2 - 4 zeta^2)``, Hz."""
        return self.mode_hz / math.sqrt(2.0 - 4.0 * self.damping ** 2)

    @property
    def assumed_mode_free_hz(self) -> tuple[float, float] | None:
        """``(band's top, Nyquist)``, Hz, where ``|W|`` stays below 1 up to Nyquist; else None.

        The sampled loop acts on frequencies up to Nyquist only.  When the weight's unseen mode
        is placed so far above the band that ``|W| = 1`` only beyond Nyquist (:attr:`unity_hz`),
        the bound never asks the loop to attenuate anything it acts on: it says nothing there,
        and the certificate rests on the *assumption* that the machine has no mode between the
        band's top and Nyquist, not on the log.  The report says so and names the statement
        that covers such a mode (``[evidence] first_mode_hz``); docs/robustness.md, "Between the
        band's top and Nyquist", says why the gap is stated rather than bounded.  None when the
        user stated the first mode (the assumption is then theirs), when the band reaches
        Nyquist, or without a known rate.
        """
        if not self.applies or not math.isfinite(self.nyquist_hz) or self.factor_basis == "spec":
            return None
        if self.unity_hz < self.nyquist_hz or self.top_hz >= self.nyquist_hz:
            return None
        return (self.top_hz, self.nyquist_hz)

    def weight(self, f_hz: np.ndarray) -> np.ndarray:
        """``|W|`` at ``f_hz`` (dimensionless; zeros when no band is known; module docstring)."""
        f_hz = np.asarray(f_hz, dtype=float)
        if not self.applies:
            return np.zeros_like(f_hz)
        z = self.damping
        x2 = (f_hz / self.mode_hz) ** 2
        below = x2 * x2 / ((1.0 - x2) ** 2 + 4.0 * z * z * x2)
        return np.where(x2 < 1.0 / (1.0 - 2.0 * z * z), np.sqrt(below), self.w_inf)

    def to_dict(self) -> dict[str, Any]:
        return {"source": self.source, "band_hz": list(self.band_hz) if self.band_hz is not None else None,
                "weight": {"factor": self.factor, "damping": self.damping, "w_inf": self.w_inf,
                           "mode_hz": self.mode_hz if self.applies else None,
                           "unity_hz": self.unity_hz if self.applies else None,
                           "form": "|W| = x^2 / sqrt((1 - x^2)^2 + (2 damping x)^2), x = f / mode_hz, "
                                   "up to its peak w_inf, then w_inf"},
                "measured_bins": int(self.measured.f_hz.size) if self.measured is not None else 0,
                "coherent_up_to_hz": self.coherent_up_to_hz if math.isfinite(self.coherent_up_to_hz) else None,
                "factor_basis": self.factor_basis,
                "nyquist_hz": self.nyquist_hz if math.isfinite(self.nyquist_hz) else None,
                "assumed_mode_free_hz": (list(self.assumed_mode_free_hz) if self.assumed_mode_free_hz is not None
                                         else None),
                "units": {"band_hz": "Hz", "mode_hz": "Hz", "unity_hz": "Hz", "factor": "1", "damping": "1",
                          "w_inf": "1", "coherent_up_to_hz": "Hz", "nyquist_hz": "Hz",
                          "assumed_mode_free_hz": "Hz"}}


def departure_factor(damping: float) -> float:
    """``sqrt(2 - 4 zeta^2)``: the factor that puts ``|W| = 1`` at the band's top (about 1.41).

    Used where the log's coherent data go on above the backed band and disagree with the model
    there (:func:`departs_above_band`): the log itself shows the model failing at the top, so the
    unseen dynamics are taken to start there -- the relative error reaches 100 % where the data
    first contradict the model -- and not a decade above it.
    """
    return math.sqrt(2.0 - 4.0 * damping * damping)


def departs_above_band(band_hz: tuple[float, float] | None, coherent_up_to_hz: float,
                       resolution_hz: float | None) -> bool:
    """The log's coherent data reach above the backed band's top (by more than one bin and a half).

    :func:`commission.identify.frf.backed_band` ends the band at the first two consecutive
    coherent bins that disagree with the model, so coherent bins above the top are bins where the
    data contradict it (a mode the model lacks, or the closed loop's own bias where the encoder
    noise's feedback dominates the command): either way the log does not back the model there, and
    gives no reason to believe the plant's first unseen mode lies a decade higher.
    """
    if band_hz is None or not math.isfinite(coherent_up_to_hz):
        return False
    step = resolution_hz if resolution_hz is not None and resolution_hz > 0 else 0.01 * band_hz[1]
    return bool(coherent_up_to_hz > band_hz[1] + 1.5 * step)


def evidence_of(ident: Identification, spec: Spec | None = None) -> Evidence:
    """The evidence ident.json records (module docstring); ``source "none"`` without a frequency response.

    ``spec``'s ``[evidence]`` sets the weight: ``first_mode_hz`` (f_1 itself, Hz, when the user
    knows the machine's lowest mode) and ``damping`` (W_inf = 1 / (2 damping)).
    """
    fr = ident.extra.get("frequency_response")
    if not isinstance(fr, Mapping):
        return Evidence("none", None)
    band = fr.get("evidence_band_hz", fr.get("band_hz"))
    band_t = (float(band[0]), float(band[1])) if isinstance(band, (list, tuple)) and len(band) == 2 else None
    meas = fr.get("measured")
    measured = None
    if isinstance(meas, Mapping) and meas.get("frequency_hz"):
        mag = np.asarray(meas["magnitude"], dtype=float)
        ph = np.radians(np.asarray(meas["phase_deg"], dtype=float))
        measured = MeasuredResponse(np.asarray(meas["frequency_hz"], dtype=float), mag * np.exp(1j * ph),
                                    np.asarray(meas["coherence"], dtype=float), max(int(fr.get("n_averages") or 1), 1))
    coh = fr.get("coherent_up_to_hz")
    coh_hz = float(coh) if isinstance(coh, (int, float)) and math.isfinite(coh) else math.nan
    res = fr.get("resolution_hz")
    res_hz = float(res) if isinstance(res, (int, float)) and math.isfinite(res) else None
    damping = spec.evidence_damping if spec is not None else ZETA_W
    factor, basis = EVIDENCE_FACTOR, "default"
    if spec is not None and spec.evidence_first_mode_hz is not None and band_t is not None:
        factor, basis = spec.evidence_first_mode_hz / band_t[1], "spec"
    elif departs_above_band(band_t, coh_hz, res_hz):
        factor, basis = departure_factor(damping), "departure"
    nyquist = 0.5 * spec.sample_rate if spec is not None else math.nan
    return Evidence(str(fr.get("source", "whole_log")), band_t, factor=factor, damping=damping, measured=measured,
                    coherent_up_to_hz=coh_hz, factor_basis=basis, nyquist_hz=nyquist)


@dataclass(frozen=True)
class RobustStability:
    """``||W T||_inf`` of one loop and its margins on the measured response.

    The two halves answer two questions: ``peak`` weighs the model's loop by the uncertainty
    above the band the log backs (the module docstring's ``W``); the ``measured_*`` margins read
    the same loop on the coherent bins the log did measure (:func:`measured_margins`).

    Attributes
    ----------
    controller : str
        ``"arc"`` or ``"pid"``.
    theta_hat_at : str
        ``"initial"``, ``"plant"`` (ARC) or ``""`` (PID).
    peak : float
        ``max |W T|`` over the grid (dimensionless; < 1 holds).
    peak_hz : float
        Where, Hz.
    crossover_hz : float
        First gain crossover on the model, Hz (nan: none).
    measured_modulus : float
        ``min |1 + L|`` on the coherent measured bins (nan: no measured response).
    measured_phase_deg : float
        Phase margin at a gain crossover among the coherent measured bins, deg (nan: none there).
    measured_up_to_hz : float
        Highest coherent measured bin, Hz (nan: none).
    measured_modulus_high : float
        ``min (|1 + L| + 2 sigma)`` over the same bins, sigma the standard error of ``|L|`` from the
        H1 estimate: the margin the data do not rule out (the gate's test; nan: none).
    """

    controller: str
    theta_hat_at: str
    peak: float
    peak_hz: float
    crossover_hz: float
    measured_modulus: float = math.nan
    measured_phase_deg: float = math.nan
    measured_up_to_hz: float = math.nan
    measured_modulus_high: float = math.nan

    @property
    def holds(self) -> bool:
        return bool(self.peak < 1.0)

    def to_dict(self) -> dict[str, Any]:
        def num(x: float) -> float | None:
            return float(x) if math.isfinite(x) else None

        return {"controller": self.controller, "theta_hat_at": self.theta_hat_at, "peak_wt": num(self.peak),
                "peak_hz": num(self.peak_hz), "crossover_hz": num(self.crossover_hz), "holds": self.holds,
                "measured_modulus_margin": num(self.measured_modulus),
                "measured_phase_margin_deg": num(self.measured_phase_deg),
                "measured_up_to_hz": num(self.measured_up_to_hz),
                "measured_modulus_margin_2sigma": num(self.measured_modulus_high)}


def weighted_peak(K: LinearController, P: np.ndarray, W: np.ndarray, f_hz: np.ndarray) -> tuple[float, float, float]:
    """``(max |W T|, its frequency in Hz, first gain crossover in Hz)`` of ``L = -K P`` on ``f_hz``."""
    L = -K.frequency_response(f_hz) * P
    with np.errstate(divide="ignore", invalid="ignore"):
        wt = np.abs(W * L / (1.0 + L))
    wt = np.where(np.isfinite(wt), wt, np.inf)
    i = int(np.argmax(wt))
    above = np.abs(L) >= 1.0
    j = np.flatnonzero(above[:-1] & ~above[1:])
    return float(wt[i]), float(f_hz[i]), float(f_hz[j[0]]) if j.size else math.nan


def measured_margins(K: LinearController, m: MeasuredResponse) -> tuple[float, float, float, float]:
    """``(modulus margin, phase margin deg, highest coherent bin Hz, modulus + 2 sigma)`` on the measured bins.

    Only bins with coherence >= BAND_COHERENCE count; the phase margin is nan when no gain
    crossover lies between two coherent neighbouring bins.  The last is ``min(|1 + L| + 2 |L|
    sigma)`` with ``sigma = sqrt((1 - gamma^2) / (2 n gamma^2))`` the relative standard error of
    an H1 estimate averaged over ``n`` windows (Bendat & Piersol): the modulus margin the
    measurement does not rule out.
    """
    ok = m.coherence >= BAND_COHERENCE
    if not np.any(ok):
        return math.nan, math.nan, math.nan, math.nan
    f, H, g2 = m.f_hz[ok], m.H[ok], np.minimum(m.coherence[ok], 1.0)
    L = -K.frequency_response(f) * H
    sigma = np.sqrt((1.0 - g2) / (2.0 * m.n_averages * g2))
    mod = float(np.abs(1.0 + L).min())
    high = float((np.abs(1.0 + L) + 2.0 * np.abs(L) * sigma).min())
    mag = np.abs(L)
    j = np.flatnonzero((mag[:-1] >= 1.0) & (mag[1:] < 1.0))
    pm = math.nan
    if j.size:
        k = int(j[0])
        a = math.log(mag[k]) / (math.log(mag[k]) - math.log(mag[k + 1]))
        ph = np.unwrap(np.angle(L[k:k + 2]))
        pm = float(np.degrees(math.remainder(ph[0] + a * (ph[1] - ph[0]) + math.pi, 2 * math.pi)))
    return mod, pm, float(f.max()), high


class EvidenceBound:
    """``||W T||_inf`` of many controllers on the identified plant (plant, grid and weight computed once).

    Parameters
    ----------
    ident : Identification
    spec : Spec
    """

    def __init__(self, ident: Identification, spec: Spec) -> None:
        from commission.robustness import margin_plants  # the same nominal plant as the margin table

        self.evidence = evidence_of(ident, spec)
        self.Ts = spec.period
        self.f_hz = frequency_grid(self.Ts)
        _, p = margin_plants(ident, spec)[0]
        self.theta_plant = (1.0 / float(p[P_M]), float(p[P_B]) / float(p[P_M]), float(ident.theta.nominal[2]))
        with one_blas_thread():
            self.plant = sampled_plant(p, self.Ts)
            self.P = self.plant.frequency_response(self.f_hz)
        self.W = self.evidence.weight(self.f_hz)
        self.modulus_floor = float(spec.min_modulus_margin)

    def row(self, K: LinearController, controller: str, at: str, stability: bool = False) -> RobustStability:
        """The row of loop ``K``; with ``stability`` its nominal closed loop is checked first (as the
        margin table checks it: :class:`commission.controllers.margins.Margins` ``stable``).

        ``||W T|| < 1`` proves robust stability only of a loop that is stable on the model: an
        unstable one gets an infinite peak (no bound holds).  The search and the yardstick call
        this on loops whose stability the margin checks already judge, so they skip it.
        """
        peak, fpk, fc = weighted_peak(K, self.P, self.W, self.f_hz)
        # The margin table's test: the adaptation's neutral modes sit on the unit circle.
        if stability and not closed_loop_radius(K, self.plant) < 1.0 + NEUTRAL_TOL:
            peak, fpk = math.inf, math.nan
        mod = pm = up = high = math.nan
        if self.evidence.measured is not None:
            mod, pm, up, high = measured_margins(K, self.evidence.measured)
        return RobustStability(controller, at, peak, fpk, fc, mod, pm, up, high)

    def arc_rows(self, arc: ArcGains, stability: bool = False) -> tuple[RobustStability, ...]:
        """The ARC at its initial estimate and at the identified theta (``stability``: :meth:`row`)."""
        ap = arc_pack(arc)
        with one_blas_thread():
            return tuple(self.row(linearize_arc(ap, th), "arc", at, stability)
                         for at, th in (("initial", tuple(arc.theta0)), ("plant", self.theta_plant)))

    def pid_row(self, pid: PidGains, stability: bool = False) -> RobustStability:
        with one_blas_thread():
            return self.row(linearize_pid(pid_pack(pid)), "pid", "", stability)

    def violation(self, arc: ArcGains) -> float:
        """Search constraint (0: met, or no band): what the gate's ``evidence`` and ``measured`` checks need.

        Summed over the ARC's two linearisations: the peak's excess over ``1 - SEARCH_ROOM``, and
        the measured modulus margin's (+2 sigma) shortfall below ``(1 + SEARCH_ROOM)`` x the floor,
        relative to the floor.
        """
        if not self.evidence.applies:
            return 0.0
        total = 0.0
        for r in self.arc_rows(arc):
            total += max(0.0, r.peak - (1.0 - SEARCH_ROOM))
            if math.isfinite(r.measured_modulus_high):
                need = (1.0 + SEARCH_ROOM) * self.modulus_floor
                total += max(0.0, need - r.measured_modulus_high) / self.modulus_floor
        return total


def evidence_table(arc: ArcGains, pid: PidGains, ident: Identification,
                   spec: Spec) -> tuple[Evidence, tuple[RobustStability, ...]]:
    """The evidence and the robust-stability rows of both loops (ARC twice, PID once); a loop
    unstable on the model holds no bound (:meth:`EvidenceBound.row`)."""
    b = EvidenceBound(ident, spec)
    return b.evidence, b.arc_rows(arc, stability=True) + (b.pid_row(pid, stability=True),)


def evidence_checks(rows: tuple[RobustStability, ...] | list[RobustStability], evidence: Evidence,
                    modulus_floor: float) -> list[Any]:
    """Gate checks (criterion ``margins``) of the ARC's rows: ``||W T|| < 1``, and the measured modulus margin.

    ``value`` of the first is the peak (limit 1); of the second floor / margin (limit 1), as
    :func:`commission.gate.margin_checks` counts a margin.  No check without a backed band, and no
    measured check without coherent measured bins.

    As on the identified model (:func:`commission.gate.margin_checks`), only the emitted loop is
    gated: the PID's row is the yardstick's, reported on the evidence lines (:func:`evidence_lines`)
    and in validation.json's ``evidence.loops``.  A yardstick that is not robust above the band is
    one the machine might not run: its simulated error flatters it, which makes the comparison harder
    on the ARC, and says nothing about whether the ARC is safe.
    """
    from commission.gate import Check

    out = []
    for r in rows:
        if not evidence.applies or r.controller != "arc":
            continue
        where = f"evidence/nominal/arc(theta_hat {r.theta_hat_at})"
        detail = (f"robust stability above the backed band (to {evidence.top_hz:.3g} Hz): peak |W T| "
                  f"{r.peak:.3g} at {r.peak_hz:.4g} Hz (limit 1; |W| = 1 at {evidence.unity_hz:.4g} Hz)"
                  if math.isfinite(r.peak) else
                  f"robust stability above the backed band (to {evidence.top_hz:.3g} Hz): none, the closed "
                  f"loop is UNSTABLE on the identified model")
        out.append(Check("margins", where, r.peak, 1.0, r.holds, detail))
        if math.isfinite(r.measured_modulus):
            # The measurement's own error is allowed for (measured_margins): refused only where the
            # data show the floor missed.
            ok = bool(r.measured_modulus_high >= modulus_floor)
            out.append(Check("margins", where.replace("evidence/", "measured/"),
                             modulus_floor / r.measured_modulus_high if r.measured_modulus_high > 0 else math.inf,
                             1.0, ok,
                             f"modulus margin on the measured response {r.measured_modulus:.3g} "
                             f"(+2 sigma {r.measured_modulus_high:.3g}; coherent bins up to "
                             f"{r.measured_up_to_hz:.4g} Hz; floor {modulus_floor:g})"))
    return out


def evidence_lines(evidence: Evidence, rows: tuple[RobustStability, ...] | list[RobustStability]) -> list[str]:
    """One-line statements of what the certificate rests on, for the report's first lines and stdout."""
    if evidence.source == "none":
        return ["evidence: ident.json records no frequency response; the loop's bandwidth is not bounded by "
                "what a log backs (identify a log to get one)"]
    if evidence.band_hz is None:
        return ["evidence: no band of coherent data agrees with the model; the plant is unknown at every "
                "frequency the loop acts on"]
    lo, hi = evidence.band_hz
    what = ("a broadband segment: the measured response backs the fitted model (mode and delay)"
            if evidence.source == "broadband" else
            "no broadband segment: the reference's own content backs the rigid model")
    why = {"departure": f"at the band's top: the log's coherent data, up to {evidence.coherent_up_to_hz:.4g} Hz, "
                        f"depart from the model there; ",
           "spec": "as spec [evidence] first_mode_hz states; "}.get(evidence.factor_basis, "")
    out = [f"evidence: {what} from {lo:.3g} to {hi:.3g} Hz; above {hi:.3g} Hz the plant is unknown, "
           f"bounded as an unseen non-collocated mode at {evidence.mode_hz:.4g} Hz or above ({why}{evidence.factor:.3g} x "
           f"the band's top; spec [evidence] first_mode_hz) damped {evidence.damping:g} or more ([evidence] "
           f"damping): |W| = 1 at {evidence.unity_hz:.4g} Hz, {evidence.w_inf:.3g} from {evidence.mode_hz:.4g} Hz on"]
    free = evidence.assumed_mode_free_hz
    if free is not None:
        w_nyq = float(evidence.weight(np.array([free[1]]))[0])
        out[0] += (f". Assumed, not measured: |W| stays below 1 up to the loop's Nyquist frequency "
                   f"({free[1]:.4g} Hz; {w_nyq:.2g} there), so the bound asks nothing of the loop there and the "
                   f"certificate assumes no structural mode from {free[0]:.4g} to {free[1]:.4g} Hz; if the machine "
                   f"may have one there, state it in spec.toml [evidence] first_mode_hz (the bound then covers it), "
                   f"or record a log that backs that band")
    for r in rows:
        who = "ARC" + (f" (theta_hat {r.theta_hat_at})" if r.theta_hat_at else "") if r.controller == "arc" else "PID"
        s = (f"{who}: peak |W T| {r.peak:.3g} at {r.peak_hz:.4g} Hz ({'holds' if r.holds else 'EXCEEDS 1'}), "
             f"crossover {r.crossover_hz:.4g} Hz" if math.isfinite(r.peak) else
             f"{who}: closed loop UNSTABLE on the identified model, no robust-stability bound")
        if math.isfinite(r.measured_modulus):
            s += (f"; on the measured response (coherent up to {r.measured_up_to_hz:.4g} Hz) modulus margin "
                  f"{r.measured_modulus:.3g}")
            if math.isfinite(r.measured_phase_deg):
                s += f", phase margin {r.measured_phase_deg:.3g} deg"
        if r.controller != "arc" and not r.holds:
            s += "; the yardstick's bound: reported, not gated (only the emitted ARC's is)"
        out.append(s)
    return out


def limits_toml(spec: Spec, ident: Identification) -> str:
    """A ``limits.toml`` sketch for ``commission excite`` (CONTRACT §6) filled with what the spec and the log know.

    ``[limits]`` travel, v_max, a_max and u_max are the spec's envelope (the ones tune and
    validate used, q-unit and u-unit); ``[drive] sample_rate`` is the log's rate (Hz); ``[axis]``
    ``mass``, ``friction`` and ``viscous`` the identified M, fc and B.  Written by the one builder
    of the sketch, :func:`commission.excite.limits_toml_sketch` (identify's is the same).
    """
    from commission.excite import limits_toml_sketch

    def known(name: str) -> float | None:
        e = ident.parameters.get(name)
        return float(e.value) if e is not None else None

    return limits_toml_sketch(
        travel=spec.travel, v_max=spec.v_max, a_max=spec.a_max, u_max=spec.u_max, sample_rate=spec.sample_rate,
        M=known("M"), B=known("B"), fc=known("fc"), q_unit=ident.units.get("q", "m"), u_unit=ident.units.get("u", "V"),
        notes={"travel": "the spec's", "v_max": "the spec's", "a_max": "the spec's", "u_max": "the spec's",
               "sample_rate": "the log's rate", "mass": "identified", "friction": "identified Coulomb level",
               "viscous": "identified"})


#: The absolute error criteria of the gate: a loop held within the evidence that misses one of them
#: misses it for want of evidence (a faster loop would need the plant above the backed band).
ERROR_CRITERIA = ("e_F", "e_M", "e_rms")


def evidence_limited_line(result: Any) -> str | None:
    """One plain sentence when the gate failed on error limits while the loop was held within a
    band the log backs without broadband content (None otherwise).

    Above the backed band the plant is unknown, so the search and the gate hold the loop to
    ||W T|| < 1 there; on a log without a broadband segment that band ends at a few tens of hertz,
    and the error limits may then be out of reach at any gains.  The refusal is then for want of
    evidence, and the remedy is a recording, not a retune: said first, with the command.

    Parameters
    ----------
    result : commission.validate.ValidationResult
        Its ``evidence`` and ``verdict``.
    """
    ev = getattr(result, "evidence", None)
    if ev is None or not ev.applies or ev.source == "broadband":
        return None
    fails = [c for c in result.verdict.failures if c.criterion in ERROR_CRITERIA]
    if not fails:
        return None
    worst = max(fails, key=lambda c: c.value / c.limit if c.limit > 0 else math.inf)
    return (f"Missing evidence: the log has no broadband segment and backs the model only up to "
            f"{ev.top_hz:.3g} Hz, so the loop is held to robust stability above it (||W T|| < 1), and at that "
            f"bandwidth {len(fails)} error limit(s) are missed (worst: {worst.scenario} {worst.criterion} "
            f"{worst.detail}). Record the run `{excite_command()}` plans to raise the band, or relax the targets.")


def excite_command(out_dir: str = "excite") -> str:
    """The command that plans the run which raises the evidence (CONTRACT §6, planned face)."""
    return f"commission excite --spec limits.toml --out-dir {out_dir}"


def raise_evidence_line(evidence: Evidence, spec: Spec, ident: Identification) -> str:
    """One sentence: what to record to raise the evidence, with the limits.toml inline (for stdout)."""
    toml = "; ".join(line.split("#")[0].strip() for line in limits_toml(spec, ident).splitlines()
                     if line and not line.startswith("#"))
    have = (f"the log backs the model only to {evidence.top_hz:.3g} Hz" if evidence.applies
            else "the log backs no band of the model")
    if evidence.source == "broadband":
        have = f"the log's broadband segment backs the model to {evidence.top_hz:.3g} Hz"
    return (f"to certify a faster loop, raise the evidence ({have}): plan a broadband run with "
            f"`{excite_command()}` (limits.toml: {toml}; check the holding loop's bandwidth_hz), record it, "
            "then `commission run` on that log")


__all__ = ["departs_above_band", "departure_factor", "EVIDENCE_FACTOR", "ZETA_W", "Evidence", "EvidenceBound", "MeasuredResponse", "RobustStability", "SEARCH_ROOM",
           "W_INF", "evidence_checks", "evidence_lines", "evidence_of", "evidence_table", "excite_command", "limits_toml",
           "raise_evidence_line", "measured_margins", "weighted_peak", "evidence_limited_line", "ERROR_CRITERIA"]
