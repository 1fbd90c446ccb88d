"""The ``commission validate`` pipeline: tuning.json -> report, gate verdict, controller.json.

Steps (numerics in :mod:`commission.controllers`; this module orchestrates):

1. Inputs are checked before any simulation: the gate TOML
   (:func:`commission.gate.load_gate`), tuning.json (strict schema), the seed
   and the Monte-Carlo count, and the output folder (an existing output file
   is refused without ``force``).
2. The scenario matrix (:func:`commission.scenarios.scenario_matrix`): the 12
   fixed scenarios (Case 1 and Case 2 x nominal, payload at both theta_1
   bounds, friction +-20 %, the delta_d disturbance step), the robustness
   scenarios (one more sample of input delay; a known mode moved and less damped) and
   ``n_monte_carlo`` plants drawn from the theta box with
   ``numpy.random.default_rng(seed)``.
3. Every scenario is simulated with the tuned ARC and with the PID baseline
   (:func:`commission.controllers.simulate.simulate`: exact ZOH plant with
   :func:`~commission.scenarios.plant_substeps` sub-steps, the encoder quantization of the tuning, the
   actuator limit ``spec.u_max``, abort when ``|q - q_d|`` exceeds the
   envelope's travel).  The runs are independent and the compiled loop
   releases the GIL, so they are spread over a thread pool (one thread per
   CPU by default); results do not depend on the number of threads.  The ARC
   is simulated with the gains *as read back from the controller.json
   layout*, runtime guards included (:func:`runtime_guards`), so what was
   validated is what is deployed.
4. The gate (:mod:`commission.gate`) is checked on every scenario, the
   robustness ones included, and on the stability margins of the ARC on the
   identified plant (:mod:`commission.robustness`,
   :func:`commission.gate.margin_checks`: gate.toml's margin keys, by default
   the tuning spec's ``[margins]``); the floors (:data:`commission.gate.FLOORS`:
   no divergence anywhere, the spec's margin floors, ...) hold whatever
   gate.toml says.  The robustness part is also listed apart in the report.
   Above the band the log backs, the ARC must keep robust stability ``||W T|| < 1``
   against the uncertainty weight of :mod:`commission.evidence`, and where the log
   measured the response, its modulus margin floor on the coherent measured bins
   (criterion ``margins``, scenarios ``evidence/...`` and ``measured/...``).
5. Outputs: ``validation.json`` (every index of every run, the gate and every
   check), ``report.md`` (+ the PNGs the CLI draws), and ``controller.json``
   only when every check passed.  With ``force`` and a failing gate a
   controller.json left by an earlier run is removed, so that the folder never
   pairs a failing report with a deployable file.

Modules
-------
* :mod:`~commission.validate.results`: the result types (:class:`RunRecord`, :class:`Trace`,
  :class:`ValidationResult`, written as validation.json) and the names of the files validate writes;
* :mod:`~commission.validate.guards`: the runtime guards (:func:`runtime_guards`, :func:`guard_values`)
  and the ARC gains as controller.json holds them (:func:`deployable_gains`);
* :mod:`~commission.validate.stage`: the stage itself (:func:`validate`), the scenario runs and the
  certification of the default payload range (:func:`certify_default_payload`);
* :mod:`~commission.validate.controller_file`: building controller.json (:func:`controller_config`,
  :func:`validated_record`, :func:`not_better_flag`);
* :mod:`~commission.validate.provenance`: tuning.json checked against its ident.json (:func:`check_provenance`);
* :mod:`~commission.validate.outputs`: the command's entry (:func:`run_validate`) and the files it writes
  (:func:`write_outputs`).
"""

from commission.tuning import log_sha256_of
from commission.validate.controller_file import (NOMINAL_RATE_RTOL, certified_validity, controller_config,
                                                 not_better_flag, validated_record)
from commission.validate.guards import (GUARD_ACCEL_MARGIN, GUARD_E_M_FACTOR, GUARD_FROZEN_MIN, GUARD_NOISE_SIGMAS,
                                        GUARD_REJECT_TIME, GUARD_SPEED_MARGIN, deployable_gains, envelope_acceleration,
                                        guard_values, holding_force, runtime_guards)
from commission.validate.outputs import FigureWriter, ValidateOutcome, output_names, run_validate, write_outputs
from commission.validate.provenance import check_provenance
from commission.validate.results import (CONTROLLER_NAME, DEFAULT_MONTE_CARLO, FIGURE_NAMES, FLAGGED_NAME, REPORT_NAME,
                                         USER_FIGURE_NAME, VALIDATION_KIND, VALIDATION_NAME, VALIDATION_SCHEMA_VERSION,
                                         Progress, RunRecord, Trace, ValidationResult)
from commission.validate.stage import (FAULT_ZERO_SAMPLES, MC_CHUNK, certify_default_payload, latched_fault_from,
                                       latched_fault_start, performance_set, validate)

__all__ = [
    "DEFAULT_MONTE_CARLO", "RunRecord", "Trace", "ValidationResult", "ValidateOutcome", "validate",
    "controller_config", "validated_record", "not_better_flag", "FLAGGED_NAME", "run_validate", "write_outputs",
    "output_names", "check_provenance", "deployable_gains", "runtime_guards", "guard_values", "envelope_acceleration",
    "holding_force", "log_sha256_of", "latched_fault_from", "latched_fault_start", "performance_set",
    # also re-exported (importable from commission.validate before the split):
    "NOMINAL_RATE_RTOL", "certified_validity", "GUARD_ACCEL_MARGIN", "GUARD_E_M_FACTOR", "GUARD_FROZEN_MIN",
    "GUARD_NOISE_SIGMAS", "GUARD_REJECT_TIME", "GUARD_SPEED_MARGIN", "FigureWriter", "CONTROLLER_NAME", "FIGURE_NAMES",
    "REPORT_NAME", "USER_FIGURE_NAME", "VALIDATION_KIND", "VALIDATION_NAME", "VALIDATION_SCHEMA_VERSION", "Progress",
    "FAULT_ZERO_SAMPLES", "MC_CHUNK", "certify_default_payload",
]
