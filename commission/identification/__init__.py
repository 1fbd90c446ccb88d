"""The ``identify`` stage: log in, checked, fitted, bounded, ``ident.json`` out.

This package is the pipeline glue between the loaders (:mod:`commission.logs`,
:mod:`commission.checks`), the numerics (:mod:`commission.identify`) and the
artifact (:class:`commission.artifacts.Identification`).  Errors of the
numerics are re-raised with the file name so that the CLI can print one line.

Modules
-------
* :mod:`~commission.identification.options`: what the stage is told (:class:`IdentifyOptions`,
  :class:`BoundsOptions`) and the checks of ``--input-gain``, ``--fix`` and ``--terms``;
* :mod:`~commission.identification.inputs`: the logs as read: folders expanded
  (:func:`expand_log_paths`), rotary angles converted (:func:`convert_axis`), resampling
  (:func:`resample_log`), the plan.json beside a log (:func:`plan_beside`);
* :mod:`~commission.identification.fitting`: the fit driver (least squares, the delay-aware
  model chosen, the validation error, the position simulation, :func:`fit_quality_warnings`);
* :mod:`~commission.identification.frequency`: the frequency-response step, the encoder noise
  and the ``evidence`` a log without a broadband segment gets;
* :mod:`~commission.identification.record`: the parts of ident.json both ways write alike
  (estimates, bounds record, theta box, time stamp) and :func:`friction_curve`;
* :mod:`~commission.identification.segments`: :func:`identify_log`, one log or several fitted
  together as segments, as a short orchestrator of named steps;
* :mod:`~commission.identification.legs`: a friction test of constant-speed legs
  (:func:`identify_legs`, :func:`leg_refusal`, :func:`classify_logs`);
* :mod:`~commission.identification.files`: :func:`identify_files`, which of the two several logs are.
"""

from __future__ import annotations

from commission.identification.options import (U_UNITS, FIXABLE, FIX_RANGES, BoundsOptions, IdentifyOptions,
    check_input_gain, payload_from_kg, parse_fix, parse_terms)
from commission.identification.inputs import (LOG_EXTENSIONS, MAX_RESAMPLE_FACTOR, PLAN_BESIDE_NAME,
    PLAN_BESIDE_SAMPLES_TOL, convert_axis, expand_log_paths, plan_beside, resample_log)
from commission.identification.fitting import POOR_FIT_RELATIVE_ERROR, UNDETERMINED_REL_STD, fit_quality_warnings
from commission.identification.record import friction_curve
from commission.identification.segments import IDENT_FIGURE_NAMES, IdentifyOutcome, identify_log
from commission.identification.legs import (LEG_FINE_COUNTS, LEG_FINE_SMOOTHING, LEG_SMOOTHING, LEG_SPEED_TOLERANCE,
    LegsOutcome, classify_logs, identify_legs, is_friction_leg, leg_refusal)
from commission.identification.files import identify_files

__all__ = ["U_UNITS", "FIXABLE", "FIX_RANGES", "BoundsOptions", "IdentifyOptions", "check_input_gain",
           "payload_from_kg", "parse_fix", "parse_terms", "LOG_EXTENSIONS", "MAX_RESAMPLE_FACTOR", "PLAN_BESIDE_NAME",
           "PLAN_BESIDE_SAMPLES_TOL", "convert_axis", "expand_log_paths", "plan_beside", "resample_log",
           "POOR_FIT_RELATIVE_ERROR", "UNDETERMINED_REL_STD", "fit_quality_warnings", "friction_curve",
           "IDENT_FIGURE_NAMES", "IdentifyOutcome", "identify_log", "LEG_FINE_COUNTS", "LEG_FINE_SMOOTHING",
           "LEG_SMOOTHING", "LEG_SPEED_TOLERANCE", "LegsOutcome", "classify_logs", "identify_legs",
           "is_friction_leg", "leg_refusal", "identify_files"]
