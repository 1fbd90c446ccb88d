"""The recording recipe: the commissioning run an engineer would record on a known axis
(:func:`excitation_plan`, :func:`random_axis_limits`) and the log written as the tool tells users
to record it (:func:`record_random_axis_log`, :func:`record_axis_log`, :func:`write_random_axis_log`).
"""

from __future__ import annotations

import dataclasses
import os
from dataclasses import dataclass
from typing import Any, Mapping

import numpy as np

from commission.errors import UsageError
from commission.synth.truth import AxisTruth
from commission.synth.random_axes import random_axis, rigid_random_axis
from commission.synth.excitation import ExcitationPlan
from commission.synth.simulation import loop_gains, simulate_excitation
from commission.synth.log_files import write_log_h5


def excitation_plan(truth: AxisTruth) -> ExcitationPlan:
    """The commissioning run an engineer would record on ``truth``: within its force and stability.

    :class:`ExcitationPlan`'s defaults, with

    * the accelerations (multisine, ladder, moves) at most 30 % of the rail's peak
      acceleration ``u_max / M`` and the fastest ladder speed such that viscous friction plus
      stiction take at most 40 % of the rail, so the feedforward, the friction and the PID's
      correction stay inside it;
    * the commissioning PID's bandwidth at most 40 Hz and a fortieth of the rate, lowered by
      steps of 0.85 until its loop on the true plant (modes and delay, linearised by
      :func:`commission.controllers.margins.loop_margins`) keeps 6 dB and 30 deg, as an
      engineer lowers the gain of a loop that rings (a loop that excites its own mode would
      not be logged); at most 40 steps.  The integral corner stays at most a tenth of the
      bandwidth.

    Parameters
    ----------
    truth : AxisTruth

    Returns
    -------
    ExcitationPlan
    """
    base = ExcitationPlan()
    a_rail = truth.u_max / truth.M
    a_cap = 0.3 * a_rail
    v_cap = (0.4 * truth.u_max - truth.fs) / max(truth.B, 1e-12)
    v_max = float(min(base.v_max, max(v_cap, 4.0 * base.v_min)))
    bw = min(base.bandwidth_hz, truth.sample_rate / 40.0)
    if truth.n_modes or truth.delay > 0:
        bw = _quiet_bandwidth(truth, base, bw)
    return dataclasses.replace(_with_bandwidth(base, bw), ms_accel=min(base.ms_accel, a_cap),
                               ladder_accel=min(base.ladder_accel, a_cap), move_accel=min(base.move_accel, a_cap),
                               v_max=v_max)


def _with_bandwidth(plan: ExcitationPlan, bw: float) -> ExcitationPlan:
    """``plan`` with the PID's bandwidth ``bw`` (Hz) and its integral corner at most a tenth of it."""
    return dataclasses.replace(plan, bandwidth_hz=bw, integral_hz=min(plan.integral_hz, bw / 10.0))


def _quiet_bandwidth(truth: AxisTruth, plan: ExcitationPlan, bw: float) -> float:
    """The largest ``bw * 0.85**k`` (k = 0 .. 40) whose commissioning PID keeps 6 dB and 30 deg, Hz."""
    from commission.controllers.linear import sampled_plant
    from commission.controllers.margins import linearize_pid, loop_margins
    from commission.controllers.pid import PidGains, pid_pack

    plant = sampled_plant(truth.plant(), truth.period)
    for _ in range(40):
        kp, kd, ki = loop_gains(truth, _with_bandwidth(plan, bw))
        g = PidGains(Ts=truth.period, M_hat=0.0, B_hat=0.0, Kp=kp, Ki=ki, Kd=kd)
        m = loop_margins(linearize_pid(pid_pack(g)), plant)
        if m.stable and m.gain_margin_db >= 6.0 and m.phase_margin_deg >= 30.0:
            break
        bw *= 0.85
    return bw


