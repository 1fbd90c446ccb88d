"""Frequency response u -> q from an excitation log, and what the rigid model lacks.

Method
------
1. **Broadband segments.**  A drive's frequency-response tool injects a PRBS,
   noise or chirp into the command while the axis moves slowly; the closed
   loop's own command is narrow-band (the reference) plus the feedback's answer
   to encoder noise, a background that is there whenever the axis moves.  The
   command is high-passed at ``fs / 10`` (zero-phase Butterworth) and its RMS
   taken over 0.1-s blocks; a block is broadband when that RMS is at least
   ``BROADBAND_FACTOR`` times the median of the moving blocks
   (``BROADBAND_FACTOR_LONG`` on blocks of ``BROADBAND_LONG_BLOCK`` samples or
   more, where that background is steady) and holds at
   least a quarter of the block's command variance.  Runs of such blocks at
   least ``MIN_SEGMENT_S`` long are the segments.
2. **Estimate.**  H1 = P_uq / P_uu with coherence (Welch averaging of
   ``scipy.signal.csd`` / ``welch``, Hann windows, half overlap, linear detrend
   per window so the constant-velocity ramp drops out), averaged over the
   segments with their window counts.  Without segments the whole log is used
   (its content is then the reference's: it backs the rigid model at low
   frequency only); with segments, the whole log's estimate extends the band
   below the segments' first bins.  In a closed loop H1 is unbiased where the injection
   dominates the command; where the feedback of encoder noise dominates it
   tends to minus the controller's inverse, which is why the segments are
   chosen by the command's broadband level and not by coherence alone, and
   why a bin whose position density stays below ``MEASURABLE_SNR`` times the
   encoder's white floor (read near Nyquist as :func:`encoder_noise` reads it,
   the rigid body taken out) gets coherence 0: the reading there is the noise.
3. **Compare.**  ``R = H / H_rigid`` with ``H_rigid`` the identified rigid
   body ``1 / (M s^2 + B s)`` sampled behind the zero-order hold
   (:func:`commission.controllers.linear.rigid_frequency_response`).  The band
   the data back is the run of coherent bins (``gamma^2 >= BAND_COHERENCE``),
   from the lowest, in which ``|R|`` is within ``BAND_GAIN_TOL`` and its phase
   within ``BAND_PHASE_TOL_DEG``; it ends at the first two consecutive
   coherent bins outside.  A run with only one bin inside is not a band: the
   next run is taken (:func:`backed_band`).
4. **Fit.**  Candidate plants (rigid; a mode seen on the load side; a mode
   seen on the motor side, with its anti-resonance at ``f_r sqrt(1 - r)``),
   each with an input delay and a scale on the mass, are evaluated with the
   exact sampled response :meth:`commission.controllers.linear.SampledPlant.frequency_response`
   and fitted by ``scipy.optimize.least_squares`` to the log-magnitude and the
   phase of H, each bin weighted by its inverse variance
   ``2 n_avg gamma^2 / (1 - gamma^2)`` (gamma^2 capped at ``COHERENCE_CAP``).
   Starts come from the data: the delay from the phase slope of R, the
   resonance from the peak of ``|R|``, the anti-resonance from its dip below
   the peak.  The structure with the least information criterion wins
   (:attr:`StructureFit.score`: BIC with the residuals' scale unknown,
   ``n ln(cost / n) + k ln n`` for n residuals and k free parameters: a fair
   comparison whether or not the model explains the data to their coherence,
   with no threshold of its own), and a mode only counts when it changes the
   fitted response by more than ``BAND_GAIN_TOL`` somewhere in the fitted
   range and its frequency and damping are not on their bounds.  The load ratio of a load-side mode does not show in u -> q (the
   response is ``(2 zeta w s + w^2) / (M s^2 (s^2 + 2 zeta w s + w^2))`` for
   any ratio): it is reported at 0.5 with ``mode_ratio_identified`` false.
5. **More modes.**  While the measured response departs from the fit beyond
   the estimate's uncertainty (:func:`departures`), one more mode is tried
   (:class:`ExtraMode`: a unit-DC-gain factor, with or without its
   anti-resonance), from the departures and afresh from the peaks of ``|R|``,
   and kept when it lowers the criterion and passes the same checks; up to
   ``MAX_MODES``.  Each parameter gets a standard deviation from the
   Jacobian at the solution (``(J^T J)^-1``, scaled by the reduced chi-square
   when above 1): statistical only, it does not hold the bias of a model
   that is not the plant's.  Two modes are then refitted as the simulator's
   plant, two appendages on the motor (:func:`plant_fit`); what is still
   left is reported as departures, each named by its frequency.
6. **Encoder noise** (:func:`encoder_noise`): the floor of ``q - P u``'s
   spectrum high in the band, less quantization's ``step^2 / 12``.

scipy.linalg on the 5x5 matrices of the sampled plant spends milliseconds in
BLAS thread hand-offs on a busy machine (a thousand times its single-thread
cost), so the fit runs under ``threadpoolctl.threadpool_limits(1)``.

Modules
-------
* :mod:`~commission.identify.frf.settings`: the thresholds and sizes named above;
* :mod:`~commission.identify.frf.estimate`: steps 1-3 (:func:`broadband_segments`, :func:`estimate`,
  :func:`backed_band`);
* :mod:`~commission.identify.frf.model`: the candidate plants (:class:`StructureFit`, :class:`ExtraMode`);
* :mod:`~commission.identify.frf.structfit`: step 4's fit of one structure (:func:`fit_structure`) and
  the departures of a fit from the data (:func:`departures`);
* :mod:`~commission.identify.frf.modes`: step 5 (more modes, fewer modes, :func:`plant_fit`);
* :mod:`~commission.identify.frf.result`: :class:`FrequencyResponse` and its ident.json record;
* :mod:`~commission.identify.frf.response`: :func:`frequency_response`, the steps in order;
* :mod:`~commission.identify.frf.noise`: step 6 (:func:`encoder_noise`).
"""

