"""One gate check, and the criterion names in report order.

Every criterion of the gate (:mod:`commission.gate.verdict`, :mod:`commission.gate.comparison`,
:mod:`commission.gate.floors`) reports its result as a :class:`Check`: the scenario, the value,
the limit and one readable line, so that a refusal names all of them.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

from commission.units import unit

#: Criterion names, in report order.
CRITERIA = ("divergence", "e_F", "e_M", "e_rms", "c_u", "u_peak", "arc_vs_pid_e_rms", "arc_vs_pid_median",
            "arc_vs_pid_p90", "arc_vs_pid_nominal", "margins", "margins_box")


@dataclass(frozen=True)
class Check:
    """One criterion on one scenario.

    Attributes
    ----------
    criterion : str
        One of :data:`CRITERIA`.
    scenario : str
    value : float
        Measured value (SI units; for ``divergence`` the abort time in s, NaN if none;
        for ``arc_vs_pid_e_rms`` the ratio ARC/PID).
    limit : float
        The limit it was compared with (NaN for ``divergence``).
    passed : bool
    detail : str
        One readable line (value and limit with units).
    """

    criterion: str
    scenario: str
    value: float
    limit: float
    passed: bool
    detail: str

    def to_dict(self) -> dict[str, Any]:
        return {"criterion": self.criterion, "scenario": self.scenario,
                "value": self.value if math.isfinite(self.value) else None,
                "limit": self.limit if math.isfinite(self.limit) else None,
                "passed": self.passed, "detail": self.detail}


def um(x: float) -> str:
    """A length in micro-units of q: um, or urad on a rotary axis (:func:`commission.units.unit`)."""
    return f"{x * 1e6:.3g} {unit('small')}" if math.isfinite(x) else "n/a"


def divergence_check(criterion: str, scenario: str, arc: Any, t_abort: float) -> Check:
    """The check that the ARC's run on ``scenario`` stayed bounded (value: the abort time, s, or NaN).

    The gate's ``divergence`` criterion and the ``no_divergence`` floor are this one check under
    two names: the gate's can be switched off in gate.toml, the floor's cannot.
    """
    return Check(criterion, scenario, t_abort if arc.diverged else math.nan, math.nan, not arc.diverged,
                 f"ARC aborted at t = {t_abort:.4g} s" if arc.diverged else "ARC stayed bounded")
