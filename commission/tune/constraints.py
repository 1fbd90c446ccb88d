"""The constraints of the gain search, each as a violation (0: met, larger: further off).

Three kinds, in the order the optimiser evaluates them (cheapest first, see
:mod:`commission.tune.optimiser`):

1. **Stability margins** (:func:`margin_violation`): the ARC linearised on the identified
   plant, its mode and delay included, at both of its linearisation points
   (:class:`commission.robustness.IdentifiedPlantArcMargins`), held to the spec's
   ``[margins]`` floors: the loops the validation gate holds to the same floors.  Each
   shortfall is counted relative to its floor (the delay margin in samples), so that one
   sample of delay margin weighs as much as the whole phase-margin floor.  The same for the
   whole theta box (:func:`box_violation`, :class:`commission.robustness.BoxArcCheck`): the
   floors with theta_hat at each box plant's theta, stability with theta_hat anywhere.
2. **Gate excess** (:func:`commission.tune.objective.gate_excess`): validate's default gate
   on the tuning scenarios, robustness scenarios and the stand-ins for validate's
   Monte-Carlo sample included, each index measured against
   :attr:`~commission.tune.settings.TuneSettings.gate_margin` of its limit.
3. **Discrete feasibility** (:func:`feasibility_violation`): the sampled loop over the corners
   of the theta box with frozen estimates (:func:`commission.controllers.design.discrete_feasibility`).
"""

from __future__ import annotations

import math
from typing import Sequence

from commission.controllers.design import FeasibilityReport
from commission.robustness import BoxRobustness, LoopMargins, MarginFloors

from commission.tune.settings import DEFAULT_SETTINGS, TuneSettings


def margin_violation(rows: Sequence[LoopMargins], floors: MarginFloors,
                     settings: TuneSettings = DEFAULT_SETTINGS) -> float:
    """Summed relative shortfall of each loop's margins below ``floors`` (0: every floor met).

    Per loop: ``(GM_floor - GM)/GM_floor + (PM_floor - PM)/PM_floor + (DM_floor - DM) +
    (MM_floor - MM)/MM_floor``, each term only when positive (gain in dB, phase in deg, delay in
    samples beyond the identified delay, modulus dimensionless); an unstable loop counts
    ``settings.unstable`` plus its spectral radius's excess over 1.
    """
    total = 0.0
    for r in rows:
        m = r.margins
        if not m.stable:
            total += settings.unstable + max(0.0, m.spectral_radius - 1.0)
            continue
        for val, floor, rel in ((m.gain_margin_db, floors.gain_db, True), (m.phase_margin_deg, floors.phase_deg, True),
                                (m.delay_margin_samples, floors.delay_samples, False),
                                (m.modulus_margin, floors.modulus, True)):
            if not math.isfinite(val) and val > 0:
                continue  # no crossover: nothing to lose
            short = floor - val if math.isfinite(val) else settings.unstable
            if short > 0:
                total += short / floor if (rel and floor > 0) else short
    return total


def box_violation(box: BoxRobustness, floors: MarginFloors, settings: TuneSettings = DEFAULT_SETTINGS) -> float:
    """How far the ARC misses the box check (0: it holds): :func:`margin_violation` of the loops with
    theta_hat at each box plant's theta, plus ``settings.unstable`` and the spectral radius's excess over 1
    when a loop with theta_hat anywhere the projection allows is unstable."""
    a = box.any_estimate
    return (margin_violation(box.at_plant, floors, settings)
            + (0.0 if a.stable else settings.unstable + a.spectral_radius - 1.0))


def feasibility_violation(rep: FeasibilityReport) -> float:
    """How far a discrete-feasibility report misses (0: it holds): the radii's excess over their bounds."""
    if rep.holds:
        return 0.0
    return max(0.0, rep.rho_max - (1.0 - rep.margin)) + max(0.0, rep.rho_adaptive_max - 1.0) + 1e-6


__all__ = ["box_violation", "feasibility_violation", "margin_violation"]
