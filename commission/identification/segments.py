"""Identify one axis from one excitation log, or several fitted together as segments: :func:`identify_log`.

:func:`identify_log` is the stage's orchestrator; each of its steps is a named function:

1. :func:`_read_inputs`: the logs read, converted, resampled and checked, the validation
   logs too, before the (long) fit, so that bad input fails fast;
2. :func:`~commission.identification.fitting._fit_step`: the least squares and the
   delay-aware model chosen on the identification logs alone;
3. :func:`~commission.identification.fitting._validation_error`: the cross-test error;
4. :func:`_bounds_step`: the theta box (Assumption 1), when M is known;
5. :func:`~commission.identification.frequency._frequency_step`: the frequency response and
   the encoder noise, when M is known;
6. :func:`_segment_warnings`, :func:`_segment_extra`: ident.json's warnings and records;
7. the :class:`~commission.artifacts.Identification` assembled (:mod:`~commission.identification.record`).
"""

from __future__ import annotations

import dataclasses
import os
from dataclasses import dataclass
from typing import Any, Literal, Mapping, Sequence

from commission.artifacts import Identification
from commission.checks import CheckReport, check_log, mass_plausibility_warnings
from commission.errors import UsageError
from commission.identification.fitting import (_delay_agreement, _find_ripple_pitch, _fit_step, _position_simulation,
                                               _validation_error, fit_quality_warnings)
from commission.identification.frequency import _evidence, _frequency_step
from commission.identification.inputs import (_conversion_record, _file_q_unit, _joined, _name, _same_axis_units,
                                              _units, convert_axis, resample_log)
from commission.identification.options import BoundsOptions, check_input_gain, parse_terms
from commission.identification.record import (_bounds_record, _estimates, _maybe, _stamp,
                                              _theta_box)
from commission.identify import richer
from commission.identify.bounds import ThetaBounds, friction_compensation, theta_bounds
from commission.identify.fit import AxisFit
from commission.identify.frf import EncoderNoise, FrequencyResponse
from commission.identify.ls import ripple_name, ripple_pitches
from commission.logs import ExcitationLog, load_log


#: Figures of one identified log (``identify --plot``; ``run`` writes them beside its report).
IDENT_FIGURE_NAMES = ("force_fit.png", "friction_curve.png", "residuals.png", "bode.png")


@dataclass(frozen=True)
class IdentifyOutcome:
    """Everything the identify stage produced (the artifact and what plots need)."""

    ident: Identification
    fit: AxisFit
    log: ExcitationLog
    checks: CheckReport
    bounds: ThetaBounds | None
    frequency: FrequencyResponse | None


@dataclass(frozen=True)
class _Inputs:
    """The logs of one :func:`identify_log` call as read, converted and checked (:func:`_read_inputs`)."""

    paths: list[str]
    val_paths: list[str]
    pitches: tuple[float, ...]
    ripple_pitch: float | tuple[float, ...] | None  # one pitch as a float, several as a tuple, none as None
    logs: list[ExcitationLog]
    val_logs: list[ExcitationLog]
    all_checks: list[CheckReport]
    file_q_unit: str


