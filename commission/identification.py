"""The ``identify`` stage: log in, checked, fitted, bounded, ``ident.json`` out.

This module is the pipeline glue between the loaders (:mod:`commission.logs`,
:mod:`commission.checks`), the numerics (:mod:`commission.identify`) and the
artifact (:class:`commission.artifacts.Identification`).  Errors of the
numerics are re-raised with the file name so that the CLI can print one line.
"""

from __future__ import annotations

import dataclasses
import datetime as _dt
import hashlib
import math
import os
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Literal, Mapping, Sequence

import numpy as np

from commission import __version__
from commission.artifacts import Estimate, Identification, ThetaBox, mass_wording
from commission.checks import CheckReport, check_log, mass_plausibility_warnings
from commission.errors import DataError, IdentifiabilityError, SchemaError, UsageError
from commission.identify.bounds import ThetaBounds, friction_compensation, theta_bounds, theta_bounds_from
from commission.identify.errors import NotIdentifiableError, SignalError, StribeckNotIdentifiableError
from commission.identify.fit import AxisFit, MapFit, evaluate_segments, fit_friction_map, fit_segments
from commission.identify.friction import friction_compensation_curve, stribeck_friction
from commission.controllers.linear import rigid_frequency_response
from commission.identify.frf import MAX_MODES, EncoderNoise, FrequencyResponse, encoder_noise, frequency_response
from commission.identify.ls import ripple_name, ripple_pitches
from commission.identify import richer
from commission.identify.signals import quantization_step
from commission.identify.steady import FrictionMap, friction_map
from commission.logs import ExcitationLog, load_log
from commission.units import axis_units_context


#: Command units of CONTRACT §1.
U_UNITS = ("V", "N", "A", "Nm", "%")

#: Figures of one identified log (``identify --plot``; ``run`` writes them beside its report).
IDENT_FIGURE_NAMES = ("force_fit.png", "friction_curve.png", "residuals.png", "bode.png")
#: File extensions a folder given to ``identify`` is searched for.
LOG_EXTENSIONS = (".h5", ".hdf5", ".csv", ".mat", ".npy", ".npz")
#: A leg of a friction test is at constant speed when its speed, smoothed over
#: :data:`LEG_SMOOTHING` of its samples, stays within this fraction of the mean speed
#: on 90 % of the samples (wide enough for a 1-rpm velocity quantisation at 1-2 rpm).
LEG_SPEED_TOLERANCE = 0.5
LEG_SMOOTHING = 0.05
#: A measured position is also checked over this fraction of the samples ...
LEG_FINE_SMOOTHING = 0.01
#: ... but over no fewer samples than it takes to travel this many encoder steps.
LEG_FINE_COUNTS = 10
#: A fit leaving more than this fraction of the command unexplained is flagged (EMPS: 0.04).
POOR_FIT_RELATIVE_ERROR = 0.3
#: A parameter whose standard deviation exceeds this multiple of its value is flagged as not determined.
UNDETERMINED_REL_STD = 1.0
#: Parameters ``--fix`` accepts.
FIXABLE = ("M",)
#: Accepted range of each ``--fix`` value, u-unit·s²/m, both ends inclusive.  ``theta1 = 1/M``
#: is what tune and the controller work with, so M's range is the reciprocal of the range
#: the tune spec accepts for theta1 (``controller.theta1_0``, :data:`commission.spec.RANGES`):
#: whatever the unit of u, an axis outside it is a typo or a unit slip, and the arithmetic of
#: the fit (``M qdd`` squared and summed over the log) and of the theta box stays finite inside it.
FIX_RANGES = {"M": (1e-12, 1e12)}


@dataclass(frozen=True)
class BoundsOptions:
    """What the user declares about the operating range (Assumption 1).

    Attributes
    ----------
    k_sigma : float
        Standard deviations of the estimates covered by the box.
    model_margin : float
        Relative margin on M and B for model error (0.2 = +-20 %).
    payload_min, payload_max : float or None
        Added mass range in operation, u-unit s^2/m; ``payload_max`` None means
        the default of :func:`commission.identify.bounds.theta_bounds` (3 M).
    disturbance_bound : float or None
        Largest constant load force besides the offset, u-unit (None: 10 max(fc, fs)).
    """

    k_sigma: float = 3.0
    model_margin: float = 0.2
    payload_min: float = 0.0
    payload_max: float | None = None
    disturbance_bound: float | None = None


@dataclass(frozen=True)
class IdentifyOptions:
    """Everything ``commission identify`` (and ``run``'s identify stage) is told about a log.

    One definition for both commands; :meth:`kwargs` gives :func:`identify_log`'s keywords.

    Attributes
    ----------
    mapping : mapping of str to str
        Contract channel -> name in the file (``--map``).
    input_gain : float
        Multiplies u (``--input-gain``), u-unit per file unit.
    sample_rate : float or None
        Hz, for a file without ``t``.
    friction : {"auto", "coulomb", "stribeck"}
    ripple_pitch : tuple of float
        Force-ripple pitches, m (rad on a rotary axis); empty: none.
    validate_on : str or None
        Second log for the cross-test relative error.
    bounds : BoundsOptions
    u_unit, q_unit, fmt : str or None
        ``--u-unit``, ``--q-unit``, ``--format``.
    resample : float or None
        Hz (``--resample``).
    fix : mapping of str to float
        Known parameters (``--fix``).
    lead, gear : float or None
        ``--lead`` (m per load rad) and ``--gear`` (motor rad per load rad): a rotary
        log's angle converted before anything is fitted (:func:`convert_axis`).
    counts_per_rev : float or None
        ``--counts-per-rev``: the log's q is in encoder counts, read as rad on loading
        (:func:`commission.logs.load_log`), before ``gear`` and ``lead``.
    plan : mapping or None
        ``--plan``: the parsed plan.json of ``commission excite`` the one log was recorded from
        (:func:`commission.excite.load_plan_json`); None: a plan.json beside the log, if it matches.
    plan_path : str or None
        Where ``plan`` was read (recorded in ``frequency_response.plan``).
    """

    mapping: Mapping[str, str] = dataclasses.field(default_factory=dict)
    input_gain: float = 1.0
    sample_rate: float | None = None
    friction: Literal["coulomb", "stribeck", "auto"] = "auto"
    ripple_pitch: tuple[float, ...] = ()
    validate_on: str | None = None
    bounds: BoundsOptions = BoundsOptions()
    u_unit: str | None = None
    q_unit: str | None = None
    fmt: str | None = None
    resample: float | None = None
    fix: Mapping[str, float] = dataclasses.field(default_factory=dict)
    lead: float | None = None
    gear: float | None = None
    counts_per_rev: float | None = None
    terms: str = "auto"
    plan: Mapping[str, Any] | None = None
    plan_path: str | None = None

    def kwargs(self) -> dict[str, object]:
        """Keywords of :func:`identify_log` (``plan`` and ``plan_path`` only when a plan is given)."""
        extra: dict[str, object] = {} if self.plan is None else {"plan": self.plan, "plan_path": self.plan_path}
        return {**extra, "mapping": dict(self.mapping), "input_gain": self.input_gain, "sample_rate": self.sample_rate,
                "friction": self.friction, "ripple_pitch": self.ripple_pitch or None,
                "validate_on": self.validate_on, "bounds": self.bounds, "u_unit": self.u_unit, "q_unit": self.q_unit,
                "fmt": self.fmt, "resample": self.resample, "fix": dict(self.fix), "lead": self.lead,
                "gear": self.gear, "counts_per_rev": self.counts_per_rev, "terms": self.terms}


def convert_axis(logs: Sequence[ExcitationLog], lead: float | None, gear: float | None) -> list[ExcitationLog]:
    """A rotary log's motor angle as the load's angle (``--gear``) or the carriage's position (``--lead``).

    The encoder of a screw or geared drive usually sits on the motor, so the log holds the
    motor angle in rad, while the user may want the model (and every parameter, bound and
    figure after it) in the load's coordinate: the load angle ``q / gear`` [rad], or the
    carriage position ``q lead / gear`` [m] of a screw whose lead is ``lead`` m per rad of
    the screw (a 5 mm/rev screw: 0.005/(2π)).  ``q`` and ``q_ref`` are scaled; time and
    command are not, so M, B, the friction speeds and everything derived from them come
    out in the converted unit (M in u-unit·s²/m after ``--lead``).  Converting before the
    checks means the plausibility checks see the unit the model will use.

    Parameters
    ----------
    logs : sequence of ExcitationLog
        As loaded; all must be rotary (``q_unit_in_file == "rad"``) when ``lead`` or ``gear`` is given.
    lead : float or None
        m of carriage travel per rad of the load (the screw); None: stay rotary.
    gear : float or None
        Motor rad per load rad (> 0); None: 1.

    Returns
    -------
    list of ExcitationLog
        The logs, unchanged when neither is given; after ``lead`` their ``q_unit_in_file`` is ``"m"``.

    Raises
    ------
    UsageError
        A ratio that is not a positive finite number, or a log that is not in rad, named.
    """
    if lead is None and gear is None:
        return list(logs)
    for flag, v in (("--lead", lead), ("--gear", gear)):
        if v is not None and not (math.isfinite(v) and v > 0):
            raise UsageError(f"{flag} must be a positive finite number, got {v}")
    for lg in logs:
        if lg.q_unit_in_file != "rad":
            flag = "--lead" if lead is not None else "--gear"
            raise UsageError(f"{flag} converts a rotary log's angle (q in rad), but {lg.source}'s q is in "
                             f"{lg.q_unit_in_file}; drop {flag}, or give the log in rad (--q-unit rad)")
    k = (1.0 if lead is None else lead) / (1.0 if gear is None else gear)
    unit = "m" if lead is not None else "rad"
    return [dataclasses.replace(lg, q=lg.q * k, q_ref=None if lg.q_ref is None else lg.q_ref * k,
                                q_unit_in_file=unit) for lg in logs]


