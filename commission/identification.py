"""The ``identify`` stage: log in, checked, fitted, bounded, ``ident.json`` out.

This module is the pipeline glue between the loaders (:mod:`commission.logs`,
:mod:`commission.checks`), the numerics (:mod:`commission.identify`) and the
artifact (:class:`commission.artifacts.Identification`).  Errors of the
numerics are re-raised with the file name so that the CLI can print one line.
"""

from __future__ import annotations

import datetime as _dt
from dataclasses import dataclass
from typing import Literal, Mapping

import numpy as np

from commission import __version__
from commission.artifacts import Estimate, Identification, ThetaBox
from commission.checks import CheckReport, check_log
from commission.errors import DataError, IdentifiabilityError, UsageError
from commission.identify.bounds import ThetaBounds, friction_compensation, theta_bounds
from commission.identify.errors import NotIdentifiableError, SignalError, StribeckNotIdentifiableError
from commission.identify.fit import AxisFit, evaluate, fit_axis
from commission.identify.friction import stribeck_friction
from commission.identify.frf import FrequencyResponse, frequency_response
from commission.logs import ExcitationLog, load_log


#: Command units of CONTRACT §1.
U_UNITS = ("V", "N", "A")


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
    bounds: ThetaBounds
    frequency: FrequencyResponse


def _fit_with_context(log: ExcitationLog, *, friction: str,
                      ripple_pitch: float | None) -> tuple[AxisFit, list[str]]:
    """Fit ``log`` with the friction model (``"auto"``: see :func:`identify_log`); the warnings it adds.

    Numerics errors come back as the pipeline's, naming the file.
    """
    try:
        try:
            model = "stribeck" if friction == "auto" else friction
            fit = fit_axis(log.t, log.q, log.u, friction=model, ripple_pitch=ripple_pitch)  # type: ignore[arg-type]
            return fit, []
        except StribeckNotIdentifiableError as exc:
            if friction != "auto":
                raise
            # A hump hidden by ripple or noise on the slow legs (2.9 sigma where 3 are asked) still
            # leaves M, B, fc and the offset well determined: commission with the Coulomb model.
            note = (f"friction auto: Stribeck curve not identifiable ({exc}); the Coulomb model was fitted "
                    f"instead (--friction stribeck refuses such a log)")
            return fit_axis(log.t, log.q, log.u, friction="coulomb", ripple_pitch=ripple_pitch), [note]
    except NotIdentifiableError as exc:
        raise IdentifiabilityError(f"{log.source}: {exc}") from None
    except SignalError as exc:
        raise DataError(f"{log.source}: {exc}") from None


