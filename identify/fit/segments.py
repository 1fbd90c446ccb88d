"""The public fits: :func:`fit_segments` (one or several logs of one axis), :func:`fit_axis`, :func:`evaluate`.

:func:`fit_segments` preprocesses every log on its own, chooses the method (a friction ladder:
steady+dynamic; else the dynamic method), fits, and assembles the :class:`AxisFit` with the
figures of merit of the full model on all decimated rows.
"""

from __future__ import annotations

import math

import numpy as np

from commission.identify.errors import MassNotIdentifiableError, NotIdentifiableError
from commission.identify.ls import FrictionModel, readonly_copy, regressor
from commission.identify.signals import (DEFAULT_BANDWIDTH_HZ, Preprocessed, default_settings, preprocess_segments,
                                         quantization_step, segment_rates)
from commission.identify.ripple import RipplePitch, ripple_periodogram
from commission.identify.steady import SteadySegments, find_steady_segments
from commission.identify.fit.checks import _check_excitation
from commission.identify.fit.dynamic import _dynamic_fit
from commission.identify.fit.friction_map import _usable_map
from commission.identify.fit.result import AxisFit, Method, _ordered, _param_values, model_force
from commission.identify.fit.steady_dynamic import MIN_MODEL_ROWS, REVERSAL_FRACTION, _steady_fit, moving_rows


def _velocity_resolution(q_raws: list[np.ndarray], pp: Preprocessed, quant: float | None) -> float:
    """Velocity resolution over every segment (``q_raws``: each segment's raw positions, untrimmed)."""
    if quant is not None:
        return quant * pp.sample_rate
    k0 = pp.trim_start
    sq = []
    for q_raw, seg in zip(q_raws, pp.segments()):
        vb = np.diff(q_raw[k0:]) * pp.sample_rate  # backward difference at samples k0+1 ...
        qd = pp.qd[seg]
        sq.append((vb - 0.5 * (qd[1:] + qd[:-1])) ** 2)
    return float(math.sqrt(6.0) * np.sqrt(np.mean(np.concatenate(sq))))


def _stitched(qs: list[np.ndarray]) -> np.ndarray:
    """The segments' positions laid end to end with no jump at the joins (for grid and motion checks only)."""
    out, last = [], None
    for q in qs:
        out.append(q if last is None else q - q[0] + last)
        last = out[-1][-1]
    return out[0] if len(out) == 1 else np.concatenate(out)


def _steady_segments(pp: Preprocessed, min_duration_s: float, v_tol: float, v_quantum: float) -> SteadySegments:
    """Constant-velocity legs of every segment (none spans a join), indices into the stacked arrays."""
    found = []
    for seg in pp.segments():
        sg = find_steady_segments(pp.t[seg], pp.q[seg], pp.qd[seg], pp.u[seg], min_duration_s=min_duration_s,
                                  v_tol=v_tol, v_quantum=v_quantum)
        found.append((seg.start, sg))
    if len(found) == 1:
        return found[0][1]
    return SteadySegments(start=np.concatenate([sg.start + a for a, sg in found]).astype(np.int64),
                          stop=np.concatenate([sg.stop + a for a, sg in found]).astype(np.int64),
                          **{k: np.concatenate([getattr(sg, k) for _, sg in found])
                             for k in ("velocity", "command", "acceleration", "duration")})


def fit_axis(t: np.ndarray, q: np.ndarray, u: np.ndarray, *, friction: FrictionModel,
             **kwargs: object) -> AxisFit:
    """Identify ``M, B``, friction, offset (and ripple) of one axis from one log.

    The one-segment case of :func:`fit_segments`, which documents the keywords.

    Parameters
    ----------
    t, q, u : array_like, shape (N,)
        Sample times (s, uniform), encoder position (m) and command (u-unit, input
        gain already applied).
    friction : {"coulomb", "stribeck"}
    **kwargs
        As in :func:`fit_segments`.
    """
    return fit_segments([(t, q, u)], friction=friction, **kwargs)  # type: ignore[arg-type]


