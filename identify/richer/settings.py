"""The terms of the delay-aware inverse dynamics, the delay grid and the selection's settings, with why."""

from __future__ import annotations

import numpy as np

#: Switchable terms, in the order they are listed.
TERMS = ("delay", "viscous_asym", "stribeck", "position", "drag")
#: Coefficient names of every term's columns, with their units ("u" is the command unit).
TERM_COEFFICIENTS: dict[str, tuple[tuple[str, str], ...]] = {
    "base": (("M", "u s^2/m"), ("B", "u s/m"), ("fc", "u"), ("offset", "u")),
    "viscous_asym": (("dB", "u s/m"),),
    "stribeck": (("dfs", "u"),),
    "position": (("kq1", "u/m"), ("kq2", "u/m^2")),
    "drag": (("cd", "u s^2/m^2"),),
}
#: Nonlinear parameters of the terms (profiled), with their units.
TERM_NONLINEAR = {"delay": ("delay_samples", "samples"), "stribeck": ("vs", "m/s")}
#: Stribeck exponent of the ``stribeck`` term (Gaussian shape), fixed.
STRIBECK_XI = 2.0
#: Delay grid beyond the zero-order hold, samples.
DELAY_GRID = tuple(np.round(np.arange(-0.5, 3.0001, 0.25), 4))
#: The delay is profiled on the rows away from reversals: those whose anti-alias window saw no speed
#: below this fraction of the fastest (where sign(qd) of the filtered velocity and a sticking axis disagree).
REVERSAL_FRACTION = 0.01
#: Cross-validation folds and rows left out on each side of a test block.
N_FOLDS = 5
GAP_ROWS = 3
#: A term must lower the CV mean squared error by more than this fraction (of the best) to be
#: worth its parameter, however consistent its gain: on long logs a systematic misfit of a few
#: tenths of a percent (the whole-log regression's own bias) is "significant" fold by fold.
MIN_RELATIVE_GAIN = 0.01
#: Initialisation window of the position simulation, samples (first samples of the log:
#: the simulation starts from the filtered state at its end and is scored after it).
SIM_INIT_SAMPLES = 20