def _read_inputs(path: str | Sequence[str], validate_on: str | Sequence[str] | None, *,
                 ripple_pitch: float | Sequence[float] | None, input_gain: float, u_unit: str | None,
                 load: Mapping[str, object], lead: float | None, gear: float | None, resample: float | None,
                 counts_per_rev: float | None,
                 loaded: tuple[Sequence[ExcitationLog], Sequence[ExcitationLog]] | None) -> _Inputs:
    """The logs and validation logs read (or taken as ``loaded``), converted, resampled and checked.

    The validation logs are read and checked before the (long) fit: bad input fails fast.
    ``load`` holds :func:`commission.logs.load_log`'s keywords.
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
    check_input_gain(input_gain, u_unit)
    logs = list(loaded[0]) if loaded is not None else [load_log(p, **load) for p in paths]  # type: ignore[arg-type]
    file_q_unit = _file_q_unit(logs[0], counts_per_rev)
    logs = convert_axis(logs, lead, gear)
    if resample is not None:
        logs = [resample_log(lg, resample) for lg in logs]
    all_checks = [check_log(lg) for lg in logs]
    _same_axis_units(logs)
    val_logs = (list(loaded[1]) if loaded is not None
                else [load_log(p, **load) for p in val_paths])  # type: ignore[arg-type]
    val_logs = convert_axis(val_logs, lead, gear)
    if resample is not None:
        val_logs = [resample_log(lg, resample) for lg in val_logs]
    for lg in val_logs:
        check_log(lg)
    return _Inputs(paths=paths, val_paths=val_paths, pitches=pitches,
                   ripple_pitch=(pitches[0] if len(pitches) == 1 else pitches) if pitches else None,
                   logs=logs, val_logs=val_logs, all_checks=all_checks, file_q_unit=file_q_unit)


def _bounds_step(fit: AxisFit, bounds: BoundsOptions) -> ThetaBounds:
    """The theta box of a fit with M over the declared operating range (Assumption 1)."""
    try:
        return theta_bounds(
            fit,
            k_sigma=bounds.k_sigma,
            model_margin=bounds.model_margin,
            payload_min=bounds.payload_min,
            payload_max=bounds.payload_max,
            disturbance_bound=bounds.disturbance_bound,
        )
    except ValueError as exc:
        raise UsageError(f"bounds: {exc}") from None


def _segment_warnings(inp: _Inputs, fit: AxisFit, notes: list[str], fix: Mapping[str, float],
                      units: Mapping[str, str], freq: FrequencyResponse | None) -> list[str]:
    """ident.json's ``warnings``: the fit's notes, each log's checks (named when several), the fit's own,
    its quality, the mass's plausibility and the frequency response's, in that order."""
    logs = inp.logs
    has_mass = "M" in fit.parameters
    log_warnings = [w if len(logs) == 1 else f"{c.source}: {w}" for c in inp.all_checks for w in c.warnings]
    return (notes + log_warnings + list(fit.warnings)
            + fit_quality_warnings({k: v for k, v in fit.parameters.items() if k not in fix},
                                   fit.relative_error, fit.condition_number)
            + mass_plausibility_warnings(dict(units), fit.parameters["M"][0] if has_mass and "M" not in fix else None)
            + (freq.warnings if freq is not None else []))


def _source_record(inp: _Inputs, *, input_gain: float, mapping: Mapping[str, str] | None,
                   resample: float | None) -> dict[str, object]:
    """ident.json's ``source``: the file(s) fitted, their digests, samples, rate, gain, mapping and q unit."""
    logs, paths, several = inp.logs, inp.paths, len(inp.logs) > 1
    return {
        "path": [str(p) for p in paths] if several else str(paths[0]),
        "sha256": [lg.sha256 for lg in logs] if several else logs[0].sha256,
        "n_samples": int(sum(lg.t.size for lg in logs)),
        "sample_rate": float(logs[0].sample_rate),
        "input_gain": float(input_gain),
        "mapping": dict(mapping or {}),
        "q_unit": inp.file_q_unit,
        "resampled_hz": resample,
    }


def _model_record(fit: AxisFit, friction: str, pitches: Sequence[float]) -> dict[str, object]:
    """ident.json's ``model``: the friction model, the method, the ripple harmonics and the fit's settings."""
    return {
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
    }


def _segment_extra(inp: _Inputs, fit: AxisFit, checks: CheckReport, *, friction: str, input_gain: float,
                   mapping: Mapping[str, str] | None, resample: float | None, bounds: BoundsOptions,
                   tb: ThetaBounds | None, comp_rms: float, freq: FrequencyResponse | None,
                   noise: EncoderNoise | None, plan_path: str | None, u_max: float | None,
                   units: Mapping[str, str], warnings: list[str]) -> dict[str, object]:
    """ident.json's records besides the estimates and the box (``Identification.extra``), for segments.

    ``warnings`` is kept as the list object given (the box step appends to it).  The model
    selection, the position simulation, ``fixed`` and ``conversion`` are added by the caller.
    """
    val_logs, val_paths, val_several = inp.val_logs, inp.val_paths, len(inp.val_logs) > 1
    extra: dict[str, object] = {
        **_stamp(),
        "source": _source_record(inp, input_gain=input_gain, mapping=mapping, resample=resample),
        "validation_source": (
            {"path": [str(p) for p in val_paths] if val_several else str(val_paths[0]),
             "sha256": [lg.sha256 for lg in val_logs] if val_several else val_logs[0].sha256}
            if val_logs else None
        ),
        "model": _model_record(fit, friction, inp.pitches),
        "encoder": {
            "quantization": checks.quantization_step,
            "apparent_resolution": checks.apparent_resolution,
            **(noise.to_dict() if noise is not None else {}),
        },
        "bounds": {} if tb is None else _bounds_record(bounds, tb),
        "friction_compensation_rms_error": comp_rms,
        "frequency_response": ({**freq.to_dict(), "plan": plan_path} if plan_path is not None
                               else freq.to_dict()) if freq is not None else None,
        "evidence": _evidence(inp.logs, freq, fit, u_max, units),
        "not_identified": dict(fit.not_identified),
        "warnings": warnings,
    }
    if len(inp.logs) > 1:
        extra["model"]["segments"] = [int(lg.t.size) for lg in inp.logs]  # type: ignore[index]
    return extra