def _constant_velocity_legs(pp: Preprocessed, quant: float | None, min_segment_s: float,
                            velocity_logged: bool) -> SteadySegments:
    """Every constant-velocity leg of ``pp`` (:func:`_steady_segments`), with the detection's tolerances
    set from the encoder step ``quant`` (None: unknown)."""
    v_tol = (quant / 0.02) if quant is not None else 0.0
    # A position integrated from a recorded velocity (velocity_logged): the step of its
    # position-difference velocity (1 rpm of a recorder) bounds how steady a leg can look.  A
    # measured position's quantization averages out over the smoothing window: no quantum.
    v_quantum = quant * pp.sample_rate if (velocity_logged and quant is not None) else 0.0
    return _steady_segments(pp, min_segment_s, v_tol, v_quantum)


def _friction_legs(pp: Preprocessed, quant: float | None, friction: FrictionModel, *, min_segment_s: float,
                   velocity_logged: bool, warnings: list[str]) -> SteadySegments | None:
    """The constant-velocity legs the friction curve is taken from (the steady+dynamic method).

    None, with a warning saying why, when the log holds no usable friction ladder: the
    whole-log (dynamic) method is used then.
    """
    segs = _constant_velocity_legs(pp, quant, min_segment_s, velocity_logged)
    reason = _usable_map(segs, friction) if len(segs) else "the log has no constant-velocity legs"
    if reason is not None:
        warnings.append(f"friction from the whole-log regression: {reason}; filtering the friction "
                        "discontinuity can bias B, fc and fs (a friction ladder avoids it)")
        return None
    return segs


def _fit_parameters(pp: Preprocessed, segs: SteadySegments | None, friction: FrictionModel,
                    ripple_pitch: float | tuple[float, ...] | None, reversal_speed: float | None, v_noise: float,
                    warnings: list[str], *, mass: float | None, allow_unidentified_mass: bool,
                    ) -> tuple[dict[str, tuple[float, float]], np.ndarray, float, dict[str, str]]:
    """The parameters by the method ``segs`` chooses, the friction map and the reversal speed.

    A log without usable acceleration content, with ``allow_unidentified_mass``, is fitted
    without the mass term and M goes to the returned ``not_identified`` with the reason.

    Returns
    -------
    (params, fmap, reversal_speed, not_identified)
        ``params`` in :data:`PARAMETER_ORDER`; ``fmap`` the map's ``(v, F)`` rows (none for
        the dynamic method).
    """
    def fit_with(m: float | None) -> tuple[dict[str, tuple[float, float]], np.ndarray, float]:
        if segs is not None:
            return _steady_fit(pp, segs, friction, ripple_pitch, reversal_speed, warnings, mass=m)
        return _dynamic_fit(pp, friction, ripple_pitch, v_noise, warnings, mass=m)[0], np.zeros((0, 2)), 0.0

    not_identified: dict[str, str] = {}
    try:
        params, fmap, rev = fit_with(mass)
    except MassNotIdentifiableError as exc:
        if not allow_unidentified_mass:
            raise
        not_identified["M"] = str(exc).removeprefix("M: ")
        params, fmap, rev = fit_with(0.0)  # the model without the mass term
        params.pop("M", None)
    if mass is not None:
        params["M"] = (float(mass), 0.0)
    return _ordered(params), fmap, rev, not_identified


def _model_rows(pp: Preprocessed, rev: float) -> np.ndarray | None:
    """:attr:`AxisFit.model_rows`: the rows away from reversals, read-only (None: too few to take a quantile over).

    ``rev`` is the mass fit's reversal speed (steady+dynamic); the whole-log method (``rev`` 0) has
    none, and its rows at reversals carry the same error of the filtered friction column: it cuts
    at :data:`REVERSAL_FRACTION` of the log's top filtered speed.
    """
    v_ex = rev if rev > 0 else REVERSAL_FRACTION * float(np.max(np.abs(pp.qd)))
    mask = np.array(moving_rows(pp, v_ex), dtype=bool, copy=True)
    if int(mask.sum()) < MIN_MODEL_ROWS:
        return None
    mask.flags.writeable = False
    return mask