def _conversion_record(file_q_unit: str, lead: float | None, gear: float | None,
                       counts_per_rev: float | None = None) -> dict[str, object]:
    """ident.json's ``source.conversion``: what ``--counts-per-rev`` (on loading) and :func:`convert_axis` did.

    Written only when one of them did something.  One record for the whole chain,
    file unit to model unit (counts -> rad -> load rad -> m), each factor under its own
    key and null for a flag not given, so a reader can redo the conversion.
    """
    return {"from": file_q_unit, "to": "m" if lead is not None else "rad", "counts_per_rev": counts_per_rev,
            "lead_m_per_rad": lead, "gear_motor_rad_per_load_rad": gear}


def _file_q_unit(log: ExcitationLog, counts_per_rev: float | None) -> str:
    """ident.json's ``source.q_unit``: the unit of q in the file, ``"counts"`` under ``--counts-per-rev``."""
    return "counts" if counts_per_rev is not None else log.q_unit_in_file


def check_input_gain(input_gain: float, u_unit: str | None) -> None:
    """Refuse a gain that is not a positive finite number, or one that changes u's unit unnamed.

    ``--input-gain G`` turns the file's command into ``G x u``, whose unit is not the
    file's (volts times N/V are newtons): every artifact and report labels u with the
    unit after the gain, so a gain other than 1 needs ``--u-unit`` to name it.

    Parameters
    ----------
    input_gain : float
        ``--input-gain``, u-unit per file unit.
    u_unit : str or None
        ``--u-unit``: the unit of ``input_gain x u``.

    Raises
    ------
    UsageError
        Naming ``--input-gain`` or ``--u-unit``.
    """
    if not input_gain > 0 or not np.isfinite(input_gain):
        raise UsageError(f"--input-gain must be a positive finite number, got {input_gain}")
    if u_unit is not None and u_unit not in U_UNITS:
        raise UsageError(f"--u-unit must be one of {', '.join(U_UNITS)}, got {u_unit!r}")
    if u_unit is None and input_gain != 1.0:
        raise UsageError(f"--input-gain {input_gain:g} needs --u-unit (the unit of {input_gain:g} x u, e.g. N)")


def payload_from_kg(kg: float, force_constant: float) -> float:
    """Convert a payload in kg to the command-unit mass, u-unit s^2/m.

    Parameters
    ----------
    kg : float
        Added mass, kg.
    force_constant : float
        Force per command unit, N/u-unit.
    """
    if not force_constant > 0:
        raise UsageError(f"--force-constant must be > 0 N per u-unit, got {force_constant}")
    return kg / force_constant


@dataclass(frozen=True)
class IdentifyOutcome:
    """Everything the identify stage produced (the artifact and what plots need)."""

    ident: Identification
    fit: AxisFit
    log: ExcitationLog
    checks: CheckReport
    bounds: ThetaBounds | None
    frequency: FrequencyResponse | None


def _fit_with_context(logs: Sequence[ExcitationLog], *, friction: str,
                      ripple_pitch: float | tuple[float, ...] | None,
                      mass: float | None = None) -> tuple[AxisFit, list[str]]:
    """Fit ``logs`` (one segment each) with the friction model (``"auto"``: see :func:`identify_log`).

    Returns the fit and the warnings it adds.  ``mass`` given: M is known.  A log
    without usable acceleration content leaves M not identified
    (:attr:`AxisFit.not_identified`) rather than refused.  Numerics errors come back
    as the pipeline's, naming the file (the offending one when the numerics say which).
    """
    kw = {"ripple_pitch": ripple_pitch, "mass": mass, "allow_unidentified_mass": True,
          "velocity_logged": any(getattr(lg, "q_from_velocity", False) for lg in logs)}
    segments = [(lg.t, lg.q, lg.u) for lg in logs]
    try:
        try:
            model = "stribeck" if friction == "auto" else friction
            fit = fit_segments(segments, friction=model, **kw)  # type: ignore[arg-type]
            fc, fs = fit.parameters.get("fc"), fit.parameters.get("fs")
            if friction == "auto" and fc is not None and fs is not None and fs[0] < fc[0]:
                # Anti-Stribeck (friction rising towards low speed) is outside the model the
                # controller compensates; auto keeps the model it can trust.
                note = (f"friction auto: the Stribeck fit is anti-Stribeck (fs = {fs[0]:.4g} < fc = {fc[0]:.4g}: "
                        "friction rises at low speed); the Coulomb model was fitted instead "
                        "(--friction stribeck keeps the Stribeck fit)")
                return fit_segments(segments, friction="coulomb", **kw), [note]  # type: ignore[arg-type]
            return fit, []
        except StribeckNotIdentifiableError as exc:
            if friction != "auto":
                raise
            # A hump hidden by ripple or noise on the slow legs (2.9 sigma where 3 are asked) still
            # leaves M, B, fc and the offset well determined: commission with the Coulomb model.
            note = (f"friction auto: Stribeck curve not identifiable ({exc}); the Coulomb model was fitted "
                    f"instead (--friction stribeck refuses such a log)")
            return fit_segments(segments, friction="coulomb", **kw), [note]  # type: ignore[arg-type]
    except NotIdentifiableError as exc:
        raise IdentifiabilityError(f"{_name(logs)}: {exc}") from None
    except SignalError as exc:
        raise DataError(f"{_name(logs, exc.segment)}: {exc}") from None


def _name(logs: Sequence[ExcitationLog], segment: int | None = None) -> str:
    """The file an error names: the offending segment's, the only log's, or the first and how many more."""
    if segment is not None:
        return logs[segment].source
    return logs[0].source if len(logs) == 1 else f"{logs[0].source} (and {len(logs) - 1} more logs fitted together)"


def _joined(logs: Sequence[ExcitationLog]) -> ExcitationLog:
    """Several logs of one axis laid end to end (what summaries and plots show of a segmented fit).

    Times of a later log are shifted to follow the previous one by one sample
    period; positions and commands are as recorded.  Only for display: the fit
    treats every log as its own segment.  ``sha256`` is that of the logs' digests
    joined by commas (ident.json lists each file's own).
    """
    if len(logs) == 1:
        return logs[0]
    ts, end = [], None
    for lg in logs:
        shift = 0.0 if end is None else end + 1.0 / lg.sample_rate - float(lg.t[0])
        ts.append(lg.t + shift)
        end = float(ts[-1][-1])
    refs = [lg.q_ref for lg in logs]
    first = logs[0]
    return dataclasses.replace(
        first, t=np.concatenate(ts), q=np.concatenate([lg.q for lg in logs]), u=np.concatenate([lg.u for lg in logs]),
        q_ref=None if any(r is None for r in refs) else np.concatenate(refs),  # type: ignore[arg-type]
        source=" + ".join(lg.source for lg in logs),
        sha256=hashlib.sha256(",".join(lg.sha256 for lg in logs).encode()).hexdigest())


def _same_axis_units(logs: Sequence[ExcitationLog]) -> None:
    """Refuse logs that do not share their units (one axis: one u unit, all rotary or all linear)."""
    units = {(lg.u_unit, lg.q_unit_in_file == "rad") for lg in logs}
    if len(units) > 1:
        raise DataError(f"{logs[0].source}: the logs of one axis must share their units; found u in "
                        f"{sorted({u for u, _ in units})} and "
                        f"{'rotary and linear' if len({r for _, r in units}) > 1 else 'one'} axes")


#: Name of the plan file ``identify`` looks for beside a log (``commission excite`` writes it).
PLAN_BESIDE_NAME = "plan.json"
#: A log matches the plan beside it when its sample count is within this fraction of the plan's.
PLAN_BESIDE_SAMPLES_TOL = 0.01


def plan_beside(path: str | os.PathLike[str], lg: ExcitationLog) -> tuple[dict[str, Any] | None, str | None, str | None]:
    """The ``plan.json`` of ``commission excite`` beside a log, when the log is a recording of it.

    ``identify LOG`` without ``--plan`` still measures the frequency response on the plan's
    injection windows when the log's folder holds a plan.json whose sample rate is the log's
    (within 1e-6) and whose sample count is the log's within ``PLAN_BESIDE_SAMPLES_TOL``
    (the log starts with the plan, as ``--plan`` assumes): the command's level does not
    always show the injection (on a noisy encoder the holding loop's answer to the noise is
    of the injection's size), the plan does.  A plan.json that does not load or does not
    match is left alone, with a note saying why.

    Returns
    -------
    (plan, path, note)
        The parsed plan and its path (None, None when none is used) and a sentence for the
        warnings (None when there is nothing to say).
    """
    from commission.excite import load_plan_json

    cand = os.path.join(os.path.dirname(os.path.abspath(os.fspath(path))), PLAN_BESIDE_NAME)
    if not os.path.isfile(cand):
        return None, None, None
    try:
        plan = load_plan_json(cand)
    except SchemaError as exc:
        return None, None, f"{cand} beside the log is not used: {exc}"
    fs_plan, n_plan = plan.get("sample_rate"), plan.get("samples")
    if (not isinstance(fs_plan, (int, float)) or not isinstance(n_plan, int)
            or abs(fs_plan - lg.sample_rate) > 1e-6 * fs_plan
            or abs(lg.t.size - n_plan) > PLAN_BESIDE_SAMPLES_TOL * n_plan):
        return None, None, (f"{cand} beside the log is not used: the log ({lg.t.size} samples at "
                            f"{lg.sample_rate:.6g} Hz) is not a recording of it ({n_plan} samples at {fs_plan} Hz); "
                            f"give --plan to use it anyway")
    wins = [w for g in plan["segments"] if g.get("name") == "injection" for w in g.get("windows_s", [])]
    if not wins:
        return None, None, None
    return plan, cand, None