from __future__ import annotations

from commission.identify.frf.settings import (BAND_COHERENCE, BAND_GAIN_TOL, BAND_PHASE_TOL_DEG, BLOCK_S,
    BROADBAND_FACTOR, BROADBAND_FACTOR_LONG, BROADBAND_FRACTION, BROADBAND_LONG_BLOCK, COHERENCE_CAP,
    DEPARTURE_ALPHA, FIT_COHERENCE, MAX_DAMPING, MIN_DAMPING,
    MAX_DELAY_SAMPLES, MAX_MODES, MEASURED_POINTS, MIN_FIT_BINS, MIN_SEGMENT_S, RESOLUTION_HZ, SCREEN_KEEP,
    SCREEN_NFEV, STRUCTURES, WHOLE_LOG_RESOLUTION_HZ)
from commission.identify.frf.model import ExtraMode, StructureFit
from commission.identify.frf.estimate import backed_band, broadband_segments, estimate
from commission.identify.frf.structfit import Departure, departures, fit_structure
from commission.identify.frf.modes import PlantFit, plant_fit
from commission.identify.frf.result import FrequencyResponse
from commission.identify.frf.response import frequency_response
from commission.identify.frf.noise import NOISE_BAND, EncoderNoise, encoder_noise

__all__ = ["BAND_COHERENCE", "BAND_GAIN_TOL", "BAND_PHASE_TOL_DEG", "BLOCK_S", "BROADBAND_FACTOR",
           "BROADBAND_FACTOR_LONG", "BROADBAND_LONG_BLOCK",
           "BROADBAND_FRACTION", "COHERENCE_CAP", "DEPARTURE_ALPHA", "FIT_COHERENCE", "MAX_DAMPING", "MIN_DAMPING",
           "MAX_DELAY_SAMPLES", "MAX_MODES", "MEASURED_POINTS", "MIN_FIT_BINS", "MIN_SEGMENT_S", "RESOLUTION_HZ",
           "SCREEN_KEEP", "SCREEN_NFEV", "STRUCTURES", "WHOLE_LOG_RESOLUTION_HZ", "ExtraMode", "StructureFit",
           "backed_band", "broadband_segments", "estimate", "Departure", "departures", "fit_structure", "PlantFit",
           "plant_fit", "FrequencyResponse", "frequency_response", "NOISE_BAND", "EncoderNoise", "encoder_noise"]
