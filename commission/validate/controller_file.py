"""controller.json from a validation: its ``validated`` section (:func:`validated_record`), the
whole file (:func:`controller_config`), the certified validity and the not-better flag.
"""

from __future__ import annotations

import datetime as _dt
from typing import Any

import commission
from commission.controller_config import ControllerConfig, ControllerProvenance
from commission.gate import safe_not_better
from commission.scenarios import plant_substeps
from commission.spec import nominal_rate
from commission.tuning import Tuning, log_sha256_of
from commission.validate.results import ValidationResult, _nn


def validated_record(result: ValidationResult) -> dict[str, Any]:
    """The ``validated`` section of controller.json.

    ``gate``: the resolved limits; ``worst``: per criterion the worst value and
    its scenario; ``nominal``: the ARC's indexes on the identified plant per
    trajectory (``case1``, ``case2``), i.e. the performance the identified model predicts.
    """
    worst = result.verdict.worst()
    nominal = {r.tags[0]: r.arc.to_dict() for r in result.runs if "nominal" in r.tags}
    return {
        "gate": result.verdict.limits.to_dict(),
        "nominal": nominal,
        "worst": {k: {"scenario": c.scenario, "value": _nn(c.value), "limit": _nn(c.limit)} for k, c in worst.items()},
        "scenarios": len(result.runs),
        "monte_carlo": result.n_monte_carlo,
        "seed": result.seed,
        "simulation": {"substeps": plant_substeps(1.0 / result.arc_gains.Ts), "quantization": result.quantization,
                       "e_abort": result.e_abort,
                       "u_sat": _nn(result.u_sat)},
    }


#: controller.json states the nominal rate when the validated one is within this of it: rounding in a
#: rate estimated from time stamps, well inside the loader's 1e-9 check of sample_period x sample_rate.
NOMINAL_RATE_RTOL = 1e-10


def controller_config(result: ValidationResult, tuning: Tuning, tuning_sha256: str,
                      created_utc: str | None = None, *, flagged: bool = False) -> ControllerConfig:
    """The deployable controller of a passed validation.

    With ``flagged``, the ARC of a validation that failed only on the comparison with the PID
    yardstick (:func:`commission.gate.safe_not_better`): its ``validated`` record holds a ``flag``
    (``beats_yardstick`` false, the failed comparison checks and the yardstick's pole).

    Raises
    ------
    ValueError
        When the gate did not pass (a controller is never built from a failed validation), unless
        ``flagged`` and the validation is safe but not better.
    """
    if flagged and not safe_not_better(result.verdict):
        raise ValueError("controller_config: flagged only when the gate failed on the PID comparison alone")
    if not result.passed and not flagged:
        raise ValueError("controller_config: the gate failed; no controller is emitted")
    prov = ControllerProvenance(
        log_sha256=log_sha256_of(tuning),
        ident_sha256=tuning.provenance.ident_sha256,
        tuning_sha256=tuning_sha256,
        tool_version=commission.__version__,
        created_utc=created_utc or _dt.datetime.now(_dt.timezone.utc).strftime("%Y-%m-%dT%H:%M:%SZ"),
    )
    # The nominal rate the drive is programmed with (2500, not 2500.0000000058 estimated from a log's
    # time stamps); sample_period stays the period validated, within the loader's 1e-9 of 1/sample_rate.
    rate = nominal_rate(tuning.spec.sample_rate, rel=NOMINAL_RATE_RTOL)
    record = validated_record(result)
    if flagged:
        record["flag"] = not_better_flag(result, tuning)
    return ControllerConfig(gains=result.arc_gains, sample_rate=rate,
                            units=dict(tuning.identification.units), validated=record,
                            provenance=prov, validity=certified_validity(result, tuning))


def certified_validity(result: ValidationResult, tuning: Tuning) -> dict[str, Any] | None:
    """The payload range the certificate claims: validate's narrowing, else tune's, else None (the whole box)."""
    v = result.validity if result.validity is not None else tuning.validity
    return None if v is None else dict(v)


def not_better_flag(result: ValidationResult, tuning: Tuning) -> dict[str, Any]:
    """The ``validated.flag`` of a flagged ARC: what it failed and what the PID yardstick is."""
    ys = tuning.pid_yardstick or {}
    return {"beats_yardstick": False, "verdict": "safe_not_better",
            "failed": [c.to_dict() for c in result.verdict.failures],
            "pid_pole": tuning.pid_pole, "pid_yardstick_method": ys.get("method", "unrecorded"),
            "pid_gains": {"Kp": tuning.pid.Kp, "Ki": tuning.pid.Ki, "Kd": tuning.pid.Kd,
                          "M_hat": tuning.pid.M_hat, "B_hat": tuning.pid.B_hat}}
