"""The thresholds and sizes of the frequency-response measurement and fit, with why each is what it is.

One place for the numbers the method of :mod:`commission.identify.frf` names (broadband
detection, resolution, the band's tolerances, the fit's bounds and starts, how many modes).
"""


#: A block is broadband when its high-passed command RMS is this many times the moving blocks' median.
#: The median is the holding loop's answer to the encoder's noise and quantization: on a noisy or coarse
#: encoder an injection within a_max stands only 4-6 times above it (a 1 um-noise 2.5 kHz axis, a 5 um
#: 1 kHz one: tests/test_excite.py), which a factor of 10 missed; the real logs without injection
#: (EMPS, ODrive, the screw drive) show no segment at 3 times.
BROADBAND_FACTOR = 3.0
#: ... or this many times where a block holds at least :data:`BROADBAND_LONG_BLOCK` samples.  At high
#: rates the holding loop turns the encoder's noise into a command whose high-passed RMS grows with the
#: rate (the derivative action), so an injection within a_max may stand only a few times above it; over
#: blocks that long the background's RMS is steady, while the short blocks of a low-rate log scatter
#: widely by chance (measured in docs/interface.md §1 and pinned by tests/test_identify_frf_broadband.py).
BROADBAND_FACTOR_LONG = 2.0
#: Samples per detection block from which :data:`BROADBAND_FACTOR_LONG` applies.
BROADBAND_LONG_BLOCK = 200
#: A broadband block also holds at least this fraction of the block's (detrended) command variance.
BROADBAND_FRACTION = 0.25
#: Block length of the detection, s.
BLOCK_S = 0.1
#: Shortest broadband segment used, s.
MIN_SEGMENT_S = 0.5
#: Target frequency resolution on broadband segments, Hz.
RESOLUTION_HZ = 5.0
#: Frequency resolution on a log without broadband segments, Hz.
WHOLE_LOG_RESOLUTION_HZ = 2.0
#: Coherence a bin needs to count for the band.
BAND_COHERENCE = 0.8
#: |H / H_rigid| within [1 / tol, tol] counts as agreement.
BAND_GAIN_TOL = 1.25
#: ... and its phase within this many degrees.
BAND_PHASE_TOL_DEG = 30.0
#: A bin is a measurement of the plant only where the position's PSD stands at least this many times
#: above the encoder's white measurement-error floor (motion at least as strong as the noise).  Below it
#: the reading is the noise, the command is the loop's answer to it, and the two are coherent because the
#: controller makes one from the other: H1 there tends to minus the controller's inverse, with a coherence
#: that the plant has no part in (docs/robustness.md, "Bins at the encoder's noise floor").
MEASURABLE_SNR = 2.0
#: Coherence a bin needs to enter the fit.
FIT_COHERENCE = 0.5
#: Cap of gamma^2 in the weights (a perfect bin would weigh infinitely).
COHERENCE_CAP = 0.995
#: Largest delay fitted, samples.
MAX_DELAY_SAMPLES = 6.0
#: Largest damping ratio fitted (a mode damped more than this is no resonance to report).
MAX_DAMPING = 0.7
#: Least damping ratio fitted: a fit that wants less is resolving a peak the estimate cannot (its
#: resolution and averaging bound how sharp a peak it measures), not a mode.
MIN_DAMPING = 0.002
#: Coherent bins the fit needs.
MIN_FIT_BINS = 12
#: Probability that a right model shows a departure somewhere in the measured response (:func:`departures`).
DEPARTURE_ALPHA = 0.01
#: Multi-start fits: iterations of the screening stage from every start, and the starts kept to the end.
SCREEN_NFEV = 30
SCREEN_KEEP = 2
#: Highest mode frequency fitted, in Nyquist frequencies.  A mode above Nyquist shows in the sampled
#: response as its alias ``fs - f``, but not as a mode there would: the hold and the delay give the two
#: different magnitude and phase, and the alias of a mode the encoder reads on one side looks like a
#: mode on the other.  The exact sampled model tells them apart, so the fit may place a mode up to
#: here, where its alias folds to half of Nyquist (a higher one is lost in the hold's roll-off and is
#: the evidence bound's to cover).  Below Nyquist only, such a mode was fitted as a compromise near
#: Nyquist that the data departed from, which cut the backed band and the loops it bounds
#: (docs/robustness.md, "Modes above Nyquist").
MODE_MAX_NYQUIST = 1.5
#: Most modes fitted (each further one must lower the information criterion and pass the guards).
MAX_MODES = 4
#: Most measured bins carried into ident.json (``frequency_response.measured``).
MEASURED_POINTS = 200

STRUCTURES = ("rigid", "load_side_mode", "motor_side_mode")