def _assembled(pp: Preprocessed, params: dict[str, tuple[float, float]], fmap: np.ndarray, rev: float, *,
               friction: FrictionModel, method: Method, ripple_pitch: float | tuple[float, ...] | None,
               mass_fitted: bool, quant: float | None, v_res: float, bandwidth_hz: float, warnings: list[str],
               not_identified: dict[str, str]) -> AxisFit:
    """The :class:`AxisFit` with the figures of merit of the full model on all decimated rows.

    The condition number is that of the fitted columns of the full decimated regressor
    (without M's column when M is fixed or not identified).
    """
    p = _param_values(params)
    y = pp.decimate(pp.u)
    y_hat = pp.decimate(model_force(p, pp.q, pp.qd, pp.qdd, ripple_pitch))
    r = y - y_hat
    full = regressor(pp.qd, pp.qdd, q=pp.q, model=friction, vs=p.get("vs"), xi=p.get("xi"),
                     ripple_pitch=ripple_pitch)
    fitted_cols = pp.decimate(full.Phi)[:, (0 if mass_fitted else 1):]  # M is column 0
    cond = float(np.linalg.cond(fitted_cols))
    return AxisFit(friction=friction, method=method, parameters=params,
                   relative_error=float(np.linalg.norm(r) / np.linalg.norm(y)), condition_number=cond,
                   residual_std=float(np.std(r, ddof=1)), residuals=readonly_copy(r), t_decimated=readonly_copy(pp.t_dec),
                   force_measured=readonly_copy(y), force_fitted=readonly_copy(y_hat), steady_velocity=readonly_copy(fmap[:, 0]),
                   steady_force=readonly_copy(fmap[:, 1]), quantization=quant, velocity_resolution=v_res,
                   v_max=float(np.max(np.abs(pp.qd))), sample_rate=pp.sample_rate, bandwidth_hz=float(bandwidth_hz),
                   cutoff_hz=pp.cutoff_hz, decimation=pp.decimation, trim_start=pp.trim_start,
                   ripple_pitch=ripple_pitch, reversal_speed=rev, warnings=tuple(warnings),
                   not_identified=not_identified,
                   model_rows=_model_rows(pp, rev))