def _frequency_of(logs: Sequence[ExcitationLog], M: float, B: float,
                  max_modes: int = MAX_MODES) -> tuple[FrequencyResponse, ExcitationLog]:
    """The frequency response of the first log that holds a broadband segment, else of the longest log.

    The response is estimated within one recording (windows never span a join);
    several logs of one axis rarely all carry a broadband injection.  Returns the log used too.
    """
    if len(logs) == 1:
        return frequency_response(logs[0].t, logs[0].q, logs[0].u, M, B, max_modes=max_modes), logs[0]
    out = None
    for lg in sorted(logs, key=lambda lg: -lg.n):
        fr = frequency_response(lg.t, lg.q, lg.u, M, B, max_modes=max_modes)
        if fr.source == "broadband":
            return fr, lg
        out = out or (fr, lg)
    return out  # type: ignore[return-value]


def _encoder_noise(fr: FrequencyResponse, lg: ExcitationLog, quantization: float | None) -> EncoderNoise | None:
    """Encoder noise and quantization's share (:func:`commission.identify.frf.encoder_noise`) of the log ``fr`` used.

    The command's effect is taken out with the fitted model (modes and delay) where the log
    has a broadband segment, else with the rigid body.
    """
    Ts = 1.0 / fr.sample_rate
    if fr.fit is not None:
        def response(f: np.ndarray) -> np.ndarray:
            return fr.fit.response(fr.M, fr.B, Ts, f)  # type: ignore[union-attr]
    else:
        def response(f: np.ndarray) -> np.ndarray:
            return rigid_frequency_response(fr.M, fr.B, Ts, f)
    segs = [(int(np.searchsorted(lg.t, a)), int(np.searchsorted(lg.t, b)) + 1) for a, b in fr.segments]
    return encoder_noise(lg.q, lg.u, fr.sample_rate, response, quantization, segs)


def _evidence(logs: Sequence[ExcitationLog], freq: FrequencyResponse | None, fit: AxisFit, u_max: float | None,
              units: Mapping[str, str]) -> dict[str, object] | None:
    """ident.json's ``evidence``: what the log lacks and the ``excite`` run that supplies it (None: nothing).

    The machine's limits in the sketch are what the logs show (span, peak speed, peak
    acceleration from a cubic Savitzky-Golay fit over 20 ms) and the drive's command limit:
    ``--u-max``, else, for a command in volts scaled by ``--input-gain``, the usual +-10 V
    analog range times that gain (said as an assumption), else the logs' peak |u|.
    """
    from scipy.signal import savgol_filter

    from commission.next_steps import ANALOG_COMMAND_RANGE_V, excite_advice

    if freq is not None and freq.source == "broadband":
        return None
    first = logs[0]
    fs = float(first.sample_rate)
    travel = max(float(np.max(lg.q) - np.min(lg.q)) for lg in logs)
    win = max(7, int(round(0.02 * fs)) | 1)
    a_peak = max(float(np.max(np.abs(savgol_filter(lg.q, win, 3, deriv=2, delta=1.0 / fs)))) if lg.q.size > win else 0.0
                 for lg in logs)
    v_peak = max(float(np.max(np.abs(savgol_filter(lg.q, win, 3, deriv=1, delta=1.0 / fs)))) if lg.q.size > win else 0.0
                 for lg in logs)
    u_peak = max(float(np.max(np.abs(lg.u))) for lg in logs)
    u_unit = units["u"]
    if u_max is not None:
        source = "the drive's command limit (--u-max)"
    elif first.u_unit == "V" and first.input_gain != 1.0:
        u_max = ANALOG_COMMAND_RANGE_V * first.input_gain
        source = (f"assumed: the drive's +-{ANALOG_COMMAND_RANGE_V:g} V command range x --input-gain "
                  f"{first.input_gain:.6g} {u_unit}/V (the log peaks at {u_peak:.4g} {u_unit}; --u-max sets it)")
    else:
        source = f"the log's peak |u| (the drive may allow more: --u-max sets it)"
    p = fit.parameters
    rate = float(round(fs)) if abs(fs - round(fs)) <= 1e-3 * fs else fs  # 1000.016 Hz measured: a 1 kHz drive
    adv = excite_advice(freq.to_dict() if freq is not None else None, travel=travel, v_peak=v_peak,
                        a_peak=a_peak, u_peak=u_peak, u_max=u_max, u_max_source=source, sample_rate=rate,
                        M=p["M"][0] if "M" in p else None, B=p["B"][0] if "B" in p else None,
                        fc=p["fc"][0] if "fc" in p else None, q_unit=units["q"], u_unit=u_unit)
    return None if adv is None else adv.to_dict()


def parse_terms(terms: str | Sequence[str] | None) -> tuple[str, ...] | None:
    """``--terms``: ``auto`` (None: every switchable term, chosen by cross-validation), ``none``
    (the richer model off), or a comma-separated subset of :data:`richer.TERMS` to choose among."""
    if terms is None:
        return None
    items = [t.strip() for t in (terms.split(",") if isinstance(terms, str) else terms) if t.strip()]
    if items == ["auto"]:
        return None
    if items == ["none"]:
        return ()
    bad = [t for t in items if t not in richer.TERMS]
    if bad or not items:
        raise UsageError(f"--terms: expected auto, none or a comma-separated subset of {', '.join(richer.TERMS)}; "
                         f"got {terms!r}")
    return tuple(t for t in richer.TERMS if t in items)


def _rich_choice(logs: Sequence[ExcitationLog], fit: AxisFit, *, ripple_pitch: float | tuple[float, ...] | None,
                 allowed: tuple[str, ...]) -> tuple[richer.Selection, AxisFit | None]:
    """The delay-aware inverse dynamics chosen on the identification logs alone (:func:`richer.select_model`).

    Returns the selection and, when it chose more than the base model, the AxisFit that
    carries it into the pipeline: ``M``, the mean viscous ``B``, ``fc``, ``offset`` and,
    for a Stribeck term with ``fs >= fc``, ``fs, vs, xi`` (the plant simulator's and the
    controller's friction curve).  What the plant cannot represent (viscous asymmetry,
    position polynomial, drag, a Stribeck dip below ``fc``) stays in ident.json's
    ``model.inverse_dynamics`` only.  None when the base model was chosen: the
    existing fit stands.
    """
    model = richer.RichModel([(lg.t, lg.q, lg.u) for lg in logs], ripple_pitch=ripple_pitch,
                             bandwidth_hz=fit.bandwidth_hz)
    sel = richer.select_model(model, allowed)
    rf = sel.fit
    if not rf.terms:
        return sel, None
    params: dict[str, tuple[float, float]] = {}
    for nm in ("M", "B", "fc"):
        params[nm] = (rf.value(nm), float(rf.std[rf.names.index(nm)]))
    der = rf.derived()
    friction = "coulomb"
    if "fs" in der and der["fs"][0] >= rf.value("fc") and rf.vs is not None:
        params["fs"] = (der["fs"][0], der["fs"][1])
        params["vs"] = (rf.vs, rf.vs_std if rf.vs_std is not None else math.nan)
        params["xi"] = (richer.STRIBECK_XI, 0.0)
        friction = "stribeck"
    params["offset"] = (rf.value("offset"), float(rf.std[rf.names.index("offset")]))
    for k in range(len(rf.ripple_pitch)):
        # a sin x + b cos x = amp sin(x + phase); standard deviations by the delta method.
        i, j = rf.names.index(ripple_name("ripple_sin", k)), rf.names.index(ripple_name("ripple_cos", k))
        a, b = float(rf.theta[i]), float(rf.theta[j])
        amp = math.hypot(a, b)
        C = np.asarray(rf.cov)[np.ix_([i, j], [i, j])]
        ga = np.array([a, b]) / amp if amp > 0 else np.zeros(2)
        gp = np.array([-b, a]) / amp**2 if amp > 0 else np.zeros(2)
        params[ripple_name("ripple_amp", k)] = (amp, float(math.sqrt(max(ga @ C @ ga, 0.0))))
        params[ripple_name("ripple_phase", k)] = (math.atan2(b, a), float(math.sqrt(max(gp @ C @ gp, 0.0))))
    r = rf.residuals
    new = dataclasses.replace(fit, friction=friction, parameters=params, relative_error=rf.relative_error,
                              condition_number=rf.condition_number, residual_std=float(np.std(r, ddof=1)),
                              residuals=r, force_measured=rf.force_measured, force_fitted=rf.force_fitted)
    return sel, new


def _position_rmse(val_logs: Sequence[ExcitationLog], models: Mapping[str, richer.RichFit]) -> dict[str, object]:
    """Open-loop position-simulation RMSE of each model under the validation logs' commands, m."""
    out: dict[str, object] = {"init_samples": richer.SIM_INIT_SAMPLES, "unit": "m",
                              "what": "open-loop simulation under the validation log's command, state from the "
                                      "filtered log at the end of the initialisation window, RMSE after it"}
    for name, rf in models.items():
        sq, n = 0.0, 0
        for lg in val_logs:
            sim = richer.simulate_position(rf, lg.t, lg.q, lg.u)
            m = lg.t.size - sim.init_samples - 1
            sq += sim.rmse**2 * m
            n += m
        out[name] = math.sqrt(sq / n) if n else None
    return out


def _coulomb_richfit(fit: AxisFit) -> richer.RichFit:
    """An IDIM-LS (Coulomb) AxisFit as a :class:`richer.RichFit` with the published alignment (for simulation)."""
    p = fit.parameters
    return richer.published_form(p["M"][0], p["B"][0], p["fc"][0], p["offset"][0], None, fit.sample_rate)


