"""Identify the friction curve from a friction test: several logs, one constant-speed leg each.

A leg moves one way at one speed (:func:`leg_refusal` says why a log is not one);
:func:`classify_logs` tells a friction test (legs in both directions) from segments of one
axis.  :func:`identify_legs` is the stage's orchestrator for a friction test; its steps:

1. :func:`_read_legs`: the files read (or taken as loaded), converted to the load's unit;
2. :func:`_usable_legs`: every file checked to be a leg, stalled legs left out;
3. :func:`_fit_map`: the friction curve fitted to the friction map, Stribeck falling back to
   Coulomb under ``friction="auto"``;
4. :func:`_map_validation_error`: the curve's error on a second test's map;
5. :func:`_legs_box`: the theta box, only with a fixed M (constant speed carries no
   information on the mass);
6. :func:`_legs_extra`: ident.json's records.
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass
from typing import Literal, Mapping, Sequence

import numpy as np

from commission.artifacts import Estimate, Identification, ThetaBox, mass_wording
from commission.errors import DataError, IdentifiabilityError, UsageError
from commission.identification.fitting import fit_quality_warnings
from commission.identification.inputs import _conversion_record, _file_q_unit, _same_axis_units, _units, convert_axis
from commission.identification.options import BoundsOptions, check_input_gain
from commission.identification.record import _bounds_record, _estimates, _stamp
from commission.identify.bounds import ThetaBounds, theta_bounds_from
from commission.identify.errors import NotIdentifiableError, StribeckNotIdentifiableError
from commission.identify.fit import MapFit, fit_friction_map
from commission.identify.friction import friction_compensation_curve, stribeck_friction
from commission.identify.signals import quantization_step
from commission.identify.steady import FrictionMap, friction_map
from commission.logs import ExcitationLog, load_log


#: A leg of a friction test is at constant speed when its speed, smoothed over
#: :data:`LEG_SMOOTHING` of its samples, stays within this fraction of the mean speed
#: on 90 % of the samples (wide enough for a 1-rpm velocity quantisation at 1-2 rpm).
LEG_SPEED_TOLERANCE = 0.5
LEG_SMOOTHING = 0.05
#: A measured position is also checked over this fraction of the samples ...
LEG_FINE_SMOOTHING = 0.01
#: ... but over no fewer samples than it takes to travel this many encoder steps.
LEG_FINE_COUNTS = 10


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


def is_friction_leg(log: ExcitationLog) -> bool:
    """Whether ``log`` is a constant-speed leg of a friction test, or a stalled one (:func:`leg_refusal`)."""
    return leg_refusal(log) is None


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


def _read_legs(paths: Sequence[str], validate_on: Sequence[str], *, load: Mapping[str, object],
               lead: float | None, gear: float | None, counts_per_rev: float | None,
               loaded: tuple[Sequence[ExcitationLog], Sequence[ExcitationLog]] | None,
               ) -> tuple[list[ExcitationLog], list[ExcitationLog], str]:
    """The legs and the validation legs, read (or taken as ``loaded``) and converted; and q's unit in the files.

    The validation legs are read before the fit: bad input fails fast.  ``load`` holds
    :func:`commission.logs.load_log`'s keywords.
    """
    if loaded is not None:  # loaded by identify_files
        logs, val_logs = list(loaded[0]), list(loaded[1])
    else:
        logs = [load_log(p, **load) for p in paths]  # type: ignore[arg-type]
        # loaded before the fit: bad input fails fast
        val_logs = [load_log(p, **load) for p in validate_on]  # type: ignore[arg-type]
    file_q_unit = _file_q_unit(logs[0], counts_per_rev) if logs else "m"
    logs, val_logs = convert_axis(logs, lead, gear), convert_axis(val_logs, lead, gear)
    _same_axis_units(logs)
    return logs, val_logs, file_q_unit


def _usable_legs(logs: Sequence[ExcitationLog], paths: Sequence[str],
                 warnings: list[str]) -> tuple[list[ExcitationLog], list[str]]:
    """The legs that move, and the stalled ones left out (a warning each); a file that is no leg is refused."""
    legs, excluded = [], []
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
    return legs, excluded


def _fit_map(fmap: FrictionMap, legs: Sequence[ExcitationLog], paths: Sequence[str], *, friction: str,
             units: Mapping[str, str], warnings: list[str]) -> MapFit:
    """The friction curve fitted to the map: the model asked for, or under ``"auto"`` Stribeck then Coulomb.

    Refusals name the folder (or files) and the slowest legs each way, on which a Stribeck
    verdict rests.
    """
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
    return mf


def _map_validation_error(val_logs: Sequence[ExcitationLog], mf: MapFit) -> float | None:
    """The fitted curve's relative error on the friction map of a second test's moving legs (None without one)."""
    if not val_logs:
        return None
    val_legs = [lg for lg in val_logs if not _stalled(lg)]
    vmap = friction_map([(lg.t, lg.q, lg.u) for lg in val_legs])
    pv = mf.parameters
    F_hat = (pv["B"][0] * vmap.velocity + pv["offset"][0]
             + stribeck_friction(vmap.velocity, pv["fc"][0], pv["fs"][0] if "fs" in pv else None,
                                 pv["vs"][0] if "vs" in pv else None, pv["xi"][0] if "xi" in pv else None))
    return float(np.linalg.norm(vmap.force - F_hat) / max(np.linalg.norm(vmap.force), 1e-300))


def _legs_box(mf: MapFit, fix: Mapping[str, float], bounds: BoundsOptions,
              paths: Sequence[str]) -> tuple[ThetaBounds | None, ThetaBox | None]:
    """The theta bounds and box of a friction test, defined only with a fixed M (None, None without)."""
    if "M" not in fix:
        return None, None
    p = mf.parameters
    try:
        tb = theta_bounds_from({**p, "M": (fix["M"], 0.0)}, mf.residuals, k_sigma=bounds.k_sigma,
                               model_margin=bounds.model_margin, payload_min=bounds.payload_min,
                               payload_max=bounds.payload_max, disturbance_bound=bounds.disturbance_bound)
        return tb, ThetaBox(tb.nominal, tb.theta_min, tb.theta_max)
    except ValueError as exc:
        raise DataError(f"{_where(paths)}: the identified friction and the fixed mass give no usable theta box "
                        f"({exc}); B = {p['B'][0]:.4g}") from None


def _legs_extra(logs: Sequence[ExcitationLog], val_logs: Sequence[ExcitationLog], legs: Sequence[ExcitationLog],
                excluded: list[str], mf: MapFit, fmap: FrictionMap, *, friction: str, fix: Mapping[str, float],
                input_gain: float, mapping: Mapping[str, str] | None, file_q_unit: str, v_top: float,
                v_res: float, not_identified: dict[str, str], comp_rms: float,
                warnings: list[str]) -> dict[str, object]:
    """ident.json's records besides the estimates and the box (``Identification.extra``), for a friction test."""
    return {
        **_stamp(),
        "source": {
            "path": [lg.source for lg in logs],
            "sha256": [lg.sha256 for lg in logs],
            "n_samples": int(sum(lg.n for lg in logs)),
            "sample_rate": float(legs[0].sample_rate),
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
        "friction_compensation_rms_error": comp_rms,
        "warnings": warnings,
    }


def identify_legs(
    paths: Sequence[str], *, mapping: Mapping[str, str] | None = None, input_gain: float = 1.0,
    sample_rate: float | None = None, friction: Literal["coulomb", "stribeck", "auto"] = "auto",
    fix: Mapping[str, float] | None = None, bounds: BoundsOptions = BoundsOptions(), u_unit: str | None = None,
    q_unit: str | None = None, fmt: str | None = None, validate_on: Sequence[str] = (), lead: float | None = None,
    gear: float | None = None, counts_per_rev: float | None = None,
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
    load = dict(mapping=mapping, input_gain=input_gain, sample_rate=sample_rate, q_unit=q_unit, fmt=fmt,
                counts_per_rev=counts_per_rev)
    logs, val_logs, file_q_unit = _read_legs(paths, validate_on, load=load, lead=lead, gear=gear,
                                             counts_per_rev=counts_per_rev, loaded=_loaded)
    warnings: list[str] = []
    legs, excluded = _usable_legs(logs, paths, warnings)
    fmap = friction_map([(lg.t, lg.q, lg.u) for lg in legs])
    units = _units(u_unit, logs[0])
    mf = _fit_map(fmap, legs, paths, friction=friction, units=units, warnings=warnings)
    warnings.extend(mf.warnings)
    warnings.extend(fit_quality_warnings(mf.parameters, mf.relative_error, mf.condition_number))
    val_err = _map_validation_error(val_logs, mf)
    p = mf.parameters
    params = _estimates(p)
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
    tb, theta = _legs_box(mf, fix, bounds, paths)
    extra = _legs_extra(logs, val_logs, legs, excluded, mf, fmap, friction=friction, fix=fix, input_gain=input_gain,
                        mapping=mapping, file_q_unit=file_q_unit, v_top=v_top, v_res=v_res,
                        not_identified=not_identified, comp_rms=comp.rms_error, warnings=warnings)
    if tb is not None:
        extra["bounds"] = _bounds_record(bounds, tb)
    if lead is not None or gear is not None or counts_per_rev is not None:
        extra["source"]["conversion"] = _conversion_record(file_q_unit, lead, gear,  # type: ignore[index]
                                                           counts_per_rev)
    ident = Identification(units=_units(u_unit, legs[0]), parameters=params, relative_error=mf.relative_error,
                           condition_number=mf.condition_number, validation_relative_error=val_err, theta=theta,
                           delta_d=None if tb is None else tb.delta_d, fric_level=comp.level,
                           fric_slope=comp.slope, extra=extra)
    return LegsOutcome(ident=ident, logs=tuple(logs), fmap=fmap, fit=mf, excluded=tuple(excluded))