def identify_log(
    path: str,
    *,
    mapping: Mapping[str, str] | None = None,
    input_gain: float = 1.0,
    sample_rate: float | None = None,
    friction: Literal["coulomb", "stribeck", "auto"] = "auto",
    ripple_pitch: float | None = None,
    validate_on: str | None = None,
    bounds: BoundsOptions = BoundsOptions(),
    u_unit: str | None = None,
    q_unit: str | None = None,
) -> IdentifyOutcome:
    """Load, check and identify one excitation log.

    Parameters
    ----------
    path : str
        Excitation log (HDF5, CSV or MAT; CONTRACT §1).
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
    ripple_pitch : float, optional
        Force-ripple pitch, m.
    validate_on : str, optional
        Second log for the cross-test relative error (same mapping and gain).
    bounds : BoundsOptions
        Declared operating range.
    u_unit : {"V", "N", "A"}, optional
        Unit of ``u`` after ``input_gain``; default the file's unit.
    q_unit : {"m", "mm", "um"}, optional
        Unit of ``q`` in files without a ``q_unit`` attribute (CSV, v5 MAT); default m.
        Applies to ``validate_on`` too.

    Returns
    -------
    IdentifyOutcome
    """
    if ripple_pitch is not None and not ripple_pitch > 0:
        raise UsageError(f"--ripple-pitch must be > 0 m, got {ripple_pitch}")
    if not input_gain > 0 or not np.isfinite(input_gain):
        raise UsageError(f"--input-gain must be a positive finite number, got {input_gain}")
    if u_unit is not None and u_unit not in U_UNITS:
        raise UsageError(f"--u-unit must be one of {', '.join(U_UNITS)}, got {u_unit!r}")
    log = load_log(path, mapping=mapping, input_gain=input_gain, sample_rate=sample_rate, q_unit=q_unit)
    checks = check_log(log)
    unit_warnings = []
    if u_unit is None and input_gain != 1.0:
        unit_warnings.append(f"u was multiplied by --input-gain {input_gain:g}; its unit is recorded as the "
                             f"file's ({log.u_unit}); pass --u-unit to name the unit after the gain")
    val_log = None
    if validate_on is not None:
        # Load and check the second log before the (long) fit: bad input fails fast.
        val_log = load_log(validate_on, mapping=mapping, input_gain=input_gain, sample_rate=sample_rate,
                           q_unit=q_unit)
        check_log(val_log)
    if friction not in ("auto", "coulomb", "stribeck"):
        raise UsageError(f"--friction: expected auto, coulomb or stribeck, got {friction!r}")
    fit, friction_warnings = _fit_with_context(log, friction=friction, ripple_pitch=ripple_pitch)
    val_err = None
    if val_log is not None:
        try:
            val_err = evaluate(fit, val_log.t, val_log.q, val_log.u)
        except (NotIdentifiableError, SignalError) as exc:
            raise DataError(f"{val_log.source}: {exc}") from None
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
    freq = frequency_response(log.t, log.q, log.u, fit.parameters["M"][0], fit.parameters["B"][0])

    params: dict[str, Estimate | None] = {}
    for name in ("M", "B", "fc", "fs", "vs", "xi", "offset"):
        v = fit.parameters.get(name)
        params[name] = Estimate(float(v[0]), float(v[1])) if v is not None else None

    warnings = unit_warnings + friction_warnings + list(checks.warnings) + list(fit.warnings)
    extra: dict[str, object] = {
        "tool": {"name": "commission", "version": __version__},
        "created_utc": _dt.datetime.now(_dt.timezone.utc).strftime("%Y-%m-%dT%H:%M:%SZ"),
        "source": {
            "path": str(path),
            "sha256": log.sha256,
            "n_samples": int(log.t.size),
            "sample_rate": float(log.sample_rate),
            "input_gain": float(input_gain),
            "mapping": dict(mapping or {}),
            "q_unit": log.q_unit_in_file,
        },
        "validation_source": (
            {"path": str(validate_on), "sha256": val_log.sha256} if val_log is not None else None
        ),
        "model": {
            "friction": fit.friction,
            "friction_requested": friction,
            "method": fit.method,
            "ripple_pitch": ripple_pitch,
            "ripple_amp": _maybe(fit.parameters.get("ripple_amp")),
            "ripple_phase": _maybe(fit.parameters.get("ripple_phase")),
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
        },
        "bounds": {
            "k_sigma": bounds.k_sigma,
            "model_margin": bounds.model_margin,
            "mass_range": list(tb.mass_range),
            "viscous_range": list(tb.viscous_range),
            "disturbance_range": list(tb.disturbance_range),
            "disturbance_bound": tb.disturbance_bound,
            "disturbance_bound_defaulted": tb.disturbance_bound_defaulted,
        },
        "friction_compensation_rms_error": comp.rms_error,
        "frequency_response": freq.to_dict(),
        "warnings": warnings,
    }
    ident = Identification(
        units={"u": u_unit or log.u_unit, "q": "m"},
        parameters=params,
        relative_error=fit.relative_error,
        condition_number=fit.condition_number,
        validation_relative_error=val_err,
        theta=ThetaBox(tb.nominal, tb.theta_min, tb.theta_max),
        delta_d=tb.delta_d,
        fric_level=comp.level,
        fric_slope=comp.slope,
        extra=extra,
    )
    return IdentifyOutcome(ident=ident, fit=fit, log=log, checks=checks, bounds=tb, frequency=freq)


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