def _delay_agreement(rf: richer.RichFit, freq: FrequencyResponse | None) -> list[str]:
    """A warning when the frequency response's input delay and the least-squares one disagree."""
    if freq is None or "delay" not in rf.terms:
        return []
    d = freq.to_dict().get("model")
    d_s = d.get("delay_s") if isinstance(d, dict) else None
    if d_s is None:
        return []
    d_frf = float(d_s) * rf.sample_rate
    tol = max(3.0 * rf.delay_std_samples, 0.5)
    if abs(float(d_frf) - rf.delay_samples) > tol:
        return [f"delay: the least squares give {rf.delay_samples:.2f} ± {rf.delay_std_samples:.2f} samples beyond "
                f"the hold, the frequency response {float(d_frf):.2f} samples (they differ by more than "
                f"{tol:.2f} samples); the plant takes the frequency response's"]
    return []



def identify_log(
    path: str | Sequence[str],
    *,
    mapping: Mapping[str, str] | None = None,
    input_gain: float = 1.0,
    sample_rate: float | None = None,
    friction: Literal["coulomb", "stribeck", "auto"] = "auto",
    ripple_pitch: float | Sequence[float] | None = None,
    validate_on: str | Sequence[str] | None = None,
    bounds: BoundsOptions = BoundsOptions(),
    u_unit: str | None = None,
    q_unit: str | None = None,
    fmt: str | None = None,
    resample: float | None = None,
    fix: Mapping[str, float] | None = None,
    lead: float | None = None,
    gear: float | None = None,
    counts_per_rev: float | None = None,
    max_modes: int | None = None,
    u_max: float | None = None,
    plan: Mapping[str, Any] | None = None,
    terms: str | Sequence[str] | None = "auto",
    plan_path: str | None = None,
    _loaded: tuple[Sequence[ExcitationLog], Sequence[ExcitationLog]] | None = None,
) -> IdentifyOutcome:
    """Load, check and identify one excitation log, or several logs of one axis fitted together.

    Several logs (``path`` a sequence) are fitted together, each as its own segment
    (:func:`commission.identify.fit.fit_segments`): every log is filtered,
    differentiated and decimated on its own, so nothing is filtered across the join
    between two recordings (where the position may jump and the command step), and
    the regression rows of all logs form one least-squares problem.

    Parameters
    ----------
    path : str or sequence of str
        Excitation log(s) (HDF5, CSV or MAT; CONTRACT §1); folders already expanded
        (:func:`expand_log_paths`).  One sample rate for all.
    mapping : mapping, optional
        Contract channel name -> name in the file.
    input_gain : float
        Multiplies ``u`` before identification (u-unit per file unit).
    sample_rate : float, optional
        Hz, for a file without ``t``.
    friction : {"auto", "coulomb", "stribeck"}
        Friction model.  ``"auto"``: the Stribeck curve when the log supports it; when its
        Stribeck-specific checks refuse it (no significant hump, too few slow samples, ``vs``
        on the edge of the speeds seen) the Coulomb model, with a warning in ident.json.
        ``"stribeck"`` refuses instead.
    ripple_pitch : float or sequence of float, optional
        Force-ripple pitch(es), m (``--ripple-pitch``, repeatable): one sinusoid per pitch.
        The first is the ripple the simulator uses (``model.ripple_pitch``/``ripple_amp``).
    validate_on : str or sequence of str, optional
        Other log(s) for the cross-test relative error (same mapping and gain; several
        are segments, as the identification logs).
    bounds : BoundsOptions
        Declared operating range.
    u_unit : {"V", "N", "A", "Nm", "%"}, optional
        Unit of ``u`` after ``input_gain``; default the file's unit, allowed only
        when ``input_gain`` is 1 (:func:`check_input_gain`).
    q_unit : {"m", "mm", "um", "rad"}, optional
        Unit of ``q`` in files without a ``q_unit`` attribute (CSV, v5 MAT); default m
        (``"rad"``: a rotary axis).
        Applies to ``validate_on`` too.
    fmt : {"hdf5", "csv", "mat", "epos"}, optional
        Forces the log format (``--format``); default: recognised from the content
        (EPOS recorder files) or the extension.  Applies to ``validate_on`` too.
    resample : float, optional
        Hz: interpolate the log (and ``validate_on``) onto a uniform grid first
        (:func:`resample_log`), for irregular time stamps.
    fix : mapping, optional
        Known parameters (``{"M": u-unit s^2/m}``, ``--fix``), not fitted.
    lead, gear : float, optional
        ``--lead`` (m per load rad) and ``--gear`` (motor rad per load rad): the rotary
        log(s), ``validate_on`` too, converted first (:func:`convert_axis`); ``ripple_pitch``
        and ``fix`` are then in the converted unit.
    counts_per_rev : float, optional
        ``--counts-per-rev``: q (and q_ref) of every log in encoder counts, N per
        revolution, read as rad (:func:`commission.logs.load_log`); ``gear`` and ``lead``
        apply after it.
    max_modes : int, optional
        ``--max-modes``: most structural modes the frequency response keeps (default
        :data:`commission.identify.frf.MAX_MODES`); modes beyond it are warned about, each
        named by its frequency.
    u_max : float, optional
        ``--u-max``: the drive's command limit, u-unit, for the ``commission excite`` sketch
        that a log without a broadband segment gets (``evidence``; :func:`_evidence`).
    plan : mapping, optional
        A parsed plan.json (:func:`commission.excite.load_plan_json`) the one log was recorded
        from: the frequency response is estimated on its injection windows
        (:func:`commission.excite.injection_ranges`) instead of the segments the command's level shows.
        Without it, a plan.json beside the one log is used when the log is a recording of it
        (:func:`plan_beside`).
    plan_path : str, optional
        Where ``plan`` was read: recorded as ``frequency_response.plan``.
    terms : str or sequence of str
        ``--terms`` (:func:`parse_terms`), with ``friction="auto"`` only: the switchable
        terms of the delay-aware inverse dynamics (:mod:`commission.identify.richer`)
        among which blocked cross-validation on the identification log(s) chooses;
        ``"auto"`` all of them, ``"none"`` none (the model of ``friction="auto"``
        before them).  Used on logs fitted by the whole-log (dynamic) method, with M
        fitted; the validation logs are read only after the choice.

    A log without usable acceleration content (slow constant-speed runs) leaves M not
    identified: ``parameters.M`` null with the reason in ``not_identified``, and no
    theta, box or frequency response (they need M); the rest is still identified.

    Returns
    -------
    IdentifyOutcome
        With several logs, ``log`` is the logs laid end to end (for summaries and
        plots) and ``checks`` the first log's report.
    """
    paths = [path] if isinstance(path, (str, os.PathLike)) else [os.fspath(p) for p in path]
    val_paths = ([] if validate_on is None else [validate_on] if isinstance(validate_on, (str, os.PathLike))
                 else list(validate_on))
    if not paths:
        raise UsageError("identify: no log given")
    try:
        pitches = ripple_pitches(ripple_pitch)
    except ValueError:
        raise UsageError(f"--ripple-pitch must be > 0 (m, or rad on a rotary axis), got {ripple_pitch}") from None
    ripple_pitch = (pitches[0] if len(pitches) == 1 else pitches) if pitches else None
    check_input_gain(input_gain, u_unit)
    load = dict(mapping=mapping, input_gain=input_gain, sample_rate=sample_rate, q_unit=q_unit, fmt=fmt,
                counts_per_rev=counts_per_rev)
    logs = list(_loaded[0]) if _loaded is not None else [load_log(p, **load) for p in paths]  # type: ignore[arg-type]
    file_q_unit = _file_q_unit(logs[0], counts_per_rev)
    logs = convert_axis(logs, lead, gear)
    if resample is not None:
        logs = [resample_log(lg, resample) for lg in logs]
    all_checks = [check_log(lg) for lg in logs]
    checks = all_checks[0]
    _same_axis_units(logs)
    # Load and check the validation logs before the (long) fit: bad input fails fast.
    val_logs = (list(_loaded[1]) if _loaded is not None
                else [load_log(p, **load) for p in val_paths])  # type: ignore[arg-type]
    val_logs = convert_axis(val_logs, lead, gear)
    if resample is not None:
        val_logs = [resample_log(lg, resample) for lg in val_logs]
    for lg in val_logs:
        check_log(lg)
    if friction not in ("auto", "coulomb", "stribeck"):
        raise UsageError(f"--friction: expected auto, coulomb or stribeck, got {friction!r}")
    fix = dict(fix or {})
    allowed = parse_terms(terms)
    with axis_units_context(_units(u_unit, logs[0])["q"]):  # the numerics' messages in the axis's unit
        fit, friction_warnings = _fit_with_context(logs, friction=friction, ripple_pitch=ripple_pitch,
                                                   mass=fix.get("M"))
        idim_fit = fit
        selection: richer.Selection | None = None
        if (friction == "auto" and allowed != () and fit.method == "dynamic" and not fix
                and not fit.not_identified):
            # Chosen on the identification logs alone: val_logs are not passed.
            try:
                selection, rich_fit = _rich_choice(logs, fit, ripple_pitch=ripple_pitch,
                                                   allowed=richer.TERMS if allowed is None else allowed)
            except (NotIdentifiableError, SignalError) as exc:
                friction_warnings.append(f"terms: the delay-aware model was not fitted ({exc})")
                rich_fit = None
            if rich_fit is not None:
                fit = rich_fit
    has_mass = "M" in fit.parameters
    val_err = None
    rich_chosen = selection is not None and fit is not idim_fit
    if val_logs:
        try:
            val_err = (richer.relative_error_on(selection.fit, [(lg.t, lg.q, lg.u) for lg in val_logs],  # type: ignore[union-attr]
                                                bandwidth_hz=fit.bandwidth_hz) if rich_chosen
                       else evaluate_segments(fit, [(lg.t, lg.q, lg.u) for lg in val_logs]))
        except SignalError as exc:
            raise DataError(f"{_name(val_logs, exc.segment)}: {exc}") from None
        except NotIdentifiableError as exc:
            raise DataError(f"{_name(val_logs)}: {exc}") from None
    tb: ThetaBounds | None = None
    if has_mass:
        try:
            tb = theta_bounds(
                fit,
                k_sigma=bounds.k_sigma,
                model_margin=bounds.model_margin,
                payload_min=bounds.payload_min,
                payload_max=bounds.payload_max,
                disturbance_bound=bounds.disturbance_bound,
            )
        except ValueError as exc:
            raise UsageError(f"bounds: {exc}") from None
    comp = friction_compensation(fit)
    # What the rigid model lacks: the measured response u -> q against M, B (identify/frf.py).
    freq, noise = None, None
    if has_mass:
        modes = MAX_MODES if max_modes is None else max_modes
        if plan is None and len(logs) == 1:
            # A log recorded from an excite plan, kept beside its plan.json: the plan says where the
            # injection is even where the command's level does not show it (a noisy encoder's feedback).
            plan, plan_path, note = plan_beside(paths[0], logs[0])
            if note:
                friction_warnings.append(note)
        if plan is not None:
            # The excitation plan says where its injection is (commission excite; identify --plan).
            from commission.excite import injection_ranges

            if len(logs) != 1:
                raise UsageError(f"--plan: takes one log recorded from the plan, got {len(logs)}")
            freq, freq_log = frequency_response(logs[0].t, logs[0].q, logs[0].u, fit.parameters["M"][0],
                                                fit.parameters["B"][0], max_modes=modes,
                                                ranges=injection_ranges(plan, logs[0].t)), logs[0]
        else:
            freq, freq_log = _frequency_of(logs, fit.parameters["M"][0], fit.parameters["B"][0], modes)
        noise = _encoder_noise(freq, freq_log, checks.quantization_step)

    if rich_chosen:
        friction_warnings += _delay_agreement(selection.fit, freq)  # type: ignore[union-attr]
    params: dict[str, Estimate | None] = {}
    for name in ("M", "B", "fc", "fs", "vs", "xi", "offset"):
        v = fit.parameters.get(name)
        params[name] = Estimate(float(v[0]), float(v[1])) if v is not None else None

    log_warnings = [w if len(logs) == 1 else f"{c.source}: {w}" for c in all_checks for w in c.warnings]
    warnings = (friction_warnings + log_warnings + list(fit.warnings)
                + fit_quality_warnings({k: v for k, v in fit.parameters.items() if k not in fix},
                                       fit.relative_error, fit.condition_number)
                + mass_plausibility_warnings(_units(u_unit, logs[0]),
                                             fit.parameters["M"][0] if has_mass and "M" not in fix else None)
                + (freq.warnings if freq is not None else []))
    several, val_several = len(logs) > 1, len(val_logs) > 1
    extra: dict[str, object] = {
        "tool": {"name": "commission", "version": __version__},
        "created_utc": _dt.datetime.now(_dt.timezone.utc).strftime("%Y-%m-%dT%H:%M:%SZ"),
        "source": {
            "path": [str(p) for p in paths] if several else str(paths[0]),
            "sha256": [lg.sha256 for lg in logs] if several else logs[0].sha256,
            "n_samples": int(sum(lg.t.size for lg in logs)),
            "sample_rate": float(logs[0].sample_rate),
            "input_gain": float(input_gain),
            "mapping": dict(mapping or {}),
            "q_unit": file_q_unit,
            "resampled_hz": resample,
        },
        "validation_source": (
            {"path": [str(p) for p in val_paths] if val_several else str(val_paths[0]),
             "sha256": [lg.sha256 for lg in val_logs] if val_several else val_logs[0].sha256}
            if val_logs else None
        ),
        "model": {
            "friction": fit.friction,
            "friction_requested": friction,
            "method": fit.method,
            "ripple_pitch": pitches[0] if pitches else None,
            "ripple_amp": _maybe(fit.parameters.get("ripple_amp")),
            "ripple_phase": _maybe(fit.parameters.get("ripple_phase")),
            "ripple_harmonics": [
                {"pitch": p, "amp": _maybe(fit.parameters.get(ripple_name("ripple_amp", k))),
                 "phase": _maybe(fit.parameters.get(ripple_name("ripple_phase", k)))}
                for k, p in enumerate(pitches)],
            "residual_std": fit.residual_std,
            "steady_points": int(fit.steady_velocity.size),
            "v_max": fit.v_max,
            "velocity_resolution": fit.velocity_resolution,
            "cutoff_hz": fit.cutoff_hz,
            "decimation": fit.decimation,
        },
        "encoder": {
            "quantization": checks.quantization_step,
            "apparent_resolution": checks.apparent_resolution,
            **(noise.to_dict() if noise is not None else {}),
        },
        "bounds": {} if tb is None else _bounds_record(bounds, tb),
        "friction_compensation_rms_error": comp.rms_error,
        "frequency_response": ({**freq.to_dict(), "plan": plan_path} if plan_path is not None
                               else freq.to_dict()) if freq is not None else None,
        "evidence": _evidence(logs, freq, fit, u_max, _units(u_unit, logs[0])),
        "not_identified": dict(fit.not_identified),
        "warnings": warnings,
    }
    if several:
        extra["model"]["segments"] = [int(lg.t.size) for lg in logs]  # type: ignore[index]
    if selection is not None:
        extra["model_selection"] = selection.to_dict()
        if rich_chosen:
            extra["model"]["inverse_dynamics"] = selection.fit.to_dict()  # type: ignore[index]
    if val_logs and has_mass and fit.method == "dynamic" and "M" not in fix:
        models = {"rmse": selection.fit if rich_chosen else _coulomb_richfit(fit)}  # type: ignore[union-attr]
        if idim_fit.friction == "coulomb" or rich_chosen:
            ref = idim_fit if idim_fit.friction == "coulomb" else fit_segments(
                [(lg.t, lg.q, lg.u) for lg in logs], friction="coulomb", ripple_pitch=ripple_pitch)
            models["reference_rmse"] = _coulomb_richfit(ref)
        if fit.friction == "coulomb" or rich_chosen:
            extra["position_simulation"] = {**_position_rmse(val_logs, models),
                                            "reference": "IDIM-LS (M, B, fc, offset) fitted to the same log"}
    if fix:
        extra["model"]["fixed"] = dict(fix)  # type: ignore[index]
    if lead is not None or gear is not None or counts_per_rev is not None:
        extra["source"]["conversion"] = _conversion_record(file_q_unit, lead, gear,  # type: ignore[index]
                                                           counts_per_rev)
    if extra["evidence"] is None:
        del extra["evidence"]
    if tb is None:
        del extra["bounds"], extra["frequency_response"]  # both need M
    if tb is not None:
        tb = _clip_negative_viscous(tb, params, extra, warnings)
    theta = None if tb is None else _theta_box(tb, _name(logs), fit)
    ident = Identification(
        units=_units(u_unit, logs[0]),
        parameters=params,
        relative_error=fit.relative_error,
        condition_number=fit.condition_number,
        validation_relative_error=val_err,
        theta=theta,
        delta_d=tb.delta_d if tb is not None else None,
        fric_level=comp.level,
        fric_slope=comp.slope,
        extra=extra,
    )
    return IdentifyOutcome(ident=ident, fit=fit, log=_joined(logs), checks=checks, bounds=tb, frequency=freq)


