"""``commission excite``: design the excitation run from the machine's limits, and prove it safe.

One recorded run should back everything ``identify`` reports, so the plan is a
sequence of segments, each made for one purpose:

* ``bump`` (only without ``[axis] mass``): a short command doublet at rest, held by
  the drive's loop, from which the mass can be read before anything larger runs;
* ``ladder``: a friction ladder, constant-velocity legs at log-spaced speeds, each
  forward and then back over the same stretch (ripple and offset cancel between the
  two directions), for the Stribeck curve, B and the friction map;
* ``moves``: back-and-forth S-curve moves (:func:`commission.controllers.trajectory.scurve_schedule`)
  at the largest acceleration the command budget allows, for M;
* ``injection``: a broadband command added to the holding loop's while the axis
  cruises (friction keeps one sign and acts as a constant force): a Schroeder-phase
  multisine whose line amplitudes rise as ``f**shaping`` over ``band_hz``, or a PRBS of
  one bit per sample, for the frequency response, the modes and the delay.  The cruise
  is raised where the pre-simulation shows the injection's own velocity swing reaching
  it (the velocity would cross zero, and Coulomb friction would damp the modes it is
  there to measure), unless ``plan.injection_speed`` sets it;
* ``sine``: optionally, a stepped sine at chosen frequencies, on the same cruises.

Every move is an S-curve of the project's trajectory generator; the position stays
within ``+-(1 - margin) travel / 2`` of the start.

Pre-simulation
--------------
The plan is played, before anything is written, through the holding loop of
``[drive]`` on a *conservative* rigid model: two masses bracket the axis (the given
``mass`` divided and multiplied by ``plan.mass_range``; without a mass, the heaviest
axis that still reaches ``a_max`` with ``u_max`` and that divided by ``5 mass_range``),
friction and viscous damping from ``[axis]`` when given, no quantization.  The loop is
the one of the synthetic logs (:func:`commission.synth.simulation._closed_loop`, a PID with the
derivative on the backward-difference velocity).  The command is not clipped in the
pre-simulation, so that its peak is seen.  Peak ``|u|``, the position range, peak
``|v|`` (backward difference) and peak ``|a|`` (second difference) are checked against
``[limits]``.  A broken limit in an injection segment (or the bump) lowers the
injection, one in another segment the moves' top speed and acceleration, by 0.9 times
the limit over the peak (by 5 % to a half; up to :data:`MAX_INJECTION_RETRIES` retries
in all); a loop that diverges, or a limit still broken, and the plan is refused naming
the limit, the segment and the model.

The band the plan will back
---------------------------
:func:`predict_band` says, before the machine time is spent, up to which frequency a recording
of the plan will back the model: the injection's spectrum on identify's bins against the
encoder's floor (``[axis] encoder_step``, ``encoder_noise``), through the holding loop on the
rigid model, gives the expected coherence, and identify's own band rule
(:func:`commission.identify.frf.backed_band`) the band.  Against ``[evidence] target_hz`` (or
1.5 times ``first_mode_hz``) a short band is warned with what would reach the target
(:func:`band_lines`).

:func:`simulate_plan` plays a plan on a known-truth :class:`commission.synth.AxisTruth`
through the same loop and returns a log in the CONTRACT §1 format (tests, sample data).

Modules
-------
* :mod:`~commission.excite.limits`: limits.toml's keys and checks (:class:`ExciteSpec`), and the sketch
  other commands print (:func:`limits_toml_sketch`);
* :mod:`~commission.excite.plan`: the segments and their samples (:func:`design_plan`);
* :mod:`~commission.excite.presim`: the pre-simulation and the planning loop (:func:`plan_run`), and
  :func:`simulate_plan` on a known truth;
* :mod:`~commission.excite.band`: the band the plan will back (:func:`predict_band`, :func:`band_lines`);
* :mod:`~commission.excite.plan_files`: plan.json / .csv / .h5 and the injection windows identify reads
  back (:func:`load_plan_json`, :func:`injection_ranges`).
"""

from __future__ import annotations

from commission.formats.plan_json import PLAN_SCHEMA_VERSION
from commission.excite.limits import (MAX_INJECTION_RETRIES, MAX_OMEGA_T, LOOP_DAMPING,
    PRESIM_SUBSTEPS, Q_UNITS, U_UNITS, INJECTIONS, ExciteSpec, excite_spec_from_mapping, load_excite_spec,
    SKETCH_BANDWIDTH_HZ, limits_toml_sketch)
from commission.excite.plan import (Segment, Plan, mass_bracket, loop_gains_for, ladder_speeds, design_plan)
from commission.excite.plan_files import (PLAN_COLUMNS, plan_columns, write_plan_csv, write_plan_h5,
    injection_ranges, load_plan_json)
from commission.excite.band import (ASSUMED_ENCODER_STEP, MODE_BAND_FACTOR, BandPrediction, expected_coherence,
    predict_band, band_lines)
from commission.excite.presim import (play, simulate_plan, PlanRefused, presimulate, plan_run)

__all__ = ["PLAN_SCHEMA_VERSION", "MAX_INJECTION_RETRIES", "MAX_OMEGA_T", "LOOP_DAMPING", "PRESIM_SUBSTEPS",
           "Q_UNITS", "U_UNITS", "INJECTIONS", "ExciteSpec", "excite_spec_from_mapping", "load_excite_spec",
           "SKETCH_BANDWIDTH_HZ", "limits_toml_sketch", "Segment", "Plan", "mass_bracket", "loop_gains_for",
           "ladder_speeds", "design_plan", "PLAN_COLUMNS", "plan_columns", "write_plan_csv", "write_plan_h5",
           "injection_ranges", "load_plan_json", "ASSUMED_ENCODER_STEP", "MODE_BAND_FACTOR", "BandPrediction",
           "expected_coherence", "predict_band", "band_lines", "play", "simulate_plan", "PlanRefused",
           "presimulate", "plan_run"]
