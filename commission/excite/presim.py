"""The pre-simulation: the plan played through the holding loop on a conservative model, and refused or scaled."""

from __future__ import annotations

import dataclasses
from typing import Any, Mapping

import numpy as np

from commission.errors import SpecError
from commission.excite.band import predict_band
from commission.excite.limits import (ExciteSpec, INJECTION_SWING_FRACTION, MAX_INJECTION_RETRIES, MAX_SPEED_RAISES,
                                      PRESIM_SUBSTEPS)
from commission.excite.plan import Plan, design_plan, injection_speed_bounds, loop_gains_for, mass_bracket


def _model_truth(spec: ExciteSpec, M: float, *, lsb: float = 1e-12, u_max: float | None = None):
    from commission.synth.truth import AxisTruth

    fc = spec.friction or 0.0
    return AxisTruth(M=M, B=spec.viscous or 0.0, fc=fc, fs=fc, vs=0.01, xi=2.0, lsb=lsb,
                     sample_rate=spec.sample_rate, u_max=u_max if u_max is not None else 1e6 * spec.u_max)


def play(plan: Plan, truth: Any, gains: tuple[float, float, float], rng: np.random.Generator | None = None,
         substeps: int = PRESIM_SUBSTEPS) -> dict[str, np.ndarray]:
    """Play ``plan`` on ``truth`` through the holding loop (PID on the reference, ``u_inject`` added).

    Returns
    -------
    dict
        ``t`` (s), ``q`` (q, the encoder's reading), ``u`` (u: the whole command, clipped at
        ``truth.u_max``), ``q_ref`` (q): a CONTRACT §1 log.
    """
    from commission.synth.simulation import _closed_loop

    n = plan.t.size
    noise = rng.normal(0.0, truth.noise_std, n) if (rng is not None and truth.noise_std > 0) else np.zeros(n)
    q = np.empty(n)
    u = np.empty(n)
    kp, kd, ki = gains
    _closed_loop(truth.plant(), plan.q_ref, plan.v_ref, plan.u_inject, noise, truth.lsb, truth.period,
                 int(substeps), kp, kd, ki, truth.u_max, q, u)
    return {"t": plan.t.copy(), "q": q, "u": u, "q_ref": plan.q_ref.copy()}


def simulate_plan(plan: Plan, truth: Any, rng: np.random.Generator, *, substeps: int = 10) -> dict[str, np.ndarray]:
    """Record ``plan`` on a known-truth axis (:class:`commission.synth.AxisTruth`).

    The holding loop is the plan's ``[drive]``: its gains, or the bandwidth designed on the
    true mass (as a drive tuned to its axis).  ``truth.sample_rate`` must be the plan's.

    Returns
    -------
    dict
        A CONTRACT §1 log (``t``, ``q``, ``u``, ``q_ref``), for :func:`commission.synth.write_log_h5`.
    """
    if abs(truth.sample_rate - plan.spec.sample_rate) > 1e-9 * plan.spec.sample_rate:
        raise ValueError(f"simulate_plan: truth.sample_rate = {truth.sample_rate} Hz, the plan's is "
                         f"{plan.spec.sample_rate} Hz")
    return play(plan, truth, loop_gains_for(plan.spec, truth.M), rng, substeps)


def _peaks(log: Mapping[str, np.ndarray], T: float) -> dict[str, np.ndarray]:
    q = log["q"]
    v = np.zeros_like(q)
    v[1:] = np.diff(q) / T
    a = np.zeros_like(q)
    a[2:] = np.diff(q, 2) / (T * T)
    return {"u": np.abs(log["u"]), "q": q, "v": np.abs(v), "a": np.abs(a)}


class PlanRefused(SpecError):
    """The limits cannot be met by any plan, or the pre-simulation breaks one."""


def presimulate(plan: Plan) -> tuple[dict[str, float], list[dict[str, float]], str | None]:
    """Play the plan on the conservative models; return (peaks, models, first violation or None)."""
    return _presimulate(plan)[:3]


def _injection_windows(plan: Plan) -> np.ndarray:
    """Samples of the injection and stepped-sine cruises (boolean mask over ``plan.t``)."""
    m = np.zeros(plan.t.size, bool)
    for g in plan.segments:
        if g.name == "injection" or g.name.startswith("sine "):
            for a, b in g.info.get("windows_s", ()):
                m |= (plan.t >= a) & (plan.t < b)
    return m


