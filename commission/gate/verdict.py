"""The gate's verdict: every criterion on every scenario (:func:`evaluate_gate`).

Every SAFETY criterion (:data:`SAFETY_CRITERIA` and the floors) is checked for the ARC on every
scenario of the validation matrix; the absolute error limits on the PERFORMANCE scenarios only
(:func:`performance_scenarios`; :mod:`commission.gate`, "What each scenario certifies"); the PID
baseline enters only through the comparison criteria (:mod:`commission.gate.comparison`).  A
criterion that fails is reported with its scenario, its value and its limit; all failures are
listed, not only the first.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from typing import Collection, Sequence

from commission.gate.check import Check, divergence_check, um
from commission.gate.comparison import (COMPARISON_CRITERIA, arc_vs_pid_nominal_checks,
                                        arc_vs_pid_quantile_checks)
from commission.gate.floors import FloorContext, check_floors
from commission.gate.limits import SATURATION_TOL, GateLimits, scenario_error_limit
from commission.controllers.metrics import Indexes


@dataclass(frozen=True)
class GateVerdict:
    """Every check of the gate.

    Attributes
    ----------
    checks : tuple of Check
        Every (criterion, scenario) evaluated, in scenario order.
    limits : GateLimits
    """

    checks: tuple[Check, ...]
    limits: GateLimits

    @property
    def passed(self) -> bool:
        return all(c.passed for c in self.checks)

    @property
    def failures(self) -> tuple[Check, ...]:
        return tuple(c for c in self.checks if not c.passed)

    def worst(self) -> dict[str, Check]:
        """Per criterion, the check closest to (or furthest beyond) its limit."""
        out: dict[str, Check] = {}
        for c in self.checks:
            if c.criterion == "divergence":
                if c.criterion not in out or (out[c.criterion].passed and not c.passed):
                    out[c.criterion] = c
                continue
            ratio = c.value / c.limit if (math.isfinite(c.value) and c.limit > 0) else math.inf
            prev = out.get(c.criterion)
            if prev is None:
                out[c.criterion] = c
                continue
            pr = prev.value / prev.limit if (math.isfinite(prev.value) and prev.limit > 0) else math.inf
            if ratio > pr or (ratio == pr == 0.0 and c.value > prev.value):  # reported only (limit inf): the largest
                out[c.criterion] = c
        return out


def evaluate_gate(limits: GateLimits, runs: Sequence[tuple[str, Indexes, Indexes, float]],
                  floors: FloorContext | None = None,
                  performance: Collection[str] | None = None, compare_nominal: bool = False) -> GateVerdict:
    """Check every criterion on every scenario.

    Parameters
    ----------
    limits : GateLimits
    runs : sequence of (scenario, arc, pid, t_abort)
        Scores of the ARC and the PID on each scenario, and the time (s) at
        which the ARC run aborted (NaN if it did not).

    floors : FloorContext, optional
        When given, the checks of every floor (:data:`commission.gate.floors.FLOORS`) are part of the verdict.
    performance : collection of str, optional
        The PERFORMANCE scenarios (:func:`performance_scenarios`): only these are held to the
        absolute error limits e_F, e_M, e_rms.  Every scenario is held to the SAFETY criteria
        (divergence, c_u, u_peak and the floors).  None: every scenario is a performance scenario
        (the strict reading ``tune``'s objective uses).
    compare_nominal : bool
        Add :func:`arc_vs_pid_nominal_checks` (validate's gate; tune's objective judges the comparison
        through its cost instead).

    Returns
    -------
    GateVerdict
        A diverged ARC run fails ``divergence`` (when required) and every
        index criterion of that scenario (its indexes are undefined).
    """
    checks: list[Check] = []
    for name, arc, pid, t_abort in runs:
        if limits.no_divergence:
            checks.append(divergence_check("divergence", name, arc, t_abort))
        for key, value in (("e_F", arc.e_F), ("e_M", arc.e_M), ("e_rms", arc.e_rms)):
            if performance is not None and name not in performance:
                break  # a SAFETY scenario: certified stable and within the drive, not held to the error limits
            limit, note = scenario_error_limit(limits, key, pid)
            ok = (not arc.diverged) and math.isfinite(value) and value <= limit
            detail = "ARC diverged" if arc.diverged else f"{um(value)} (limit {um(limit)}{note})"
            checks.append(Check(key, name, value, limit, ok, detail))
        ok = (not arc.diverged) and math.isfinite(arc.c_u) and arc.c_u <= limits.c_u
        checks.append(Check("c_u", name, arc.c_u, limits.c_u, ok,
                            "ARC diverged" if arc.diverged else f"{arc.c_u:.3g} (limit {limits.c_u:.3g})"))
        reached = arc.u_peak >= limits.u_max * (1.0 - SATURATION_TOL)
        ok = math.isfinite(arc.u_peak) and not reached
        checks.append(Check("u_peak", name, arc.u_peak, limits.u_max, ok,
                            f"peak |u| {arc.u_peak:.4g} (limit {limits.u_max:.4g}"
                            f"{'; reached: the command was clipped' if reached else ''})"))
        if not limits.arc_vs_pid_every:
            continue
        if arc.diverged:
            ratio = math.inf
            ok = False
            detail = "ARC diverged"
        elif pid.diverged or not math.isfinite(pid.e_rms):
            ratio = 0.0
            ok = True
            detail = f"ARC {um(arc.e_rms)}, PID diverged"
        else:
            ratio = arc.e_rms / pid.e_rms if pid.e_rms > 0 else math.inf
            ok = arc.e_rms <= limits.arc_vs_pid_e_rms * pid.e_rms + limits.arc_vs_pid_slack
            slack = f" + {um(limits.arc_vs_pid_slack)} slack" if limits.arc_vs_pid_slack > 0 else ""
            detail = (f"ARC {um(arc.e_rms)} vs PID {um(pid.e_rms)}: ratio {ratio:.3g} "
                      f"(limit {limits.arc_vs_pid_e_rms:.3g} x PID{slack})")
        checks.append(Check("arc_vs_pid_e_rms", name, ratio, limits.arc_vs_pid_e_rms, ok, detail))
    checks.extend(arc_vs_pid_quantile_checks(limits, runs))
    if compare_nominal:
        checks.extend(arc_vs_pid_nominal_checks(limits, runs))
    if floors is not None:
        checks.extend(check_floors(floors))
    return GateVerdict(tuple(checks), limits)


#: The SAFETY criteria of a simulated scenario (:mod:`commission.gate`, "What each scenario certifies").
SAFETY_CRITERIA = ("divergence", "c_u", "u_peak")


def safety_failures(limits: GateLimits, runs: Sequence[tuple[str, Indexes, Indexes, float]]) -> list[Check]:
    """The failed SAFETY checks (:data:`SAFETY_CRITERIA`) of ``runs``: divergence (always, whatever
    ``no_divergence`` says: it is a floor), chattering and a clipped command."""
    v = evaluate_gate(dataclasses.replace(limits, no_divergence=True), runs, performance=frozenset())
    return [c for c in v.failures if c.criterion in SAFETY_CRITERIA]


#: Variants of the fixed matrix (``<case>/<variant>``) that always certify PERFORMANCE: the identified
#: plant.  The payload corners and the load step join them when the user stated the range they come
#: from; the others (friction corners, one more sample of delay, the mode's variants) certify SAFETY
#: only (:mod:`commission.gate`, "What each scenario certifies").
PERFORMANCE_VARIANTS = ("nominal",)


def performance_scenarios(names: Sequence[str], *, payload_stated: bool,
                          disturbance_stated: bool) -> frozenset[str]:
    """The fixed scenarios held to the absolute error limits (:mod:`commission.gate`, "What each scenario certifies").

    Parameters
    ----------
    names : sequence of str
        Every scenario of the validation.
    payload_stated : bool
        The user gave the payload range (``commission identify --payload-max``; ``bounds.payload_defaulted``
        false, or an ident.json without the record): ``<case>/payload_light`` and ``<case>/payload_heavy``
        are then the user's requirement, and performance scenarios.
    disturbance_stated : bool
        The user gave the load-force bound (``--disturbance-bound``; ``bounds.disturbance_bound_defaulted``
        false, or no record): ``<case>/disturbance`` is then a performance scenario.

    Returns
    -------
    frozenset of str
        Never a Monte-Carlo plant: the Monte-Carlo distribution certifies performance by the quantiles of
        the ARC-vs-PID factor (:func:`commission.gate.comparison.arc_vs_pid_quantile_checks`), not by its
        single worst plant.
    """
    out = set()
    for name in names:
        if name.startswith("mc/"):
            continue
        variant = name.rsplit("/", 1)[-1]
        if (variant in PERFORMANCE_VARIANTS or (payload_stated and variant in ("payload_light", "payload_heavy"))
                or (disturbance_stated and variant == "disturbance")):
            out.add(name)
    return frozenset(out)


def safe_not_better(verdict: "GateVerdict") -> bool:
    """The gate failed only on the comparison with the PID yardstick (:data:`COMPARISON_CRITERIA`).

    Every floor held, every limit on the ARC alone (c_u, peak command, margins on every scenario; the
    error limits on the performance scenarios, :func:`performance_scenarios`) held: the ARC is safe
    and meets the targets, but it does not beat the yardstick.
    ``validate`` then says so plainly and writes the ARC flagged (``controller_not_better.json``),
    never ``controller.json`` (docs/robustness.md, "Safe but not better").
    """
    fails = verdict.failures
    return bool(fails) and all(c.criterion in COMPARISON_CRITERIA for c in fails)