#: Most samples an excite-planned random-axis log may have; above it the plan is shortened
#: with :data:`SHORT_PLAN` (identify on a long high-rate log is slow).
EXCITE_MAX_SAMPLES = 600_000
#: ``[plan]`` options of the shortened plan (fewer ladder speeds and moves, shorter legs and injection).
SHORT_PLAN = {"n_speeds": 5, "leg_time": 0.5, "moves": 4, "injection_s": 4.0}
#: Travel the random axes' limits.toml states, m (the legacy run's stroke, ExcitationPlan.travel).
RANDOM_TRAVEL = 0.3
#: Seeded factor range of the rough mass in the random axes' limits.toml.
RANDOM_MASS_GUESS = (0.7, 1.4)
#: Fraction of the rail's peak acceleration ``u_max / M`` stated as ``[limits] a_max``.
RANDOM_A_MAX_FRACTION = 0.5
LOG_KINDS = ("excite", "legacy")


@dataclass(frozen=True)
class RandomAxisLog:
    """What :func:`record_random_axis_log` wrote: the truth, which log, and why.

    Attributes
    ----------
    truth : AxisTruth
        The axis (not shown to the pipeline).
    log : str
        ``"excite"`` (the plan of ``commission excite`` played on the true axis) or
        ``"legacy"`` (the commissioning run of :func:`excitation_plan`, no broadband injection).
    requested : str
        The log asked for.
    limits : dict or None
        The limits.toml (as a mapping) an engineer of the axis would write; None for the legacy log.
    duration_s : float
        Length of the recorded run, s.
    samples : int
        Rows of the log.
    note : str
        Why the log is the legacy one when the excite log was asked for (the refusal), or
        that the plan was shortened; empty otherwise.
    """

    truth: AxisTruth
    log: str
    requested: str
    limits: Mapping[str, Any] | None
    duration_s: float
    samples: int
    note: str = ""


def random_axis_limits(truth: AxisTruth, rng: np.random.Generator) -> dict[str, Any]:
    """The limits.toml (as a mapping) an engineer of the random axis ``truth`` would write.

    * ``[limits]``: ``travel`` :data:`RANDOM_TRAVEL` (the legacy run's stroke), ``v_max`` the
      legacy run's fastest ladder speed (which keeps viscous friction and stiction within 40 %
      of the rail), ``a_max`` :data:`RANDOM_A_MAX_FRACTION` of the rail's peak acceleration
      ``u_max / M``, ``u_max`` the rail;
    * ``[drive]``: ``sample_rate`` the axis's, ``bandwidth_hz`` the holding loop that the
      legacy generator finds quiet on the true axis (:func:`excitation_plan`: at most 40 Hz and
      rate/40, lowered until its loop keeps 6 dB and 30 deg with the modes and the delay), as a
      drive already holding the axis;
    * ``[axis]``: ``mass`` the truth's M (command unit s^2/m) times a factor drawn from ``rng``
      in :data:`RANDOM_MASS_GUESS` (a rough guess), ``u_unit`` the command's, ``q_unit`` m.

    No friction is stated (an engineer rarely knows it); ``[plan]`` keeps excite's defaults.
    """
    legacy = excitation_plan(truth)
    a_rail = truth.u_max / truth.M
    return {
        "limits": {"travel": RANDOM_TRAVEL, "v_max": float(legacy.v_max),
                   "a_max": float(RANDOM_A_MAX_FRACTION * a_rail), "u_max": float(truth.u_max)},
        "drive": {"sample_rate": float(truth.sample_rate), "bandwidth_hz": float(legacy.bandwidth_hz)},
        "axis": {"mass": float(truth.M * rng.uniform(*RANDOM_MASS_GUESS)), "u_unit": truth.u_unit, "q_unit": "m"},
    }


def record_random_axis_log(seed: int, path: str | os.PathLike[str], *, log: str = "excite") -> RandomAxisLog:
    """Draw random axis ``seed`` and write its log (HDF5) as the tool tells users to record it.

    ``log="excite"`` (the recommended workflow): :func:`random_axis_limits` (mass factor from
    ``default_rng(seed + 2000)``), :func:`commission.excite.plan_run` on it, the plan played on
    the TRUE axis (modes, delay, noise, quantization, rail) by
    :func:`commission.excite.simulate_plan` with ``default_rng(seed + 1000)``.  A plan with
    more than :data:`EXCITE_MAX_SAMPLES` rows is planned again with :data:`SHORT_PLAN`'s
    ``[plan]`` options.  If ``excite`` refuses the limits (an exit-2 :class:`SpecError`),
    the legacy log is written and the record says so (``log="legacy"``, ``note`` = the refusal).

    ``log="legacy"``: the commissioning run of :func:`excitation_plan` (ladder, moves, a low
    multisine; no broadband injection), :func:`simulate_excitation` with
    ``default_rng(seed + 1000)``: the logs of the sweep before excite.

    Raises
    ------
    UsageError
        ``log`` is not one of :data:`LOG_KINDS`.
    """
    return record_axis_log(random_axis(np.random.default_rng(seed)), path, seed=seed, log=log)