def injection_swing(plan: Plan, log: Mapping[str, np.ndarray]) -> float:
    """Largest ``|v - v_ref|`` over the injection's cruises of a played ``plan``, q/s (0 without any).

    ``v`` is the backward difference of the log's position (the pre-simulation has no encoder
    step), ``v_ref`` the plan's cruise: the velocity the injection adds to the cruise.
    """
    m = _injection_windows(plan)
    m[0] = False
    if not m.any():
        return 0.0
    v = np.diff(log["q"]) * plan.spec.sample_rate
    return float(np.max(np.abs(v[m[1:]] - plan.v_ref[1:][m[1:]])))


def _presimulate(plan: Plan) -> tuple[dict[str, float], list[dict[str, float]], str | None, float, float]:
    """:func:`presimulate`, the broken limit over its peak (1 when none is broken), and the
    injection's largest velocity swing over the models (:func:`injection_swing`, q/s)."""
    s = plan.spec
    T = 1.0 / s.sample_rate
    half = s.travel / 2.0
    peaks = {"u": 0.0, "q_min": 0.0, "q_max": 0.0, "v": 0.0, "a": 0.0}
    models = []
    violation = None
    ratio = 1.0
    swing = 0.0
    for label, M in zip(("light", "heavy"), mass_bracket(s)):
        gains = loop_gains_for(s, M)
        truth = _model_truth(s, M)
        log = play(plan, truth, gains)
        swing = max(swing, injection_swing(plan, log))
        pk = _peaks(log, T)
        # The pre-simulation clips the command at 1e6 u_max only: a command past 1e5 u_max is a loop
        # that diverges, not a plan that asks too much.
        runaway = np.flatnonzero(~np.isfinite(pk["u"]) | (pk["u"] >= 1e5 * s.u_max))
        bad = int(runaway[0]) if runaway.size else None
        models.append({"label": label, "M": M, "B": s.viscous or 0.0, "fc": s.friction or 0.0,
                       "kp": gains[0], "kd": gains[1], "ki": gains[2]})
        peaks["u"] = max(peaks["u"], float(np.max(pk["u"])))
        peaks["q_min"] = min(peaks["q_min"], float(np.min(pk["q"])))
        peaks["q_max"] = max(peaks["q_max"], float(np.max(pk["q"])))
        peaks["v"] = max(peaks["v"], float(np.max(pk["v"])))
        peaks["a"] = max(peaks["a"], float(np.max(pk["a"])))
        if violation is not None:
            continue
        checks = [("limits.u_max", pk["u"], s.u_max, s.u_unit),
                  ("limits.travel", np.abs(pk["q"]), half, s.q_unit),
                  ("limits.v_max", pk["v"], s.v_max, f"{s.q_unit}/s"),
                  ("limits.a_max", pk["a"], s.a_max, f"{s.q_unit}/s^2")]
        if bad is not None:
            k = int(np.flatnonzero(pk["u"] > s.u_max)[0]) if np.any(pk["u"] > s.u_max) else bad
            tk = float(plan.t[k])
            seg = next((g.name for g in plan.segments if g.t_start <= tk < g.t_end), plan.segments[-1].name)
            violation = (f"limits.u_max: the holding loop diverges on the {label} model (M = {M:.4g} "
                         f"{s.u_unit} s^2/{s.q_unit}): |u| passes u_max in segment '{seg}' at t = {tk:.4g} s "
                         f"(sample {k}) and grows without bound; check [drive] (its gains) or [axis] mass")
            continue
        for key, x, lim, unit in checks:
            over = np.flatnonzero(x > lim)
            if over.size:
                k = int(over[0])
                tk = float(plan.t[k])
                seg = next((g.name for g in plan.segments if g.t_start <= tk < g.t_end), plan.segments[-1].name)
                what = "|q - start|" if key == "limits.travel" else f"|{key[7]}|"
                lim_s = f"{lim:.4g} {unit}" + (" (travel / 2)" if key == "limits.travel" else "")
                ratio = min(ratio, lim / float(np.max(x)))
                violation = (f"{key}: the pre-simulation breaks it in segment '{seg}' at t = {tk:.4g} s "
                             f"(sample {k}): {what} = {float(np.max(x)):.4g} {unit} > {lim_s}, on the {label} "
                             f"model (M = {M:.4g} {s.u_unit} s^2/{s.q_unit})")
                break
    return peaks, models, violation, ratio, swing