def _bounds_record(bounds: BoundsOptions, tb: ThetaBounds) -> dict[str, object]:
    """ident.json's ``bounds``: the declared settings and the ranges the theta box covers."""
    return {"k_sigma": bounds.k_sigma, "model_margin": bounds.model_margin, "mass_range": list(tb.mass_range),
            "viscous_range": list(tb.viscous_range), "disturbance_range": list(tb.disturbance_range),
            "disturbance_bound": tb.disturbance_bound, "disturbance_bound_defaulted": tb.disturbance_bound_defaulted,
            # The payload range the box covers and whether it was defaulted (tune may then narrow it to what
            # the controller can certify, commission.robustness.certified_payload).
            "payload_range": [tb.payload_range[0], tb.payload_range[1]], "payload_defaulted": tb.payload_defaulted}


def _units(u_unit: str | None, log: ExcitationLog) -> dict[str, str]:
    """ident.json's ``units``: u after the gain (``--u-unit``, else the file's), q in m or rad."""
    return {"u": u_unit or log.u_unit, "q": "rad" if log.q_unit_in_file == "rad" else "m"}


def _clip_negative_viscous(tb: ThetaBounds, params: dict[str, Estimate | None], extra: dict[str, object],
                           warnings: list[str]) -> ThetaBounds:
    """A negative viscous estimate whose confidence interval reaches B > 0: the physical box, not a refusal.

    A viscous coefficient below zero (friction that pushes the axis along) is not physical; a fit
    returns one when the rigid model explains the log poorly (structural modes, a high rate).  The
    box already holds only B >= 0 (:func:`identify.bounds.theta_bounds_from` cuts its lower end at 0),
    and when its upper end is above 0 the estimate's interval B + k_sigma std reaches physical values:
    the nominal B is then clipped to the box's lower end (>= 0), which lies inside that interval's
    physical part, and the box is kept.  ``bounds.viscous_clipped`` records the estimate and a warning
    says so.  An interval entirely below zero (upper end 0) is still refused by :func:`_theta_box`.
    """
    est = params.get("B")
    if est is None or not tb.nominal[1] < tb.theta_min[1] or not tb.theta_max[1] > 0:
        return tb
    b_phys = float(tb.viscous_range[0])
    m = 1.0 / tb.nominal[0]
    params["B"] = Estimate(b_phys, est.std)
    bounds = extra.get("bounds")
    if isinstance(bounds, dict):
        bounds["viscous_clipped"] = {"estimate": est.value, "std": est.std, "clipped_to": b_phys}
    warnings.append(f"B: the fit's viscous coefficient {est.value:.4g} +- {est.std:.2g} is negative (not physical); "
                    f"its interval reaches B > 0, so B is taken as {b_phys:.4g}, the lower end of the physical box "
                    f"[{tb.viscous_range[0]:.4g}, {tb.viscous_range[1]:.4g}] (ident.json bounds.viscous_clipped); "
                    f"the rigid model explains this log poorly: record a log with a broadband segment "
                    f"(commission excite)")
    return dataclasses.replace(tb, nominal=(tb.nominal[0], b_phys / m, tb.nominal[2]))


