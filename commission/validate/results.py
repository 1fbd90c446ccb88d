"""The validation's result types: one run (:class:`RunRecord`), a kept trace (:class:`Trace`) and the
whole result (:class:`ValidationResult`, written as validation.json), with the file names validate writes.

validation.json's layout is one table, :mod:`commission.formats.validation_json` (a run's keys are its
rows: :meth:`RunRecord.to_dict`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Callable, Mapping

import numpy as np

from commission.controllers.arc import ArcGains
from commission.gate import GateVerdict
from commission.evidence import Evidence, RobustStability
from commission.formats.validation_json import RUN_KEYS, VALIDATION_KIND, VALIDATION_SCHEMA_VERSION
from commission.robustness import CONTROLLERS, BoxRobustness, LoopMargins, MarginFloors, worst
from commission.scenarios import plant_substeps
from commission.controllers.metrics import Indexes


Progress = Callable[[int, int], None]

#: Monte-Carlo plants by default.
DEFAULT_MONTE_CARLO = 64

REPORT_NAME = "report.md"
VALIDATION_NAME = "validation.json"
CONTROLLER_NAME = "controller.json"
#: The ARC of a validation that failed only on the comparison with the PID yardstick
#: (:func:`commission.gate.safe_not_better`): loadable with ``load_controller``, flagged in
#: ``validated.flag``; never named controller.json (CONTRACT: that file means every gate passed).
FLAGGED_NAME = "controller_not_better.json"
#: Figures the CLI draws (cli/plots_validate.py); listed here so that --force checks cover them.
#: The tracking figure of the machine's own moves, drawn only when the spec gives them.
USER_FIGURE_NAME = "tracking_user.png"
FIGURE_NAMES = ("tracking_case1.png", "tracking_case2.png", "theta_hat.png", "control_input.png",
                "monte_carlo.png", "loops.png")


@dataclass(frozen=True)
class RunRecord:
    """ARC and PID on one scenario.

    Attributes
    ----------
    name : str
    tags : tuple of str
    arc, pid : Indexes
        Indexes (SI units; NaN when diverged) and the peak |u|.
    arc_t_abort, pid_t_abort : float
        Time of the abort, s (NaN when the run completed).
    theta_final : tuple of 3 float
        ARC estimates at the last sample.
    theta_true : tuple of 3 float
        The scenario plant's [1/M, B/M, -offset/M] (friction not included).
    """

    name: str
    tags: tuple[str, ...]
    arc: Indexes
    pid: Indexes
    arc_t_abort: float
    pid_t_abort: float
    theta_final: tuple[float, float, float]
    theta_true: tuple[float, float, float]

    def to_dict(self) -> dict[str, Any]:
        """validation.json's ``runs[i]``: the table's run keys (:data:`commission.formats.validation_json.RUN_KEYS`)."""
        return {k: _json_value(getattr(self, k)) for k in RUN_KEYS}


@dataclass(frozen=True)
class Trace:
    """Time histories of one fixed scenario, for the figures.

    Arrays stop at an abort (``y_arc`` and ``y_pid`` may be shorter than ``t``).

    Attributes
    ----------
    t, qd : numpy.ndarray
        Sample times (s) and desired position (m).
    y_arc, u_arc, y_pid, u_pid : numpy.ndarray
        Measured position (m) and applied command (u-unit).
    theta_hat : numpy.ndarray, shape (n, 3)
        ARC estimates.
    theta_true : tuple of 3 float
    """

    t: np.ndarray
    qd: np.ndarray
    y_arc: np.ndarray
    u_arc: np.ndarray
    y_pid: np.ndarray
    u_pid: np.ndarray
    theta_hat: np.ndarray
    theta_true: tuple[float, float, float]

    @property
    def e_arc(self) -> np.ndarray:
        """Measured ARC tracking error, m."""
        return self.y_arc - self.qd[: self.y_arc.shape[0]]

    @property
    def e_pid(self) -> np.ndarray:
        """Measured PID tracking error, m."""
        return self.y_pid - self.qd[: self.y_pid.shape[0]]


@dataclass(frozen=True)
class ValidationResult:
    """Everything ``validate`` computed.

    Attributes
    ----------
    runs : tuple of RunRecord
        In scenario-matrix order (fixed scenarios, then ``mc/NNN``).
    traces : dict
        Scenario name -> :class:`Trace`, for the fixed scenarios.
    verdict : GateVerdict
        The gate's criteria, each with its limit and measured value, and whether it passed.
    units : dict
        ``{"u": command unit, "q": "m"}``.
    seed : int
        Seed of the Monte-Carlo plants.
    n_monte_carlo : int
        Monte-Carlo plants drawn from the theta box.
    arc_gains : ArcGains
        The gains simulated (read back from the controller.json layout).
    quantization : float
        Encoder resolution simulated, m.
    e_abort : float
        Abort threshold on |q - q_d|, m.
    u_sat : float
        Actuator limit simulated, u-unit.
    elapsed : float
        Wall time of the simulations, s.
    workers : int
        Threads used.
    margins : tuple of LoopMargins
        Stability margins of both loops per plant (:mod:`commission.robustness`).
    margin_floors : MarginFloors
        The spec's floors they are held against.
    loops : tuple of ndarray
        ``(f_hz, L_arc, L_pid)`` on the identified plant, for the loop figure (not in JSON).
    box : BoxRobustness or None
        The ARC over the whole theta box (:class:`commission.robustness.BoxArcCheck`), gated as
        criterion ``margins_box``.
    robustness : GateVerdict or None
        The part of ``verdict`` on the robustness scenarios and the stability margins (required
        like every other check; listed apart in the report).
    executor : dict or None
        Where the simulations ran (:meth:`commission.infra.executor.Executor.describe`); varies with the
        machine, so it is not written to validation.json (which is the same on every executor).
    monte_carlo_summary : dict or None
        Quantiles and worst plants of the Monte-Carlo sample (:mod:`commission.montecarlo`).
    evidence : Evidence or None
        What the certificate rests on: the band the log backs and the uncertainty weight above it
        (:mod:`commission.evidence`).
    evidence_rows : tuple of RobustStability
        Peak ``|W T|`` of the ARC (both linearisations) and the PID, and their margins on the
        measured response.
    validity : mapping or None
        The payload range certified when validate narrowed a defaulted one
        (:func:`certify_default_payload`); None: the tuning's own ``validity`` (or the whole box).
    """

    runs: tuple[RunRecord, ...]
    traces: Mapping[str, Trace]
    verdict: GateVerdict
    units: Mapping[str, str]
    seed: int
    n_monte_carlo: int
    arc_gains: ArcGains
    quantization: float
    e_abort: float
    u_sat: float
    elapsed: float
    workers: int
    margins: tuple[LoopMargins, ...] = ()
    margin_floors: MarginFloors = MarginFloors()
    loops: tuple[np.ndarray, ...] = ()
    robustness: GateVerdict | None = None
    executor: Mapping[str, Any] | None = None
    monte_carlo_summary: Mapping[str, Any] | None = None
    box: BoxRobustness | None = None
    evidence: Evidence | None = None
    evidence_rows: tuple[RobustStability, ...] = ()
    validity: Mapping[str, Any] | None = None

    @property
    def passed(self) -> bool:
        return self.verdict.passed

    def run(self, name: str) -> RunRecord:
        for r in self.runs:
            if r.name == name:
                return r
        raise KeyError(name)

    def to_dict(self) -> dict[str, Any]:
        return {
            "kind": VALIDATION_KIND,
            "schema_version": VALIDATION_SCHEMA_VERSION,
            "passed": self.passed,
            "seed": self.seed,
            "monte_carlo": self.n_monte_carlo,
            "units": dict(self.units),
            "simulation": {"substeps": plant_substeps(1.0 / self.arc_gains.Ts), "quantization": self.quantization,
                           "e_abort": self.e_abort,
                           "u_sat": _nn(self.u_sat), "sample_period": self.arc_gains.Ts},
            "gate": self.verdict.limits.to_dict(),
            "failures": [c.to_dict() for c in self.verdict.failures],
            "worst": {k: c.to_dict() for k, c in self.verdict.worst().items()},
            "runs": [r.to_dict() for r in self.runs],
            "elapsed_s": self.elapsed,
            "monte_carlo_summary": None if self.monte_carlo_summary is None else dict(self.monte_carlo_summary),
            "robustness": None if self.robustness is None else {
                "passed": self.robustness.passed, "required": True,
                "failures": [c.to_dict() for c in self.robustness.failures],
                "checks": len(self.robustness.checks)},
            "margins": {"floors": self.margin_floors.to_dict(), "loops": [m.to_dict() for m in self.margins],
                        "worst": {c: (w.to_dict() if (w := worst(self.margins, c)) is not None else None)
                                  for c in CONTROLLERS}},
            **({} if self.box is None else {"box_robustness": self.box.to_dict(self.margin_floors)}),
            "evidence": None if self.evidence is None else {
                **self.evidence.to_dict(), "loops": [r.to_dict() for r in self.evidence_rows]},
            **({} if self.validity is None else {"validity": dict(self.validity)}),
        }


def _nn(x: float) -> float | None:
    return float(x) if math.isfinite(x) else None


def _json_value(v: Any) -> Any:
    """A record's value as JSON holds it: a score as its dict, a tuple as a list, a number that is not
    finite as null."""
    if isinstance(v, Indexes):
        return v.to_dict()
    if isinstance(v, tuple):
        return [_json_value(x) for x in v]
    if isinstance(v, float):
        return _nn(v)
    return v
