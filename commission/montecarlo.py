"""Streaming summary of validate's Monte-Carlo plants: quantiles and the worst plants.

``validate --monte-carlo N`` simulates the N plants in chunked tasks on the executor
(:mod:`commission.infra.executor`); the chunks come back in task order and are folded here one
at a time.  What is kept per plant is a handful of floats (the indexes summarised below);
the simulations' time histories are dropped in the worker, so a run of 10 000 plants holds
10 000 x 6 floats here, not 10 000 simulations.  The worst plants are a bounded heap
(:data:`WORST_KEPT`), ties broken by plant order, so the summary is the same whatever the
executor and the number of workers.

The summary (``monte_carlo_summary`` in validation.json) is for reading at scale; the gate
itself still checks every plant's record (:mod:`commission.gate`).
"""

from __future__ import annotations

import heapq
import math
from array import array
from typing import Any

import numpy as np

from commission.controllers.metrics import Indexes

#: Quantiles reported, as fractions (``p50`` ... ``p99`` and ``max``).
QUANTILES = (0.5, 0.9, 0.99)
#: Indexes summarised, per controller (SI units: m for e_*, the command's unit for u_rms).
METRICS = ("e_M", "e_F", "e_rms", "u_rms")
#: Worst plants listed (by the ARC's e_rms; a diverged run counts as the worst).
WORST_KEPT = 5


class MonteCarloSummary:
    """Fold Monte-Carlo records in plant order; :meth:`to_dict` gives the summary."""

    def __init__(self, units: dict[str, str] | None = None) -> None:
        self.n = 0
        self.units = dict(units or {})
        self._vals: dict[tuple[str, str], array] = {(c, m): array("d") for c in ("arc", "pid") for m in METRICS}
        self._div = {"arc": 0, "pid": 0}
        self._worst: list[tuple[float, int, str, float, float]] = []  # min-heap of (key, -order, name, e_rms, e_M)

    def add(self, name: str, arc: Indexes, pid: Indexes) -> None:
        """One plant's ARC and PID scores (call in plant order)."""
        order = self.n
        self.n += 1
        for ctrl, sc in (("arc", arc), ("pid", pid)):
            if sc.diverged:
                self._div[ctrl] += 1
            for m in METRICS:
                self._vals[(ctrl, m)].append(float(getattr(sc, m)))
        key = math.inf if arc.diverged or not math.isfinite(arc.e_rms) else float(arc.e_rms)
        item = (key, -order, name, float(arc.e_rms), float(arc.e_M))
        if len(self._worst) < WORST_KEPT:
            heapq.heappush(self._worst, item)
        elif item > self._worst[0]:
            heapq.heapreplace(self._worst, item)

    def to_dict(self) -> dict[str, Any]:
        """``{"plants", "diverged", "quantiles", "worst", "units"}`` (NaN and inf as null).

        ``quantiles[ctrl][metric]`` holds ``p50``, ``p90``, ``p99`` and ``max`` over the plants
        that did not diverge (linear interpolation, numpy's default); ``worst`` lists up to
        :data:`WORST_KEPT` plants, worst first, with the ARC's ``e_rms`` and ``e_M`` (m).
        """
        q: dict[str, dict[str, Any]] = {}
        for ctrl in ("arc", "pid"):
            q[ctrl] = {}
            for m in METRICS:
                v = np.frombuffer(self._vals[(ctrl, m)], dtype=float) if self.n else np.empty(0)
                v = v[np.isfinite(v)]
                d: dict[str, Any] = {f"p{int(round(p * 100))}": (float(np.quantile(v, p)) if v.size else None)
                                     for p in QUANTILES}
                d["max"] = float(np.max(v)) if v.size else None
                q[ctrl][m] = d
        worst = sorted(self._worst, reverse=True)
        return {"plants": self.n, "diverged": dict(self._div), "quantiles": q, "units": dict(self.units),
                "worst": [{"name": name, "arc_e_rms": _nn(e), "arc_e_M": _nn(em)} for _k, _o, name, e, em in worst]}


def _nn(x: float) -> float | None:
    return float(x) if math.isfinite(x) else None


__all__ = ["MonteCarloSummary", "QUANTILES", "METRICS", "WORST_KEPT"]