def _theta_box(tb: ThetaBounds, path: str, fit: AxisFit) -> ThetaBox:
    try:
        return ThetaBox(tb.nominal, tb.theta_min, tb.theta_max)
    except ValueError as exc:
        # E.g. a negative B from a log the rigid model does not explain: no controller can use it.
        raise DataError(f"{path}: the identified parameters give no usable theta box ({exc}); "
                        f"M = {fit.parameters['M'][0]:.4g}, B = {fit.parameters['B'][0]:.4g}, relative error "
                        f"{fit.relative_error:.3g}: the model does not explain this log") from None


#: Largest accepted --resample rate as a multiple of the log's median rate (interpolation adds no information).
MAX_RESAMPLE_FACTOR = 10.0


def resample_log(log: ExcitationLog, rate: float) -> ExcitationLog:
    """The log on the uniform grid ``t[0] + k / rate`` by linear interpolation (``--resample``).

    For logs whose time stamps are irregular (host polling over USB, dropped samples):
    q, u (and q_ref) are interpolated linearly between the recorded samples.  A rate
    far above the log's median rate adds samples but no information, so it is refused.

    Parameters
    ----------
    log : ExcitationLog
    rate : float
        Hz.
    """
    if not (math.isfinite(rate) and rate > 0):
        raise UsageError(f"--resample must be a positive rate in Hz, got {rate}")
    t = np.asarray(log.t)
    if t.size < 2 or not np.all(np.isfinite(t)) or not np.all(np.diff(t) > 0):
        raise DataError(f"{log.source}: channel t: --resample needs strictly increasing finite time stamps")
    median_rate = 1.0 / float(np.median(np.diff(t)))
    if rate > MAX_RESAMPLE_FACTOR * median_rate:
        raise UsageError(f"--resample {rate:g} Hz is more than {MAX_RESAMPLE_FACTOR:g} x the log's median rate "
                         f"{median_rate:.4g} Hz")
    n = int(math.floor((t[-1] - t[0]) * rate + 1e-9)) + 1
    tu = t[0] + np.arange(n) / rate

    def interp(x: np.ndarray | None) -> np.ndarray | None:
        return None if x is None else np.interp(tu, t, x)

    return dataclasses.replace(log, t=tu, q=interp(log.q), u=interp(log.u), q_ref=interp(log.q_ref),
                               sample_rate=float(rate))


def expand_log_paths(paths: Sequence[str]) -> list[str]:
    """The log files named by ``paths``: files as given, folders as their log files (sorted by name).

    The same file reached twice -- given twice, given with a folder that holds it,
    or through a symlink or a hard link -- is refused: its samples would be fitted
    twice, and the standard deviations (hence the theta box) would shrink by sqrt(2)
    with nothing to show for it.  Files are compared by device and inode, so every
    spelling of one file is caught.

    Raises
    ------
    UsageError
        A path that does not exist, a folder without a log file, or one file twice
        (naming both spellings).
    """
    out: list[str] = []
    seen: dict[tuple[int, int], str] = {}

    def add(name: str, via: str | None) -> None:
        spelled = name if via is None else f"{name} (in the folder {via})"
        try:
            st = os.stat(name)
        except OSError:
            st = None  # unreadable: the reader names it
        if st is not None:
            key = (st.st_dev, st.st_ino)
            if key in seen:
                raise UsageError(f"{seen[key]} and {spelled}: the same file given twice; "
                                 "give each log once (its samples would be fitted twice)")
            seen[key] = spelled
        out.append(name)

    for p in paths:
        path = Path(p)
        if path.is_dir():
            found = sorted((f for f in path.iterdir() if f.is_file() and f.suffix.lower() in LOG_EXTENSIONS),
                           key=lambda f: f.name)
            if not found:
                raise UsageError(f"{p}: a folder without log files ({', '.join(LOG_EXTENSIONS)})")
            for f in found:
                add(str(f), str(p))
        elif path.exists():
            add(str(p), None)
        else:
            raise UsageError(f"{p}: no such file or folder")
    return out


def parse_fix(items: Sequence[str]) -> dict[str, float]:
    """``["M=0.027"]`` -> ``{"M": 0.027}`` (``--fix``; values of :data:`FIXABLE` within :data:`FIX_RANGES`).

    A parameter given twice is refused rather than the last one kept: the two
    values disagree (or one is a typo), and which one the user meant is theirs
    to say.  A value outside its range is refused by name (the range and why
    are at :data:`FIX_RANGES`).

    Raises
    ------
    UsageError
        Naming the ``--fix`` item.
    """
    out: dict[str, float] = {}
    given: dict[str, str] = {}
    for item in items:
        name, sep, value = item.partition("=")
        name = name.strip()
        if not sep or name not in FIXABLE:
            raise UsageError(f"--fix {item!r}: expected NAME=VALUE with NAME one of {', '.join(FIXABLE)}")
        if name in given:
            raise UsageError(f"--fix {name}: given twice ({given[name]!r} and {item!r}); give it once")
        try:
            v = float(value)
        except ValueError:
            raise UsageError(f"--fix {item!r}: {value!r} is not a number") from None
        lo, hi = FIX_RANGES[name]
        if not (math.isfinite(v) and v > 0):
            raise UsageError(f"--fix {item!r}: {name} must be a positive finite number (u-unit·s²/m)")
        if not lo <= v <= hi:
            raise UsageError(f"--fix {item!r}: {name} = {v:g} is outside the plausible range [{lo:g}, {hi:g}] "
                             f"u-unit·s²/m (theta1 = 1/{name} must lie in tune's range for theta1)")
        given[name], out[name] = item, v
    return out


@dataclass(frozen=True)
class LegsOutcome:
    """A friction test identified from several logs, one constant-speed leg each."""

    ident: Identification
    logs: tuple[ExcitationLog, ...]
    fmap: FrictionMap
    fit: MapFit
    excluded: tuple[str, ...]


