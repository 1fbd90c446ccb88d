"""The fit driver: the rigid model's least squares, the delay-aware model chosen, and what they are judged by.

:func:`_fit_with_context` fits the logs (one segment each) with the friction model the user
asked for, falling back from Stribeck to Coulomb under ``friction="auto"``, and turns the
numerics' errors into the pipeline's, naming the file.  :func:`_rich_choice` chooses among
the switchable terms of the delay-aware inverse dynamics (:mod:`commission.identify.richer`)
on the identification logs alone.  The position-simulation RMSE, the agreement of the two
delay estimates and the fit-quality warnings judge the result.
"""

from __future__ import annotations

import dataclasses
import math
from typing import Mapping, Sequence

import numpy as np

from commission.errors import DataError, IdentifiabilityError
from commission.identification.inputs import _name
from commission.identify import richer
from commission.identify.errors import NotIdentifiableError, SignalError, StribeckNotIdentifiableError
from commission.identify.fit import AxisFit, evaluate_segments, find_ripple_pitch, fit_segments
from commission.identify.ripple import RipplePitch
from commission.identify.frf import FrequencyResponse
from commission.identify.ls import ripple_name
from commission.identify.units import unit
from commission.logs import ExcitationLog
from commission.units import axis_units_context


#: A fit leaving more than this fraction of the command unexplained is flagged (EMPS: 0.04).
POOR_FIT_RELATIVE_ERROR = 0.3
#: A parameter whose standard deviation exceeds this multiple of its value is flagged as not determined.
UNDETERMINED_REL_STD = 1.0


def _find_ripple_pitch(logs: Sequence[ExcitationLog]) -> RipplePitch:
    """``--ripple-pitch auto``: the pitch the logs' constant-velocity legs show
    (:func:`commission.identify.fit.find_ripple_pitch`; ``pitch`` None when none stands out)."""
    try:
        return find_ripple_pitch([(lg.t, lg.q, lg.u) for lg in logs],
                                 velocity_logged=any(getattr(lg, "q_from_velocity", False) for lg in logs))
    except SignalError as exc:
        raise DataError(f"{_name(logs, exc.segment)}: {exc}") from None


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


def _fit_step(logs: Sequence[ExcitationLog], *, friction: str, ripple_pitch: float | tuple[float, ...] | None,
              fix: Mapping[str, float], allowed: tuple[str, ...] | None,
              q_unit: str) -> tuple[AxisFit, AxisFit, richer.Selection | None, list[str]]:
    """The fit of :func:`commission.identification.identify_log`: least squares, then the delay-aware choice.

    The delay-aware model is chosen only under ``friction="auto"``, on a whole-log (dynamic)
    fit with M fitted and nothing fixed, and on the identification logs alone (the validation
    logs are not passed).  The numerics' messages are in the axis's unit ``q_unit``.

    Returns
    -------
    (fit, idim_fit, selection, notes)
        The fit carried on, the least-squares (IDIM-LS) fit, the model selection (None when
        not run) and the warnings the fit adds.
    """
    with axis_units_context(q_unit):  # the numerics' messages in the axis's unit
        fit, notes = _fit_with_context(logs, friction=friction, ripple_pitch=ripple_pitch, mass=fix.get("M"))
        idim_fit = fit
        selection: richer.Selection | None = None
        if (friction == "auto" and allowed != () and fit.method == "dynamic" and not fix
                and not fit.not_identified):
            # Chosen on the identification logs alone: val_logs are not passed.
            try:
                selection, rich_fit = _rich_choice(logs, fit, ripple_pitch=ripple_pitch,
                                                   allowed=richer.TERMS if allowed is None else allowed)
            except (NotIdentifiableError, SignalError) as exc:
                notes.append(f"terms: the delay-aware model was not fitted ({exc})")
                rich_fit = None
            if rich_fit is not None and rich_fit.parameters["B"][0] < 0.0:
                # Viscous friction dissipates (VISCOUS_BOUND_NOTE): a delay-aware model that needs B < 0
                # to explain the log is not the plant's; the least squares, fitted under B >= 0, stand.
                notes.append(f"terms: the delay-aware model ({', '.join(selection.fit.terms)}) is not carried on: "  # type: ignore[union-attr]
                             f"its viscous coefficient B = {rich_fit.parameters['B'][0]:.4g} {unit('B')} is negative "
                             "(not physical); the least-squares fit, with B >= 0, stands")
                rich_fit = None
            if rich_fit is not None:
                fit = rich_fit
    return fit, idim_fit, selection, notes


def _validation_error(val_logs: Sequence[ExcitationLog], fit: AxisFit, selection: richer.Selection | None,
                      rich_chosen: bool) -> float | None:
    """The cross-test relative error of the model carried on, on the validation logs (None without them)."""
    if not val_logs:
        return None
    try:
        return (richer.relative_error_on(selection.fit, [(lg.t, lg.q, lg.u) for lg in val_logs],  # type: ignore[union-attr]
                                         bandwidth_hz=fit.bandwidth_hz) if rich_chosen
                else evaluate_segments(fit, [(lg.t, lg.q, lg.u) for lg in val_logs]))
    except SignalError as exc:
        raise DataError(f"{_name(val_logs, exc.segment)}: {exc}") from None
    except NotIdentifiableError as exc:
        raise DataError(f"{_name(val_logs)}: {exc}") from None


def _position_simulation(logs: Sequence[ExcitationLog], val_logs: Sequence[ExcitationLog], fit: AxisFit,
                         idim_fit: AxisFit, selection: richer.Selection | None, rich_chosen: bool, *,
                         ripple_pitch: float | tuple[float, ...] | None,
                         fix: Mapping[str, float]) -> dict[str, object] | None:
    """ident.json's ``position_simulation``: the model's open-loop position RMSE on the validation logs.

    Against the IDIM-LS Coulomb model of the same logs as the reference.  None when there are no
    validation logs, no fitted M, a fit that is not whole-log (dynamic), or a Stribeck least-squares
    fit carried on (the simulation's model is the Coulomb or the delay-aware one).
    """
    if not (val_logs and "M" in fit.parameters and fit.method == "dynamic" and "M" not in fix):
        return None
    models = {"rmse": selection.fit if rich_chosen else _coulomb_richfit(fit)}  # type: ignore[union-attr]
    if idim_fit.friction == "coulomb" or rich_chosen:
        ref = idim_fit if idim_fit.friction == "coulomb" else fit_segments(
            [(lg.t, lg.q, lg.u) for lg in logs], friction="coulomb", ripple_pitch=ripple_pitch)
        models["reference_rmse"] = _coulomb_richfit(ref)
    if fit.friction == "coulomb" or rich_chosen:
        return {**_position_rmse(val_logs, models), "reference": "IDIM-LS (M, B, fc, offset) fitted to the same log"}
    return None
