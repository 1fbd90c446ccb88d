"""The comparison of the ARC with the PID yardstick: criteria ``arc_vs_pid_median``, ``arc_vs_pid_p90``
(:func:`arc_vs_pid_quantile_checks`) and ``arc_vs_pid_nominal`` (:func:`arc_vs_pid_nominal_checks`).

The Monte-Carlo distribution certifies performance statistically, through the quantiles of the
per-scenario ARC-vs-PID factor (:func:`required_factor`), never through its single worst plant; on
the identified plant itself the ARC must beat the yardstick outright.  The scenario-by-scenario
criterion ``arc_vs_pid_e_rms`` (when gate.toml gives it) is checked with the others in
:func:`commission.gate.verdict.evaluate_gate`.
"""

from __future__ import annotations

import math
from typing import Sequence

import numpy as np

from commission.gate.check import Check, um
from commission.gate.limits import GateLimits
from commission.controllers.metrics import Indexes

#: The quantiles judged, criterion name -> quantile.
ARC_VS_PID_QUANTILES = {"arc_vs_pid_median": 0.5, "arc_vs_pid_p90": 0.9}
#: The fixed-matrix variants that are the identified plant: as logged, with the one more sample of
#: input delay a drive may add (the true-plant judgement's four runs, :mod:`commission.true_axis`), and,
#: where the log resolved no Stribeck rise, with the rise it most likely has
#: (:func:`commission.scenarios.unseen_stribeck`).
NOMINAL_COMPARISON_VARIANTS = ("nominal", "delay+1", "stribeck")
#: The criteria that compare the ARC with the PID yardstick (the others judge the ARC alone).
COMPARISON_CRITERIA = ("arc_vs_pid_e_rms", "arc_vs_pid_median", "arc_vs_pid_p90", "arc_vs_pid_nominal")


def scenario_group(name: str) -> str:
    """``"monte_carlo"`` for a Monte-Carlo plant (``mc/...``), else ``"fixed"``."""
    return "monte_carlo" if name.startswith("mc/") else "fixed"


def required_factor(arc: Indexes, pid: Indexes, slack: float) -> float:
    """The smallest factor f with ``ARC e_rms <= f x PID e_rms + slack`` on one scenario.

    0 where the PID diverged (or its e_rms is undefined) and the ARC did not; inf where the ARC
    diverged.  The fraction of scenarios whose factor is at most f is the fraction that passes the
    scenario-by-scenario comparison at factor f: a quantile of it is a statement about the whole
    distribution, not about its single worst plant.
    """
    if arc.diverged or not math.isfinite(arc.e_rms):
        return math.inf
    if pid.diverged or not math.isfinite(pid.e_rms):
        return 0.0
    excess = max(arc.e_rms - slack, 0.0)
    if excess == 0.0:
        return 0.0
    return excess / pid.e_rms if pid.e_rms > 0 else math.inf


def arc_vs_pid_quantile_checks(limits: GateLimits, runs: Sequence[tuple[str, Indexes, Indexes, float]]) -> list[Check]:
    """The ARC-vs-PID judgement by quantiles: per group of scenarios (fixed, Monte-Carlo), the median
    and the 90th percentile of :func:`required_factor` against ``arc_vs_pid_median`` and
    ``arc_vs_pid_p90``.

    The quantile is an observed value (numpy's ``"higher"`` method: no interpolation, so an infinite
    factor of a diverged ARC counts as one scenario).  Each check's detail names the group's worst
    scenario and its ARC/PID e_rms, reported, not judged on its own.
    """
    groups: dict[str, list[tuple[float, str, Indexes, Indexes]]] = {}
    for name, arc, pid, _t in runs:
        groups.setdefault(scenario_group(name), []).append((required_factor(arc, pid, limits.arc_vs_pid_slack),
                                                            name, arc, pid))
    out = []
    for group in ("fixed", "monte_carlo"):
        rows = groups.get(group)
        if not rows:
            continue
        f = np.array([r[0] for r in rows])
        worst = max(rows, key=lambda r: r[0])
        raw = (f"ARC {um(worst[2].e_rms)} vs PID {um(worst[3].e_rms)}" if not worst[2].diverged
               else "ARC diverged")
        for key, q in ARC_VS_PID_QUANTILES.items():
            lim, note = _comparison_limit(limits, key)
            val = float(np.quantile(f, q, method="higher"))
            ok = bool(val <= lim)
            slack = f" + {um(limits.arc_vs_pid_slack)} slack" if limits.arc_vs_pid_slack > 0 else ""
            out.append(Check(key, group, val, lim, ok,
                             f"{int(round(q * 100))}th percentile of ARC e_rms <= f x PID e_rms{slack} over "
                             f"{len(rows)} {group.replace('_', '-')} scenarios: f = {val:.3g} "
                             f"(limit {getattr(limits, key):.3g}{note}); "
                             f"{int(np.sum(f <= 1.0))} of {len(rows)} at f <= 1; worst {worst[1]}: f = "
                             f"{worst[0]:.3g} ({raw})"))
    return out


#: How a comparison reported, not gated, says so (:attr:`commission.gate.limits.GateLimits.comparison_reported`).
REPORTED_NOTE = "; reported, not gated: no PID of (57) keeps the margin floors, so there is no yardstick"


def _comparison_limit(limits: GateLimits, key: str) -> tuple[float, str]:
    """The limit a comparison criterion is checked against (inf: reported only) and the note saying so."""
    if key in limits.comparison_reported:
        return math.inf, REPORTED_NOTE
    return float(getattr(limits, key)), ""