def fit_segments(segments: list[tuple[np.ndarray, np.ndarray, np.ndarray]] | tuple, *, friction: FrictionModel,
                 ripple_pitch: float | tuple[float, ...] | None = None, use_steady: bool = True,
                 bandwidth_hz: float = DEFAULT_BANDWIDTH_HZ, cutoff_hz: float | None = None,
                 decimation: int | None = None, trim_start: int | None = None, min_segment_s: float = 0.2,
                 reversal_speed: float | None = None, mass: float | None = None,
                 allow_unidentified_mass: bool = False, velocity_logged: bool = False) -> AxisFit:
    """Identify ``M, B``, friction, offset (and ripple) of one axis from one or several logs.

    Each log is a segment: it is filtered, differentiated, trimmed and decimated on
    its own (:func:`commission.identify.signals.preprocess_segments`), its
    constant-velocity legs are found on its own, and the regression rows of all
    segments are stacked into one least-squares problem (standard deviations from
    ``sigma^2 (Phi^T Phi)^-1`` over all rows).  Nothing is filtered across the join
    between two logs, where the position may jump and the command step: a filter
    across it would smear a jump into a spurious velocity and acceleration.  One log
    gives exactly the single-log method of the module docstring.

    Parameters
    ----------
    segments : sequence of (t, q, u)
        Each log's sample times (s, uniform; one sample rate for all), encoder
        position (m) and command (u-unit, input gain already applied).
    friction : {"coulomb", "stribeck"}
        Friction model.
    ripple_pitch : float or sequence of float, optional
        Force-ripple pitch(es), m; fits a sinusoidal ripple of each pitch (e.g. the
        harmonics of one cogging period: P, P/2, P/4).
    use_steady : bool
        Use constant-velocity legs for the friction curve when the log has them.
    bandwidth_hz : float
        Dynamic bandwidth of the excitation, Hz (EMPS: 20); sets the defaults of
        the three preprocessing settings below (:mod:`commission.identify.signals`).
    cutoff_hz : float, optional
        Butterworth cut-off of the position pre-filter, Hz (default ``5 * bandwidth_hz``).
    decimation : int, optional
        Decimation factor (default ``round(0.8 * (fs/2) / (2 * bandwidth_hz))``).
    trim_start : int, optional
        Samples dropped at the start (default ``round(4.9 * fs / cutoff_hz)``).
    min_segment_s : float
        Shortest constant-velocity leg used, s.
    reversal_speed : float, optional
        Rows that come near speeds below this are left out of the mass fit of the
        ``"steady+dynamic"`` method, m/s (default ``3 vs`` of the map's Stribeck
        curve, else 5 % of the fastest constant-velocity leg).
    mass : float, optional
        A known mass, u-unit s^2/m: its term is moved to the left side and the rest
        is fitted (reported with std 0).
    allow_unidentified_mass : bool
        When the log has no usable acceleration content, fit the rest without the
        mass term and report M in :attr:`AxisFit.not_identified` instead of refusing
        the log (slow constant-speed runs: friction and ripple tests).
    velocity_logged : bool
        The position was integrated from a recorded velocity (an EPOS recorder file): leg
        detection allows for the velocity's quantum (:func:`find_steady_segments`, ``v_quantum``).

    Returns
    -------
    AxisFit

    Raises
    ------
    SignalError
        Malformed arrays (:attr:`SignalError.segment` names the log).
    NotIdentifiableError
        The log cannot identify the requested model (constant command, no
        reversals, no acceleration content, too little slow motion for Stribeck).
    """
    if friction not in ("coulomb", "stribeck"):
        raise ValueError(f"friction must be 'coulomb' or 'stribeck', got {friction!r}")
    checked = segment_rates(list(segments))
    q_all = _stitched([c[1] for c in checked])
    _check_excitation(q_all, np.concatenate([c[2] for c in checked]))
    pp = preprocess_segments([c[:3] for c in checked], bandwidth_hz=bandwidth_hz, cutoff_hz=cutoff_hz,
                             decimation=decimation, trim_start=trim_start)
    warnings: list[str] = []
    quant = quantization_step(q_all)
    if quant is None:
        warnings.append("q: the positions are not on an encoder grid (resampled or processed data?)")
    v_res = _velocity_resolution([c[1] for c in checked], pp, quant)
    # Velocity noise floor of the decimated velocity: one encoder count per anti-alias window.
    v_noise = (quant if quant is not None else 0.0) * pp.sample_rate / max(pp.decimation, 1)
    segs = (_friction_legs(pp, quant, friction, min_segment_s=min_segment_s, velocity_logged=velocity_logged,
                           warnings=warnings) if use_steady else None)
    if mass is not None and not (math.isfinite(mass) and mass > 0):
        raise ValueError(f"mass must be a positive finite number, got {mass!r}")
    method: Method = "steady+dynamic" if segs is not None else "dynamic"
    params, fmap, rev, not_identified = _fit_parameters(pp, segs, friction, ripple_pitch, reversal_speed, v_noise,
                                                        warnings, mass=mass,
                                                        allow_unidentified_mass=allow_unidentified_mass)
    return _assembled(pp, params, fmap, rev, friction=friction, method=method, ripple_pitch=ripple_pitch,
                      mass_fitted=not (mass is not None or not_identified), quant=quant, v_res=v_res,
                      bandwidth_hz=bandwidth_hz, warnings=warnings, not_identified=not_identified)


