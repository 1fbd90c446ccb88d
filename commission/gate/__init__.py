"""The validation gate of ``commission validate`` (``gate.toml``).

The gate decides whether a tuned ARC may be deployed.  Every safety criterion is checked for the
ARC on **every** scenario of the validation matrix (the fixed scenarios and every Monte-Carlo
plant), the error limits on the performance scenarios ("What each scenario certifies" below); the
PID baseline enters only through the comparison criteria.  A criterion that fails is reported with
its scenario, its value and its limit; all failures are listed, not only the first.  Errors are
measured on the encoder (``e = y - q_d``, as in the paper).

``gate.toml``: one table ``[gate]``, every key optional.  Its keys, their defaults, ranges and
units are the rows of :data:`commission.formats.gate_toml.GATE_KEYS` (``validate --help``,
docs/interface.md §6 and docs/schemas/gate.schema.json are generated from them); this package
validates through that table (:func:`gate_from_mapping`) and resolves the defaults from it
(:func:`resolve_gate`).

Which module holds what
-----------------------
* :mod:`commission.gate.spec` -- what a gate.toml says (:class:`GateSpec`, :class:`ErrorLimit`,
  :func:`gate_from_mapping`, :func:`load_gate`);
* :mod:`commission.gate.limits` -- the gate resolved for one axis (:class:`GateLimits`,
  :func:`resolve_gate`, :func:`absolute_mode`, :func:`scenario_error_limit`,
  :func:`comparison_reported`) and what the defaults mean;
* :mod:`commission.gate.check` -- one check (:class:`Check`) and the criterion names (:data:`CRITERIA`);
* :mod:`commission.gate.verdict` -- every criterion on every scenario (:func:`evaluate_gate`,
  :class:`GateVerdict`, :func:`performance_scenarios`, :func:`safety_failures`, :func:`safe_not_better`);
* :mod:`commission.gate.comparison` -- the ARC against the PID yardstick (:func:`required_factor`,
  :func:`arc_vs_pid_quantile_checks`, :func:`arc_vs_pid_nominal_checks`);
* :mod:`commission.gate.floors` -- what no gate.toml can lower (:data:`FLOORS`) and the margin checks
  (:func:`margin_checks`, :func:`box_checks`);
* :mod:`commission.gate.search` -- the search's own verdict (:func:`search_infeasible_line`).

What each scenario certifies
----------------------------
A certificate makes two kinds of claim, and each scenario backs the one it has evidence for:

* **SAFETY** -- the loop stays stable, within the drive and not chattering: no divergence, peak
  |u| below ``u_max``, ``c_u``, the floors (:data:`FLOORS`) and the margins over the whole box.
  Every scenario is held to these: the identified plant, the box corners and variants (payload
  light/heavy, friction -+20 %, the load step, one more sample of delay, the mode's variants) and
  every Monte-Carlo plant.  A plant the controller may meet must not make it unsafe, however
  hypothetical the plant.
* **PERFORMANCE** -- how well it tracks: the absolute error limits ``e_F``, ``e_M``, ``e_rms``
  (from the encoder, the travel and the spec's ``[targets]``) and the ARC-vs-yardstick quantiles.
  The error limits hold on the plant the log identified (``<case>/nominal``), and on the scenarios
  whose range the user stated: the payload corners when the payload range was given
  (``commission identify --payload-max``), the load step when the load-force bound was given
  (``--disturbance-bound``) (:func:`performance_scenarios`).  The Monte-Carlo distribution
  certifies performance statistically, through the quantiles of the ARC-vs-PID factor
  (:func:`arc_vs_pid_quantile_checks`), never through its single worst plant.  On the identified
  plant itself the ARC must beat the yardstick outright (:func:`arc_vs_pid_nominal_checks`).

Why: an absolute error limit on a corner that nobody stated -- the default payload of up to three
times the axis's mass, ten times the stiction as a load -- measures the tool's guess, not the
machine's requirement.  It refused controllers that are stable on the true axis and track at a
fraction of the best PID's error there (docs/robustness.md, "What each scenario certifies").  The
safety criteria stay on those corners: what the certificate may not do anywhere is fail.  A
controller that keeps its error within limits on the identified plant is held to the limits there,
where the evidence is.
"""

from commission.formats.gate_toml import MARGIN_KEYS
from commission.gate.check import CRITERIA, Check
from commission.gate.comparison import (ARC_VS_PID_QUANTILES, BEYOND_EVIDENCE, COMPARISON_CRITERIA,
                                        NOMINAL_COMPARISON_VARIANTS,
                                        arc_vs_pid_nominal_checks, arc_vs_pid_quantile_checks, required_factor,
                                        scenario_group)
from commission.gate.floors import FLOORS, GATED_PLANT, Floor, FloorContext, box_checks, check_floors, margin_checks
from commission.gate.limits import (ABSOLUTE_FIXED, ABSOLUTE_REPORTED, ABSOLUTE_YARDSTICK, DEFAULT_ARC_VS_PID,
                                    DEFAULT_ARC_VS_PID_MEDIAN, DEFAULT_ARC_VS_PID_NOMINAL, DEFAULT_ARC_VS_PID_P90,
                                    DEFAULT_ARC_VS_PID_SLACK_LSB, DEFAULT_C_U, SATURATION_TOL, TARGET_FACTOR,
                                    GateLimits, absolute_mode, comparison_reported, resolve_gate,
                                    scenario_error_limit)
from commission.gate.search import (SEARCH_FEASIBLE, SEARCH_GATE_MISSED, SEARCH_STABILITY_MISSED,
                                    search_infeasible_line)
from commission.gate.spec import ErrorLimit, GateSpec, gate_from_mapping, load_gate
from commission.gate.verdict import (PERFORMANCE_VARIANTS, SAFETY_CRITERIA, GateVerdict, evaluate_gate,
                                     performance_scenarios, safe_not_better, safety_failures)

__all__ = ["ABSOLUTE_FIXED", "ABSOLUTE_REPORTED", "ABSOLUTE_YARDSTICK", "ARC_VS_PID_QUANTILES", "COMPARISON_CRITERIA",
           "CRITERIA", "Check", "DEFAULT_ARC_VS_PID", "DEFAULT_ARC_VS_PID_MEDIAN", "DEFAULT_ARC_VS_PID_NOMINAL",
           "DEFAULT_ARC_VS_PID_P90", "DEFAULT_ARC_VS_PID_SLACK_LSB", "DEFAULT_C_U", "ErrorLimit", "FLOORS", "Floor",
           "FloorContext", "GATED_PLANT", "GateLimits", "GateSpec", "GateVerdict", "MARGIN_KEYS",
           "NOMINAL_COMPARISON_VARIANTS", "PERFORMANCE_VARIANTS", "SAFETY_CRITERIA", "SATURATION_TOL",
           "SEARCH_FEASIBLE", "SEARCH_GATE_MISSED", "SEARCH_STABILITY_MISSED", "TARGET_FACTOR", "absolute_mode",
           "arc_vs_pid_nominal_checks", "BEYOND_EVIDENCE", "arc_vs_pid_quantile_checks", "box_checks", "check_floors",
           "comparison_reported",
           "evaluate_gate", "gate_from_mapping", "load_gate", "margin_checks", "performance_scenarios",
           "required_factor", "resolve_gate", "safe_not_better", "safety_failures", "scenario_error_limit",
           "scenario_group", "search_infeasible_line"]