def _add_model_records(extra: dict[str, object], inp: _Inputs, fit: AxisFit, idim_fit: AxisFit,
                       selection: richer.Selection | None, *, fix: Mapping[str, float], has_box: bool,
                       conversion: tuple[float | None, float | None, float | None]) -> None:
    """Complete :func:`_segment_extra`'s records: the model selection, the position simulation, ``fixed``,
    the unit ``conversion`` (``(lead, gear, counts_per_rev)``), and no ``evidence``, ``bounds`` or
    ``frequency_response`` when there is none (the last two need M)."""
    rich_chosen = selection is not None and fit is not idim_fit
    if selection is not None:
        extra["model_selection"] = selection.to_dict()
        if rich_chosen:
            extra["model"]["inverse_dynamics"] = selection.fit.to_dict()  # type: ignore[index]
    position = _position_simulation(inp.logs, inp.val_logs, fit, idim_fit, selection, rich_chosen,
                                    ripple_pitch=inp.ripple_pitch, fix=fix)
    if position is not None:
        extra["position_simulation"] = position
    if fix:
        extra["model"]["fixed"] = dict(fix)  # type: ignore[index]
    lead, gear, counts_per_rev = conversion
    if lead is not None or gear is not None or counts_per_rev is not None:
        extra["source"]["conversion"] = _conversion_record(inp.file_q_unit, lead, gear,  # type: ignore[index]
                                                           counts_per_rev)
    if extra["evidence"] is None:
        del extra["evidence"]
    if not has_box:
        del extra["bounds"], extra["frequency_response"]  # both need M