def record_axis_log(truth: AxisTruth, path: str | os.PathLike[str], *, seed: int = 0,
                    log: str = "excite") -> RandomAxisLog:
    """Write the log of a given ``truth`` (HDF5) exactly as :func:`record_random_axis_log` records axis ``seed``.

    The same recipe (limits from ``default_rng(seed + 2000)``, the plan played with
    ``default_rng(seed + 1000)``, the shortened plan above :data:`EXCITE_MAX_SAMPLES`, the legacy
    fallback), for a named development axis built by hand rather than drawn.

    Raises
    ------
    UsageError
        ``log`` is not one of :data:`LOG_KINDS`.
    """
    if log not in LOG_KINDS:
        raise UsageError(f"log: {log!r} is not one of {', '.join(LOG_KINDS)}")
    note = ""
    if log == "excite":
        from commission.errors import SpecError
        from commission.excite import excite_spec_from_mapping, plan_run, simulate_plan

        limits = random_axis_limits(truth, np.random.default_rng(seed + 2000))
        try:
            plan = plan_run(excite_spec_from_mapping(limits, f"axis {seed} limits.toml"))
            if plan.t.size > EXCITE_MAX_SAMPLES:
                note = (f"plan of {plan.t.size} samples ({plan.duration:.1f} s) shortened with [plan] "
                        + ", ".join(f"{k} = {v:g}" for k, v in SHORT_PLAN.items()))
                limits = {**limits, "plan": dict(SHORT_PLAN)}
                plan = plan_run(excite_spec_from_mapping(limits, f"axis {seed} limits.toml"))
        except SpecError as exc:
            note = f"excite refused, legacy log written: {exc}"
        else:
            data = simulate_plan(plan, truth, np.random.default_rng(seed + 1000))
            write_log_h5(path, data, u_unit=truth.u_unit)
            return RandomAxisLog(truth, "excite", log, limits, plan.duration, int(plan.t.size), note)
    data = simulate_excitation(truth, excitation_plan(truth), np.random.default_rng(seed + 1000))
    write_log_h5(path, data, u_unit=truth.u_unit)
    n = int(data["t"].size)
    return RandomAxisLog(truth, "legacy", log, None, n / truth.sample_rate, n, note)


def write_random_axis_log(seed: int, path: str | os.PathLike[str], *, rigid: bool = False,
                          log: str = "excite") -> AxisTruth:
    """Draw random axis ``seed`` and write its log (HDF5) to ``path``; return its truth.

    The axis is ``random_axis(default_rng(seed))`` and its log that of
    :func:`record_random_axis_log` with ``log`` (``"excite"``: the plan of ``commission
    excite`` from the axis's limits, played on the true axis, falling back to the legacy run
    when excite refuses; ``"legacy"``: the commissioning run of :func:`excitation_plan`, no
    broadband injection), written in the axis's command unit.  With ``rigid=True`` it is
    ``rigid_random_axis(default_rng(seed))`` with the default :class:`ExcitationPlan`
    whatever ``log`` says: the axes of issues 4-20 that ``tests/test_tune_random_axes.py``
    pins.  This is the numbering of the random-axes tests and of
    ``benchmarks/sweep_random_axes.py`` ("axis 16" is seed 16).

    Returns
    -------
    AxisTruth
        The known truth (not used by the pipeline).
    """
    if rigid:
        truth = rigid_random_axis(np.random.default_rng(seed))
        write_log_h5(path, simulate_excitation(truth, ExcitationPlan(), np.random.default_rng(seed + 1000)),
                     u_unit=truth.u_unit)
        return truth
    return record_random_axis_log(seed, path, log=log).truth
