"""The search's own verdict: what tune's gain search records when it found no feasible gains.

The search's constraints are the gate's checks, so a refusal that follows from a search that met
none of them is the search's, and validate's report says so first (:func:`search_infeasible_line`).
"""

from __future__ import annotations

from typing import Any

#: tuning.json ``search.chosen_level`` values (:mod:`commission.tune.optimiser`): every constraint met,
#: the gate on the tuning scenarios missed, a stability constraint missed.
SEARCH_FEASIBLE, SEARCH_GATE_MISSED, SEARCH_STABILITY_MISSED = 0, 1, 2


def search_infeasible_line(search: Any) -> str | None:
    """One plain sentence when tune's search found no gains meeting its own constraints (None: it did).

    The search's constraints are the gate's checks (the same functions on the same plants and
    frequency grid: :class:`commission.robustness.IdentifiedPlantArcMargins` computes the rows
    :func:`commission.robustness.margin_table` gives validate, :class:`commission.robustness.BoxArcCheck`
    is called by both).  When no candidate met them, tune still writes its closest miss so that
    validate can say what it misses; the refusal that follows is then the search's, and the
    report says so first instead of leaving a margin 0.2 % below its floor to look like a
    disagreement between tune and validate.

    Parameters
    ----------
    search : commission.tuning.SearchRecord
        ``chosen_level``, ``chosen_violation``, ``n_evaluations``, ``n_feasible``.
    """
    level = int(getattr(search, "chosen_level", SEARCH_FEASIBLE))
    if level == SEARCH_FEASIBLE:
        return None
    n, v = int(search.n_evaluations), float(search.chosen_violation)
    if level == SEARCH_STABILITY_MISSED:
        return (f"The gain search found no feasible gains: none of its {n} candidates kept every stability "
                f"constraint (the margin floors on the identified plant and over the whole theta box, robust "
                f"stability above the band the log backs, discrete feasibility), the same checks this gate "
                f"makes. The gains validated here are its closest miss (summed relative shortfall {v:.3g}), "
                f"so this refusal is the search's.")
    return (f"The gain search found no feasible gains: each of its {n} candidates that kept the stability "
            f"constraints missed the gate on the tuning scenarios; the gains validated here miss it least "
            f"(gate excess {v:.3g}).")