def identify_log(
    path: str | Sequence[str], *, mapping: Mapping[str, str] | None = None, input_gain: float = 1.0,
    sample_rate: float | None = None, friction: Literal["coulomb", "stribeck", "auto"] = "auto",
    ripple_pitch: float | Sequence[float] | None = None, validate_on: str | Sequence[str] | None = None,
    bounds: BoundsOptions = BoundsOptions(), u_unit: str | None = None, q_unit: str | None = None,
    fmt: str | None = None, resample: float | None = None, fix: Mapping[str, float] | None = None,
    lead: float | None = None, gear: float | None = None, counts_per_rev: float | None = None,
    max_modes: int | None = None, u_max: float | None = None, plan: Mapping[str, Any] | None = None,
    terms: str | Sequence[str] | None = "auto", plan_path: str | None = None, find_ripple: bool = True,
    _loaded: tuple[Sequence[ExcitationLog], Sequence[ExcitationLog]] | None = None,
) -> IdentifyOutcome:
    """Load, check and identify one excitation log, or several logs of one axis fitted together.

    Several logs (``path`` a sequence) are fitted together, each as its own segment
    (:func:`commission.identify.fit.fit_segments`): every log is filtered,
    differentiated and decimated on its own, so nothing is filtered across the join
    between two recordings (where the position may jump and the command step), and
    the regression rows of all logs form one least-squares problem.  A log without usable
    acceleration content (slow constant-speed runs) leaves M not identified:
    ``parameters.M`` null with the reason in ``not_identified``, and no theta, box or
    frequency response (they need M); the rest is still identified.

    Parameters
    ----------
    path : str or sequence of str
        Excitation log(s) (HDF5, CSV or MAT; CONTRACT §1); folders already expanded
        (:func:`commission.identification.expand_log_paths`).  One sample rate for all.
    max_modes : int, optional
        ``--max-modes``: most structural modes the frequency response keeps (default
        :data:`commission.identify.frf.MAX_MODES`); modes beyond it are warned about.
    u_max : float, optional
        ``--u-max``: the drive's command limit, u-unit, for the ``commission excite`` sketch
        that a log without a broadband segment gets (``evidence``).
    mapping, input_gain, sample_rate, friction, ripple_pitch, validate_on, bounds
        As the attributes of :class:`~commission.identification.IdentifyOptions`.
    u_unit, q_unit, fmt, resample, fix, lead, gear, counts_per_rev, terms, plan, plan_path, find_ripple
        As the attributes of :class:`~commission.identification.IdentifyOptions` (one definition
        for ``identify`` and ``run``; its ``kwargs()`` gives these keywords).

    Returns
    -------
    IdentifyOutcome
        With several logs, ``log`` is the logs laid end to end (for summaries and
        plots) and ``checks`` the first log's report.
    """
    load = dict(mapping=mapping, input_gain=input_gain, sample_rate=sample_rate, q_unit=q_unit, fmt=fmt,
                counts_per_rev=counts_per_rev)
    inp = _read_inputs(path, validate_on, ripple_pitch=ripple_pitch, input_gain=input_gain, u_unit=u_unit, load=load,
                       lead=lead, gear=gear, resample=resample, counts_per_rev=counts_per_rev, loaded=_loaded)
    logs, val_logs, checks = inp.logs, inp.val_logs, inp.all_checks[0]
    if friction not in ("auto", "coulomb", "stribeck"):
        raise UsageError(f"--friction: expected auto, coulomb or stribeck, got {friction!r}")
    fix = dict(fix or {})
    allowed = parse_terms(terms)
    units = _units(u_unit, logs[0])
    search = None
    if find_ripple and not inp.pitches:  # given pitches are the user's word: no search then
        search = _find_ripple_pitch(logs)
        if search.pitch is not None:
            inp = dataclasses.replace(inp, pitches=(search.pitch,), ripple_pitch=search.pitch)
    fit, idim_fit, selection, notes = _fit_step(logs, friction=friction, ripple_pitch=inp.ripple_pitch, fix=fix,
                                                allowed=allowed, q_unit=units["q"])
    if search is not None and search.pitch is not None:
        # a ripple found changes the model, so it is said; none found is only recorded (model.ripple_search)
        notes.insert(0, search.describe(units["q"]))
    has_mass = "M" in fit.parameters
    rich_chosen = selection is not None and fit is not idim_fit
    val_err = _validation_error(val_logs, fit, selection, rich_chosen)
    tb = _bounds_step(fit, bounds) if has_mass else None
    comp = friction_compensation(fit)
    # What the rigid model lacks: the measured response u -> q against M, B (identify/frf/).
    freq, noise = None, None
    if has_mass:
        freq, noise, plan_path = _frequency_step(logs, inp.paths, fit, checks.quantization_step, max_modes=max_modes,
                                                 plan=plan, plan_path=plan_path, notes=notes)
    if rich_chosen:
        notes += _delay_agreement(selection.fit, freq)  # type: ignore[union-attr]
    params = _estimates(fit.parameters)
    warnings = _segment_warnings(inp, fit, notes, fix, units, freq)
    extra = _segment_extra(inp, fit, checks, friction=friction, input_gain=input_gain, mapping=mapping,
                           resample=resample, bounds=bounds, tb=tb, comp_rms=comp.rms_error, freq=freq, noise=noise,
                           plan_path=plan_path, u_max=u_max, units=units, warnings=warnings)
    _add_model_records(extra, inp, fit, idim_fit, selection, fix=fix, has_box=tb is not None,
                       conversion=(lead, gear, counts_per_rev))
    if search is not None:
        extra["model"]["ripple_search"] = search.record()  # type: ignore[index]
    theta = None if tb is None else _theta_box(tb, _name(logs), fit)
    ident = Identification(units=units, parameters=params, relative_error=fit.relative_error,
                           condition_number=fit.condition_number, validation_relative_error=val_err, theta=theta,
                           delta_d=tb.delta_d if tb is not None else None, fric_level=comp.level,
                           fric_slope=comp.slope, extra=extra)
    return IdentifyOutcome(ident=ident, fit=fit, log=_joined(logs), checks=checks, bounds=tb, frequency=freq)