def find_ripple_pitch(segments: list[tuple[np.ndarray, np.ndarray, np.ndarray]] | tuple, *,
                      bandwidth_hz: float = DEFAULT_BANDWIDTH_HZ, cutoff_hz: float | None = None,
                      decimation: int | None = None, trim_start: int | None = None, min_segment_s: float = 0.2,
                      velocity_logged: bool = False) -> RipplePitch:
    """The force-ripple pitch the logs' constant-velocity legs show (:mod:`commission.identify.ripple`).

    The logs go through the preprocessing and the leg detection of :func:`fit_segments`
    (same keywords), so the legs searched are the ones the friction map is taken from.

    Parameters
    ----------
    segments : sequence of (t, q, u)
        As in :func:`fit_segments`: s, q-unit, u-unit.

    Returns
    -------
    RipplePitch
        ``pitch`` None when no pitch stands out (or the logs hold no constant-velocity legs).
    """
    checked = segment_rates(list(segments))
    q_all = _stitched([c[1] for c in checked])
    pp = preprocess_segments([c[:3] for c in checked], bandwidth_hz=bandwidth_hz, cutoff_hz=cutoff_hz,
                             decimation=decimation, trim_start=trim_start)
    quant = quantization_step(q_all)
    segs = _constant_velocity_legs(pp, quant, min_segment_s, velocity_logged)
    legs = [(pp.q[a:b], pp.u[a:b]) for a, b in zip(segs.start, segs.stop)]
    return ripple_periodogram(legs, step=quant)


def evaluate(fit: AxisFit, t: np.ndarray, q: np.ndarray, u: np.ndarray) -> float:
    """Relative error ``||y - y_hat|| / ||y||`` of a fitted model on another log.

    The one-segment case of :func:`evaluate_segments`.

    Parameters
    ----------
    fit : AxisFit
    t, q, u : array_like, shape (N,)
        s, m, u-unit.

    Returns
    -------
    float
        Fraction.
    """
    return evaluate_segments(fit, [(t, q, u)])


def evaluate_segments(fit: AxisFit, segments: list[tuple[np.ndarray, np.ndarray, np.ndarray]] | tuple) -> float:
    """Relative error ``||y - y_hat|| / ||y||`` of a fitted model on other logs, each its own segment.

    The log goes through the same preprocessing as the identification log (same
    cut-off, decimation and trim when the sample rates agree; otherwise the
    defaults for its own sample rate and the fit's bandwidth) and the error is
    taken over all decimated rows of all segments: the EMPS cross-test.  Each log is
    preprocessed on its own (nothing filtered across the joins), as in :func:`fit_segments`.

    Parameters
    ----------
    fit : AxisFit
    segments : sequence of (t, q, u)
        s, m, u-unit; one sample rate for all.

    Returns
    -------
    float
        Fraction.

    Raises
    ------
    SignalError
        Malformed arrays (:attr:`SignalError.segment` names the log).
    """
    checked = segment_rates(list(segments))
    fs_ = checked[0][3]
    data = [c[:3] for c in checked]
    if math.isclose(fs_, fit.sample_rate, rel_tol=1e-6):
        pp = preprocess_segments(data, cutoff_hz=fit.cutoff_hz, decimation=fit.decimation, trim_start=fit.trim_start)
    else:
        cutoff, _, _ = default_settings(fs_, fit.bandwidth_hz)
        pp = preprocess_segments(data, bandwidth_hz=fit.bandwidth_hz, cutoff_hz=cutoff)
    y = pp.decimate(pp.u)
    y_hat = pp.decimate(model_force(_param_values(fit.parameters), pp.q, pp.qd, pp.qdd, fit.ripple_pitch))
    ny = float(np.linalg.norm(y))
    if ny == 0:
        raise NotIdentifiableError("u: the validation command is zero; the relative error is undefined")
    return float(np.linalg.norm(y - y_hat) / ny)
