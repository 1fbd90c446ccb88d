"""Synthetic excitation logs of a linear-motor axis with known parameters.

A commissioning run, simulated: a closed-loop PID with a rough feedforward
tracks a reference made of

* a **friction ladder**: constant-velocity legs at speeds spaced geometrically
  from ``v_min`` to ``v_max``, each run forward and then back over the same
  stretch of travel (so that position-dependent force ripple and the offset
  cancel between the two directions), with short dwells in between; and
* a **multisine** position excitation about the middle of the travel
  (Schroeder phases, equal velocity amplitude per line) for the inertia, with
  many velocity reversals.

and, optionally, a **broadband injection**: a PRBS added to the command on two
slow constant-velocity legs (``ExcitationPlan.injection_s``), from which
:mod:`commission.identify.frf` measures the frequency response.

The plant is :func:`commission.controllers.plant.plant_step` (Stribeck
friction with a stiction switch model, offset and ripple; optionally a
structural mode and an input delay) under zero-order hold with sub-steps; the encoder quantizes ``round(x / lsb) * lsb`` after optional
Gaussian position noise.  :func:`write_log_h5` and :func:`write_log_csv` write
the result in the excitation-log format of CONTRACT section 1.

Everything random comes from the ``numpy.random.Generator`` passed in.

Where it sits
-------------
This package is the synthetic-log generator of the tests, the benchmarks and
``sample_data/make_sample_data.py``.  Production code uses two of its pieces:
``commission excite``'s pre-simulation plays a plan through the holding loop
(:func:`commission.synth.simulation._closed_loop`) on a rigid
:class:`~commission.synth.truth.AxisTruth` model, and :mod:`commission.true_axis`
reads an :class:`AxisTruth`.

Modules
-------
* :mod:`~commission.synth.truth`: the known truth (:class:`AxisTruth`) and the log's channels and units;
* :mod:`~commission.synth.random_axes`: random axes (:func:`random_axis`, :func:`rigid_random_axis`);
* :mod:`~commission.synth.excitation`: the legacy run's reference (:class:`ExcitationPlan`, :class:`Leg`,
  :class:`Reference`);
* :mod:`~commission.synth.simulation`: the holding loop and the simulated log (:func:`simulate_excitation`,
  :func:`loop_gains`);
* :mod:`~commission.synth.record`: the recording recipe (:func:`excitation_plan`, :func:`random_axis_limits`,
  :func:`record_random_axis_log`, :func:`record_axis_log`, :func:`write_random_axis_log`);
* :mod:`~commission.synth.log_files`: the CONTRACT section 1 writers (:func:`write_log_h5`, :func:`write_log_csv`).
"""

from commission.synth.excitation import ExcitationPlan, Leg, Reference
from commission.synth.log_files import write_log_csv, write_log_h5
from commission.synth.random_axes import (RANDOM_MASS_KG, RANDOM_MODE_COUNT_P, RANDOM_MODE_HZ, RANDOM_PEAK_ACCEL,
                                          RANDOM_RATES, random_axis, rigid_random_axis)
from commission.synth.record import (EXCITE_MAX_SAMPLES, LOG_KINDS, RANDOM_A_MAX_FRACTION, RANDOM_MASS_GUESS,
                                     RANDOM_TRAVEL, SHORT_PLAN, RandomAxisLog, excitation_plan, random_axis_limits,
                                     record_axis_log, record_random_axis_log, write_random_axis_log)
from commission.synth.simulation import loop_gains, simulate_excitation
from commission.synth.truth import LOG_CHANNELS, Q_UNITS, U_UNITS, AxisTruth

__all__ = ["AxisTruth", "LOG_CHANNELS", "Q_UNITS", "U_UNITS", "RANDOM_MASS_KG", "RANDOM_MODE_COUNT_P", "RANDOM_MODE_HZ",
           "RANDOM_PEAK_ACCEL", "RANDOM_RATES", "random_axis", "rigid_random_axis", "EXCITE_MAX_SAMPLES", "LOG_KINDS",
           "RANDOM_A_MAX_FRACTION", "RANDOM_MASS_GUESS", "RANDOM_TRAVEL", "SHORT_PLAN", "RandomAxisLog",
           "excitation_plan", "random_axis_limits", "record_axis_log", "record_random_axis_log",
           "write_random_axis_log", "ExcitationPlan", "Leg", "Reference", "loop_gains", "simulate_excitation",
           "write_log_csv", "write_log_h5"]
