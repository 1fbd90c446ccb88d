"""The payload range ``validate`` certifies when it was defaulted: the ``payload_heavy`` scenarios at
another mass (:func:`payload_heavy_at`) and the bisection for the largest safe payload
(:func:`largest_safe_payload`)."""

from __future__ import annotations

import math
from typing import Any, Sequence

from commission.controllers.plant import P_M
from commission.scenarios.scenario import Scenario

#: Bisection steps of :func:`largest_safe_payload`: the certified payload to 1/64 of the default range.
PAYLOAD_BISECTIONS = 6


def payload_heavy_at(scenarios: Sequence[Scenario], mass: float) -> list[Scenario]:
    """The fixed ``<case>/payload_heavy`` scenarios of ``scenarios`` with the moving mass at ``mass``.

    Parameters
    ----------
    scenarios : sequence of Scenario
        A validation matrix (:func:`scenario_matrix`).
    mass : float
        Moving mass M, u-unit s^2/m (the unloaded heavy end plus a payload; viscous B, friction and
        offset unchanged, as in ``payload_heavy``).

    Returns
    -------
    list of Scenario
        Same names, trajectories, disturbances and encoder as the matrix's; only ``M`` differs.
    """
    if not (mass > 0 and math.isfinite(mass)):
        raise ValueError(f"mass: must be a finite positive u-unit s^2/m, got {mass}")
    out = []
    for s in scenarios:
        if "monte_carlo" in s.tags or not s.name.endswith("/payload_heavy"):
            continue
        p = s.plant.copy()
        p[P_M] = mass
        out.append(Scenario(s.name, p, s.trajectory, s.disturbance, s.y0, s.tags, s.quantization, s.noise_std))
    return out


def largest_safe_payload(payload_min: float, payload_max: float, safe: Any,
                         steps: int = PAYLOAD_BISECTIONS) -> float | None:
    """The largest payload in ``[payload_min, payload_max]`` at which ``safe(payload)`` holds, by bisection.

    ``validate`` calls it when the payload range was DEFAULTED and the ARC fails a safety criterion at
    the box's heavy end (issue 30, Build 1: certify the largest payload range that can be certified,
    and say so).  A heavier payload is taken as no easier (the mass scales the force the loop must
    apply and lowers the plant's gain the gains were designed around), so the bisection keeps the
    safe end: the result is ``payload_min`` plus a multiple of ``(payload_max - payload_min) / 2**steps``.

    Parameters
    ----------
    payload_min, payload_max : float
        The default payload range, u-unit s^2/m; ``safe(payload_max)`` is taken as false (the caller saw it fail).
    safe : callable(float) -> bool
        Whether every safety criterion holds with that payload.
    steps : int
        Bisection steps.

    Returns
    -------
    float or None
        None when not even ``payload_min`` is safe (nothing to certify: the gate refuses, naming the corner).
    """
    if not (payload_max > payload_min >= 0.0):
        raise ValueError(f"payload range: need 0 <= min < max, got [{payload_min}, {payload_max}]")
    if not safe(payload_min):
        return None
    lo, hi = payload_min, payload_max
    for _ in range(int(steps)):
        mid = 0.5 * (lo + hi)
        if safe(mid):
            lo = mid
        else:
            hi = mid
    return lo