def nominal_comparisons(runs: Sequence[tuple[str, Indexes, Indexes]]
                        ) -> dict[str, tuple[float, list[tuple[str, Indexes, Indexes]]]]:
    """Per case, the value :func:`arc_vs_pid_nominal_checks` checks and the ``(name, ARC, PID)`` runs summed.

    The runs of a case are its fixed scenarios ``<case>/<variant>`` whose variant is in
    :data:`NOMINAL_COMPARISON_VARIANTS` (Monte-Carlo plants and names without a variant are left
    out).  The value is ``sum ARC e_rms / sum PID e_rms`` over them; ``inf`` (all the case's runs
    returned) where the ARC diverged in one; a run whose PID diverged or has no e_rms is left out of
    the sum, and a case left without runs is left out.
    """
    per_case: dict[str, list[tuple[str, Indexes, Indexes]]] = {}
    for name, arc, pid in runs:
        if name.startswith("mc/") or "/" not in name:
            continue
        case, variant = name.rsplit("/", 1)
        if variant in NOMINAL_COMPARISON_VARIANTS:
            per_case.setdefault(case, []).append((name, arc, pid))
    out: dict[str, tuple[float, list[tuple[str, Indexes, Indexes]]]] = {}
    for case, rows in per_case.items():
        if any(a.diverged or not math.isfinite(a.e_rms) for _n, a, _p in rows):
            out[case] = (math.inf, rows)
            continue
        rows = [r for r in rows if not r[2].diverged and math.isfinite(r[2].e_rms)]
        if rows:
            a_sum = sum(a.e_rms for _n, a, _p in rows)
            p_sum = sum(p.e_rms for _n, _a, p in rows)
            out[case] = (a_sum / p_sum if p_sum > 0 else math.inf, rows)
    return out


#: Suffix of the case of an ``arc_vs_pid_nominal`` check against the PID beyond the evidence
#: (:func:`arc_vs_pid_nominal_checks`'s ``beyond``): ``<case>/beyond_evidence``.
BEYOND_EVIDENCE = "beyond_evidence"


def arc_vs_pid_nominal_checks(limits: GateLimits, runs: Sequence[tuple[str, Indexes, Indexes, float]],
                              beyond: float | None = None) -> list[Check]:
    """The ARC beats the yardstick on the identified plant: one check per case (criterion ``arc_vs_pid_nominal``).

    Per case (``case1``, ``case2``, ...), over its scenarios that are the identified plant
    (:data:`NOMINAL_COMPARISON_VARIANTS`: ``<case>/nominal`` and, when validated, ``<case>/delay+1``
    and, where the fit kept Coulomb friction only, ``<case>/stribeck``)
    the value is ``sum ARC e_rms / sum PID e_rms``, and it must be **below** ``arc_vs_pid_nominal``
    (default 1).  Why: the quantiles (:func:`arc_vs_pid_quantile_checks`) judge the distribution over
    the uncertain plants, and their slack lets the ARC lose by up to the encoder's quantisation noise;
    on the plant the log identified, where the model is best, an ARC that does not beat the PID will
    not beat a PID tuned on the machine either (docs/robustness.md has the axes this was measured
    on).  The sum over these runs weighs them by their errors, as one figure
    per case, so a loss within the model's error in one of them is not a refusal while a loss in the
    case as a whole is.

    No slack, and strict: where both loops track within about one encoder step, e_rms is the
    encoder's quantisation (LSB / sqrt(12)) plus a fraction of a step, and which one is better is
    not observable on the machine: a tie there is not a win, and the ARC is not certified as
    better (it is written flagged, :func:`commission.gate.verdict.safe_not_better`).

    ``inf`` where the ARC diverged in one of the case's runs; a run whose PID diverged (or has no
    e_rms) is left out of the sum (the ARC beat it), and a case left without runs gives no check.

    ``beyond`` (rad/s): the runs' PID is not the yardstick but the faster PID the identified plant
    admits and the log does not back (tuning.json ``pid_yardstick.unbacked_pid``, where only the
    evidence bound held the yardstick down).  The checks are then named ``<case>/beyond_evidence``
    and say so; they are held to the same limit.
    """
    per_case = nominal_comparisons([(name, arc, pid) for name, arc, pid, _t in runs])
    out = []
    lim, note = _comparison_limit(limits, "arc_vs_pid_nominal")
    shown = limits.arc_vs_pid_nominal
    what = ("" if beyond is None else
            f"against the PID at pole {beyond:.4g} rad/s that the identified plant admits beyond the band the "
            f"log backs (a drive's auto-tuner would deliver it), ")
    for case_key in sorted(per_case):
        val, rows = per_case[case_key]
        case = case_key if beyond is None else f"{case_key}/{BEYOND_EVIDENCE}"
        if any(a.diverged or not math.isfinite(a.e_rms) for _n, a, _p in rows):
            out.append(Check("arc_vs_pid_nominal", case, math.inf, shown, False,
                             "ARC diverged on the identified plant"))
            continue
        a_sum = sum(a.e_rms for _n, a, _p in rows)
        p_sum = sum(p.e_rms for _n, _a, p in rows)
        each = "; ".join(f"{n} ARC {um(a.e_rms)} vs PID {um(p.e_rms)}" for n, a, p in rows)
        floor = ""
        if limits.lsb > 0 and max(a_sum, p_sum) / len(rows) <= limits.lsb:
            floor = " (both within an encoder step" + (")" if val < shown else ": a tie there is not a win)")
        out.append(Check("arc_vs_pid_nominal", case, val, lim, bool(val < lim),
                         f"identified plant, {what}ARC e_rms / PID e_rms summed over {len(rows)} run(s): "
                         f"{val:.3g} (below {shown:.3g}, no slack{note}){floor}: {each}"))
    return out