def plan_run(spec: ExciteSpec, progress: Any = None) -> Plan:
    """Design the plan and pre-simulate it, lowering the injection (or the moves) while it breaks a limit.

    The injection rides on a cruise so that friction keeps one sign.  Where the pre-simulation's
    velocity swing about the cruise (:func:`injection_swing`, the larger over the two models: the
    light one's) exceeds ``INJECTION_SWING_FRACTION`` of the cruise speed, the velocity would come near zero
    and Coulomb friction would damp the modes the injection is there to measure; the cruise is
    then raised to ``swing / INJECTION_SWING_FRACTION`` (at least 10 % up) and the plan
    pre-simulated again, up to ``MAX_SPEED_RAISES`` times.  The cruise stays below the ladder's top
    speed (:func:`commission.excite.plan.injection_speed_bounds`) by the room the swing needs
    above it: ``top / (1 + INJECTION_SWING_FRACTION)``; a soft holding loop that swings more than
    that keeps the injection (the limits alone lower it, as for any plan): the signal is worth more
    than the last of the linearity.  On a linear loop with one-signed friction the
    swing hardly depends on the cruise (only the legs' layout moves it, where the injection starts
    and stops), so one raise mostly suffices.  A raise is not one of the ``MAX_INJECTION_RETRIES``.  A cruise the
    user set (``plan.injection_speed``) is kept.

    Raises
    ------
    PlanRefused
        No plan keeps within the limits (named, with the segment).
    """
    scale = motion = 1.0
    speed: float | None = None  # the injection's cruise, once raised
    raised = 0
    attempt = -1
    while attempt < MAX_INJECTION_RETRIES + raised:  # the raises of the cruise are not retries
        attempt += 1
        try:
            plan = design_plan(spec, injection_scale=scale, motion_scale=motion, injection_speed=speed)
        except SpecError:
            if attempt == 0:
                raise
            if speed is not None:  # the raised cruise does not fit the travel: back to the default one, for good
                speed, raised = None, MAX_SPEED_RAISES
                continue
            break  # slower moves no longer fit the travel: refuse with the violation that asked for them
        if progress is not None:
            progress(f"pre-simulating {plan.duration:.1f} s of plan (attempt {attempt + 1}) ...")
        peaks, models, violation, ratio, swing = _presimulate(plan)
        if violation is None and raised < MAX_SPEED_RAISES and spec.plan.get("injection_speed") is None:
            default, top = injection_speed_bounds(spec, motion)
            cruise = default if speed is None else speed
            if swing > INJECTION_SWING_FRACTION * cruise:
                # The fastest cruise that leaves the swing room below the ladder's top speed.
                cap = max(top / (1.0 + INJECTION_SWING_FRACTION), default)
                if cruise < cap:
                    # at least 10 % up each time: the legs' layout moves the swing a little with the cruise
                    speed = min(max(swing / INJECTION_SWING_FRACTION, 1.1 * cruise), cap)
                    raised += 1
                    continue
        if violation is None:
            done = Plan(t=plan.t, q_ref=plan.q_ref, v_ref=plan.v_ref, a_ref=plan.a_ref, u_inject=plan.u_inject,
                        segments=plan.segments, spec=spec, models=tuple(models), peaks=peaks, injection_scale=scale,
                        motion_scale=motion)
            return dataclasses.replace(done, prediction=predict_band(done))
        if "diverges" in violation:
            break
        injected = any(g.name in ("injection", "bump") or g.name.startswith("sine ") for g in plan.segments
                       if f"segment '{g.name}'" in violation)
        # Lower the injection, or else the moves' speed and acceleration, in proportion to the excess
        # (at least by 5 %, at most by half).
        step = min(max(0.9 * ratio, 0.5), 0.95)
        if injected:
            scale *= step
        else:
            motion *= step
    raise PlanRefused(f"{spec.source}: plan refused: {violation}")


# --------------------------------------------------------------------------- the band the plan will back