def _smoothed_speed(log: ExcitationLog, w: int) -> np.ndarray:
    """The difference speed ``dq/dt`` averaged over ``w`` samples (edges padded with their own value)."""
    v = np.gradient(log.q, log.t)
    kernel = np.ones(w) / w
    return np.convolve(np.pad(v, (w // 2, w - 1 - w // 2), mode="edge"), kernel, mode="valid")


def _where(paths: Sequence[str]) -> str:
    """What a refusal about several logs names: their common folder, or the first file and a count."""
    paths = [os.fspath(p) for p in paths]
    if len(paths) == 1:
        return paths[0]
    folders = {os.path.dirname(p) for p in paths}
    if len(folders) == 1 and next(iter(folders)):
        return f"{next(iter(folders))} ({len(paths)} logs)"
    return f"{paths[0]} and {len(paths) - 1} other logs"


def _named_legs(fmap: FrictionMap, legs: Sequence[ExcitationLog], speed_unit: str, k: int = 2) -> str:
    """The ``k`` slowest legs each way, by file and mean speed: the ones a Stribeck verdict rests on."""
    out = []
    for sign, word in ((1, "forward"), (-1, "backward")):
        idx = [i for i in np.argsort(np.abs(fmap.velocity)) if np.sign(fmap.velocity[i]) == sign][:k]
        if idx:
            out.append(f"{word} " + ", ".join(f"{os.path.basename(legs[i].source)} at {fmap.velocity[i]:.3g} "
                                              f"{speed_unit}" for i in idx))
        else:
            out.append(f"no leg {word}")
    return "slowest legs: " + "; ".join(out)


def _stalled(log: ExcitationLog) -> bool:
    """The position never moves by more than two encoder steps (a leg that did not run)."""
    quant = quantization_step(log.q)
    return bool(np.ptp(log.q) <= 2.0 * (quant or 0.0))


def leg_refusal(log: ExcitationLog) -> str | None:
    """Why ``log`` is not a constant-speed leg of a friction test; None if it is one (or a stalled one).

    A leg moves one way at one speed.  Three tests, each with the figure that failed:

    - it does not reverse: its speed, smoothed over :data:`LEG_SMOOTHING` of the
      samples, never takes the opposite sign of the mean speed (a run that returns to
      its start, mean speed 0 after moving, is an excitation, not a stalled leg);
    - that smoothed speed stays within :data:`LEG_SPEED_TOLERANCE` of the mean on
      90 % of the samples (wide, for a recorder's 1-rpm velocity quantum at 1-2 rpm);
    - a measured position (not integrated from a recorded velocity) is also checked
      on a finer scale, :data:`LEG_FINE_SMOOTHING` of the samples but never fewer than
      :data:`LEG_FINE_COUNTS` encoder steps of travel: a one-direction run whose speed
      varies along the way (a motor that nearly stalls on each cog, a speed ramp)
      averages to a steady speed over the coarse window, not over this one.

    A stalled leg (the position never moves by more than two encoder steps) is a leg:
    :func:`identify_legs` leaves it out with a warning.
    """
    if log.n < 2 or not (np.all(np.isfinite(log.t)) and np.all(np.isfinite(log.q))):
        return "fewer than 2 finite samples of t and q"
    if _stalled(log):
        return None
    v_mean = (log.q[-1] - log.q[0]) / (log.t[-1] - log.t[0])
    if v_mean == 0.0:
        return "it ends where it started after moving (mean speed 0)"
    w = max(3, int(LEG_SMOOTHING * log.n))
    smooth = _smoothed_speed(log, w)
    back = int(np.sum(np.sign(smooth) == -np.sign(v_mean)))
    if back:
        return f"it reverses (its smoothed speed is opposite the mean speed on {back} of {log.n} samples)"
    spread = float(np.quantile(np.abs(smooth - v_mean) / abs(v_mean), 0.9))
    if spread > LEG_SPEED_TOLERANCE:
        return (f"its smoothed speed departs from the mean by {spread * 100:.0f} % or more on 10 % of the samples "
                f"(at most {LEG_SPEED_TOLERANCE * 100:.0f} %)")
    if not log.q_from_velocity:
        quant = quantization_step(log.q)
        rate = log.sample_rate if math.isfinite(log.sample_rate) else (log.n - 1) / (log.t[-1] - log.t[0])
        w_counts = math.ceil(LEG_FINE_COUNTS * quant * rate / abs(v_mean)) if quant is not None else 0
        w_fine = max(3, int(LEG_FINE_SMOOTHING * log.n), w_counts)
        if w_fine < w:
            fine = float(np.quantile(np.abs(_smoothed_speed(log, w_fine) - v_mean) / abs(v_mean), 0.9))
            if fine > LEG_SPEED_TOLERANCE:
                return (f"its speed varies along the way: averaged over {w_fine / rate:.3g} s it departs from the "
                        f"mean by {fine * 100:.0f} % or more on 10 % of the samples "
                        f"(at most {LEG_SPEED_TOLERANCE * 100:.0f} %)")
    return None


def identify_legs(
    paths: Sequence[str],
    *,
    mapping: Mapping[str, str] | None = None,
    input_gain: float = 1.0,
    sample_rate: float | None = None,
    friction: Literal["coulomb", "stribeck", "auto"] = "auto",
    fix: Mapping[str, float] | None = None,
    bounds: BoundsOptions = BoundsOptions(),
    u_unit: str | None = None,
    q_unit: str | None = None,
    fmt: str | None = None,
    validate_on: Sequence[str] = (),
    lead: float | None = None,
    gear: float | None = None,
    counts_per_rev: float | None = None,
    _loaded: tuple[Sequence[ExcitationLog], Sequence[ExcitationLog]] | None = None,
) -> LegsOutcome:
    """Identify the friction curve from a friction test: several logs, one constant-speed leg each.

    Each file is its own leg, so nothing is filtered across the joins between
    files.  Each leg gives one point of the friction map (mean speed, median
    command, spread, samples; :func:`commission.identify.steady.friction_map`), and
    the friction curve ``B v + Ff(v) + offset`` is fitted to the map
    (:func:`commission.identify.fit.fit_friction_map`).  Constant speed carries no
    information on the mass: ``M`` is reported as not identified, with the reason,
    unless the user fixes it (``fix={"M": value}``); only then are theta, its box and
    delta_d defined.  A leg whose mean speed is zero (a stalled run) is left out
    with a warning; a file that is not at constant speed is refused, named.

    Parameters
    ----------
    paths : sequence of str
        Log files (at least two; folders already expanded, :func:`expand_log_paths`).
    fix : mapping, optional
        Known parameters (``{"M": u-unit s^2/m}``).
    validate_on : sequence of str
        Legs of a second friction test (files, folders expanded): the fitted curve's
        relative error on their map is ``validation_relative_error``.
    mapping, input_gain, sample_rate, friction, bounds, u_unit, q_unit, fmt, lead, gear, counts_per_rev
        As in :func:`identify_log`, applied to every file.

    Returns
    -------
    LegsOutcome
    """
    if not paths:
        raise UsageError("identify: no log file given (a friction test needs one file per leg)")
    check_input_gain(input_gain, u_unit)
    if friction not in ("auto", "coulomb", "stribeck"):
        raise UsageError(f"--friction: expected auto, coulomb or stribeck, got {friction!r}")
    fix = dict(fix or {})
    if _loaded is not None:  # loaded by identify_files
        logs, val_logs = list(_loaded[0]), list(_loaded[1])
    else:
        load = dict(mapping=mapping, input_gain=input_gain, sample_rate=sample_rate, q_unit=q_unit, fmt=fmt,
                    counts_per_rev=counts_per_rev)
        logs = [load_log(p, **load) for p in paths]  # type: ignore[arg-type]
        # loaded before the fit: bad input fails fast
        val_logs = [load_log(p, **load) for p in validate_on]  # type: ignore[arg-type]
    file_q_unit = _file_q_unit(logs[0], counts_per_rev) if logs else "m"
    logs, val_logs = convert_axis(logs, lead, gear), convert_axis(val_logs, lead, gear)
    _same_axis_units(logs)
    legs, excluded, warnings = [], [], []
    for lg in logs:
        if lg.n < 2 or not np.all(np.isfinite(lg.t)) or not np.all(np.isfinite(lg.q)) or not np.all(np.isfinite(lg.u)):
            raise DataError(f"{lg.source}: a leg needs at least 2 finite samples of t, q and u")
        why = leg_refusal(lg)
        if why is not None:
            raise DataError(f"{lg.source}: not a constant-speed leg: {why}; a friction test is constant-speed legs "
                            "only; logs with excitation are fitted together as segments (identify_files)")
        if _stalled(lg):
            excluded.append(lg.source)
            warnings.append(f"{lg.source}: mean speed 0 (a stalled leg); left out of the friction map")
            continue
        legs.append(lg)
    if len(legs) < 2:
        raise IdentifiabilityError(f"{_where(paths)}: {len(legs)} usable constant-speed leg(s) of {len(logs)} files; "
                                   "a friction map needs legs in both directions")
    fmap = friction_map([(lg.t, lg.q, lg.u) for lg in legs])
    units = _units(u_unit, logs[0])
    speed_unit = units["q"] + "/s"
    named = _named_legs(fmap, legs, speed_unit)

    def fit(model: str) -> MapFit:
        return fit_friction_map(fmap.velocity, fmap.force, friction=model,  # type: ignore[arg-type]
                                speed_unit=speed_unit, force_unit=units["u"])

    try:
        try:
            mf = fit("stribeck" if friction == "auto" else friction)
            fc, fs = mf.parameters["fc"][0], mf.parameters.get("fs", (None,))[0]
            if friction == "auto" and fs is not None and fs < fc:
                warnings.append(f"friction auto: the Stribeck fit is anti-Stribeck (fs = {fs:.4g} < fc = {fc:.4g}); "
                                "the Coulomb model was fitted instead (--friction stribeck keeps the Stribeck fit)")
                mf = fit("coulomb")
        except StribeckNotIdentifiableError as exc:
            if friction != "auto":
                raise IdentifiabilityError(f"{_where(paths)}: {exc} ({named})") from None
            warnings.append(f"friction auto: Stribeck curve not identifiable ({exc}; {named}); the Coulomb model "
                            "was fitted instead (--friction stribeck refuses such a map)")
            mf = fit("coulomb")
    except NotIdentifiableError as exc:
        raise IdentifiabilityError(f"{_where(paths)}: {exc} ({named})") from None
    warnings.extend(mf.warnings)
    warnings.extend(fit_quality_warnings(mf.parameters, mf.relative_error, mf.condition_number))
    val_err = None
    if val_logs:
        val_legs = [lg for lg in val_logs if not _stalled(lg)]
        vmap = friction_map([(lg.t, lg.q, lg.u) for lg in val_legs])
        pv = mf.parameters
        F_hat = (pv["B"][0] * vmap.velocity + pv["offset"][0]
                 + stribeck_friction(vmap.velocity, pv["fc"][0], pv["fs"][0] if "fs" in pv else None,
                                     pv["vs"][0] if "vs" in pv else None, pv["xi"][0] if "xi" in pv else None))
        val_err = float(np.linalg.norm(vmap.force - F_hat) / max(np.linalg.norm(vmap.force), 1e-300))

    p = mf.parameters
    params: dict[str, Estimate | None] = {}
    for name in ("M", "B", "fc", "fs", "vs", "xi", "offset"):
        v = p.get(name)
        params[name] = Estimate(float(v[0]), float(v[1])) if v is not None else None
    not_identified: dict[str, str] = {}
    if "M" in fix:
        params["M"] = Estimate(fix["M"], 0.0)
    else:
        not_identified["M"] = ("the logs are constant-speed legs: no acceleration, so no information on the "
                               + mass_wording(_units(u_unit, logs[0]))[0])
    # The controller's velocity estimate: sqrt(6) x the rms of the per-sample velocity about
    # the leg's smoothed speed (as identify.fit does for a log not on an encoder grid).
    v_res = float(np.median([math.sqrt(6.0) * np.std(np.diff(lg.q) / np.diff(lg.t)) for lg in legs]))
    v_top = float(np.max(np.abs(fmap.velocity)))
    comp = friction_compensation_curve(p["fc"][0], p["fs"][0] if "fs" in p else None,
                                       p["vs"][0] if "vs" in p else None, p["xi"][0] if "xi" in p else None,
                                       v_max=v_top, v_resolution=max(v_res, 1e-9))
    theta = None
    delta_d = None
    tb = None
    if "M" in fix:
        try:
            tb = theta_bounds_from({**p, "M": (fix["M"], 0.0)}, mf.residuals, k_sigma=bounds.k_sigma,
                                   model_margin=bounds.model_margin, payload_min=bounds.payload_min,
                                   payload_max=bounds.payload_max, disturbance_bound=bounds.disturbance_bound)
            theta = ThetaBox(tb.nominal, tb.theta_min, tb.theta_max)
        except ValueError as exc:
            raise DataError(f"{_where(paths)}: the identified friction and the fixed mass give no usable theta box "
                            f"({exc}); B = {p['B'][0]:.4g}") from None
        delta_d = tb.delta_d
    first = legs[0]
    extra: dict[str, object] = {
        "tool": {"name": "commission", "version": __version__},
        "created_utc": _dt.datetime.now(_dt.timezone.utc).strftime("%Y-%m-%dT%H:%M:%SZ"),
        "source": {
            "path": [lg.source for lg in logs],
            "sha256": [lg.sha256 for lg in logs],
            "n_samples": int(sum(lg.n for lg in logs)),
            "sample_rate": float(first.sample_rate),
            "input_gain": float(input_gain),
            "mapping": dict(mapping or {}),
            "q_unit": file_q_unit,
            "excluded": excluded,
        },
        "validation_source": ({"path": [lg.source for lg in val_logs], "sha256": [lg.sha256 for lg in val_logs]}
                              if val_logs else None),
        "model": {
            "friction": mf.friction,
            "friction_requested": friction,
            "method": "friction-legs",
            "legs": len(legs),
            "fixed": {k: v for k, v in fix.items()},
            "v_max": v_top,
            "velocity_resolution": v_res,
        },
        "friction_map": fmap.to_dict(),
        "not_identified": not_identified,
        "friction_compensation_rms_error": comp.rms_error,
        "warnings": warnings,
    }
    if tb is not None:
        extra["bounds"] = _bounds_record(bounds, tb)
    if lead is not None or gear is not None or counts_per_rev is not None:
        extra["source"]["conversion"] = _conversion_record(file_q_unit, lead, gear,  # type: ignore[index]
                                                           counts_per_rev)
    ident = Identification(
        units=_units(u_unit, first),
        parameters=params,
        relative_error=mf.relative_error,
        condition_number=mf.condition_number,
        validation_relative_error=val_err,
        theta=theta,
        delta_d=delta_d,
        fric_level=comp.level,
        fric_slope=comp.slope,
        extra=extra,
    )
    return LegsOutcome(ident=ident, logs=tuple(logs), fmap=fmap, fit=mf, excluded=tuple(excluded))


def is_friction_leg(log: ExcitationLog) -> bool:
    """Whether ``log`` is a constant-speed leg of a friction test, or a stalled one (:func:`leg_refusal`)."""
    return leg_refusal(log) is None


def identify_files(paths: Sequence[str], *, validate_on: Sequence[str] = (), ripple_pitch: float | Sequence[float]
                   | None = None, resample: float | None = None, **options: object) -> IdentifyOutcome | LegsOutcome:
    """Identify one axis from one log or several (``commission identify LOG...``).

    One log: :func:`identify_log`.  Several logs are read once and then

    - constant-speed legs in both directions (:func:`classify_logs`): a friction test,
      :func:`identify_legs` (``ripple_pitch`` and ``resample`` are refused: one
      leg per file gives one map point, no ripple or time base to fit);
    - otherwise (a log with excitation among them, or constant-speed runs all one
      way): fitted together, each log its own segment, :func:`identify_log` with the
      list of paths; the first warning says which files are which.

    Parameters
    ----------
    paths : sequence of str
        Log files, folders already expanded (:func:`expand_log_paths`).
    validate_on : sequence of str
        Logs for the cross-test relative error (folders expanded), read the same way.
    ripple_pitch, resample, **options
        As in :func:`identify_log` (``mapping``, ``input_gain``, ``sample_rate``,
        ``friction``, ``bounds``, ``u_unit``, ``q_unit``, ``fmt``, ``fix``, ``lead``, ``gear``,
        ``counts_per_rev``).

    Returns
    -------
    IdentifyOutcome or LegsOutcome
    """
    paths = list(paths)
    if not paths:
        raise UsageError("identify: no log file given")
    if len(paths) == 1:
        return identify_log(paths[0], validate_on=list(validate_on) or None, ripple_pitch=ripple_pitch,
                            resample=resample, **options)  # type: ignore[arg-type]
    check_input_gain(options.get("input_gain", 1.0), options.get("u_unit"))  # type: ignore[arg-type]
    load = {k: options.get(k) for k in ("mapping", "sample_rate", "q_unit", "fmt", "counts_per_rev")}
    gain = float(options.get("input_gain", 1.0))  # type: ignore[arg-type]
    logs = [load_log(p, input_gain=gain, **load) for p in paths]  # type: ignore[arg-type]
    val_logs = [load_log(p, input_gain=gain, **load) for p in validate_on]  # type: ignore[arg-type]
    rotary = options.get("lead") is None and logs[0].q_unit_in_file == "rad"
    with axis_units_context("rad" if rotary else "m"):  # the numerics' messages in the axis's unit
        return _identify_loaded(paths, logs, val_logs, validate_on=validate_on, ripple_pitch=ripple_pitch,
                                resample=resample, options=options)


def _identify_loaded(paths: list[str], logs: list[ExcitationLog], val_logs: list[ExcitationLog], *,
                     validate_on: Sequence[str], ripple_pitch: float | Sequence[float] | None,
                     resample: float | None, options: Mapping[str, object]) -> IdentifyOutcome | LegsOutcome:
    """:func:`identify_files` once its logs are read: a friction test or segments of one fit."""
    kind, note = classify_logs(logs)
    if kind == "legs":
        for flag, value in (("--ripple-pitch", ripple_pitch or None), ("--resample", resample)):
            if value is not None:
                raise UsageError(f"{flag}: not available for a friction test of several logs ({note}; one map "
                                 "point per leg, no ripple or time base to fit): drop it, or give one file")
        legs_kw = {k: options[k] for k in ("mapping", "input_gain", "sample_rate", "friction", "fix", "bounds",
                                            "u_unit", "q_unit", "fmt", "lead", "gear", "counts_per_rev")
                   if k in options}
        return identify_legs(paths, validate_on=list(validate_on), _loaded=(logs, val_logs),
                             **legs_kw)  # type: ignore[arg-type]
    out = identify_log(paths, validate_on=list(validate_on), ripple_pitch=ripple_pitch, resample=resample,
                       _loaded=(logs, val_logs), **options)  # type: ignore[arg-type]
    out.ident.extra.setdefault("warnings", []).insert(0, note)  # type: ignore[union-attr]
    return out


def classify_logs(logs: Sequence[ExcitationLog]) -> tuple[Literal["legs", "segments"], str]:
    """Whether several logs are a friction test (``"legs"``) or segments of one axis, and a note saying why.

    A friction test is constant-speed legs (:func:`leg_refusal`) in both directions: a
    friction map needs both to tell the Coulomb level from the offset.  Anything else is
    fitted as segments of one axis: logs with excitation among them, or constant-speed
    runs in one direction only (slow runs for a ripple, say), which are no friction test.
    The note names which files are which (stalled legs counted with the legs).
    """
    why = {lg.source: leg_refusal(lg) for lg in logs}
    legs = [lg for lg in logs if why[lg.source] is None]
    moving = [lg for lg in legs if not _stalled(lg)]
    directions = {int(np.sign(lg.q[-1] - lg.q[0])) for lg in moving}

    def names(group: Sequence[ExcitationLog], limit: int = 6) -> str:
        shown = [os.path.basename(lg.source) for lg in group[:limit]]
        return ", ".join(shown) + (f" and {len(group) - limit} more" if len(group) > limit else "")

    if len(legs) == len(logs) and directions == {-1, 1}:
        return "legs", f"{len(logs)} constant-speed legs in both directions: a friction test"
    if len(legs) == len(logs):
        way = "forward" if directions == {1} else "backward" if directions == {-1} else "nowhere"
        return "segments", (f"the {len(logs)} logs are constant-speed runs all {way}, not a friction test (whose "
                            "legs run both ways): fitted together as segments of one axis")
    others = [lg for lg in logs if why[lg.source] is not None]
    first = others[0]
    text = (f"the {len(logs)} logs are fitted together as segments of one axis; not constant-speed legs: "
            f"{names(others)} ({os.path.basename(first.source)}: {why[first.source]})")
    if legs:
        text += f"; constant-speed legs: {names(legs)}"
    return "segments", text


def fit_quality_warnings(parameters: Mapping[str, tuple[float, float]], relative_error: float,
                         condition_number: float) -> list[str]:
    """Warnings, with the figures, when the fit does not explain the log or leaves a parameter undetermined.

    Flagged, not refused: the numbers are still the best the log gives, and the
    user decides (another log, ``--fix``, other units).  ``M`` without information is
    handled before this (reported as not identified).
    """
    out = []
    if relative_error > POOR_FIT_RELATIVE_ERROR:
        out.append(f"fit: relative error {relative_error:.3g} ({relative_error * 100:.0f} % of the command is not "
                   f"explained; condition number {condition_number:.3g}): the rigid model does not explain this log; "
                   "check --map, --input-gain and the units, and that the axis moved without saturating")
    for name, (value, std) in parameters.items():
        if name in ("ripple_phase",) or not math.isfinite(std):
            continue
        if std > UNDETERMINED_REL_STD * abs(value):
            rel = f"{std / abs(value) * 100:.0f} %" if value else "no value"
            out.append(f"{name} = {value:.4g} ± {std:.2g} ({rel}): not determined by this log; do not rely on it "
                       "(a log that excites it, or --fix for M)")
    return out


def _maybe(v: tuple[float, float] | None) -> dict[str, float] | None:
    return None if v is None else {"value": float(v[0]), "std": float(v[1])}


def friction_curve(ident: Identification, v: np.ndarray) -> np.ndarray:
    """Identified total friction ``B v + Ff(v) + offset`` at velocities ``v`` (m/s), u-unit."""
    p = ident.parameters

    def val(name: str) -> float | None:
        e = p.get(name)
        return None if e is None else e.value

    ff = stribeck_friction(np.asarray(v, float), val("fc"), val("fs"), val("vs"), val("xi"))  # type: ignore[arg-type]
    return ident.value("B") * np.asarray(v, float) + ff + ident.value("offset")
