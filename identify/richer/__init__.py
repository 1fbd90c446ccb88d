"""Delay-aware inverse dynamics with switchable interpretable terms, chosen by blocked cross-validation.

Model, in command units (u-unit, the contract's sign convention)::

    u(t) = F(t + tau),   tau = (0.5 + d) Ts
    F = M qdd + B qd + fc sign(qd) + offset                         (base: the IDIM-LS model)
        + dB |qd|                                                   (viscous_asym)
        + dfs exp(-(|qd| / vs)^2) sign(qd)                          (stribeck, xi = 2)
        + kq1 (q - q_c) + kq2 (q - q_c)^2                           (position)
        + cd qd |qd|                                                (drag)
        [+ ripple sin/cos(2 pi q / P) for every given pitch]        (always in when given)

Delay
-----
The command reaches the force ``d`` samples after the zero-order hold (the plant
vector's ``P_DELAY``, :mod:`commission.controllers.plant`): a held command acts on
average half a sample after it is logged, so the kinematics the command explains
are those ``tau = (0.5 + d) Ts`` later.  The regression keeps ``u`` as measured
and evaluates the regressor at ``t + tau`` (cubic interpolation of the filtered
position, velocity and acceleration, segment by segment), so the relative error
of every delay is measured against the same ``u``.  ``d`` is profiled: for a
term set, the residual sum of squares is minimised over ``d`` (grid, then a
bounded scalar search) on the rows away from reversals (whose anti-alias window
saw no speed below :data:`REVERSAL_FRACTION` of the fastest): at a reversal a
sticking axis and ``sign(qd)`` of the filtered velocity disagree, and on all rows
the delay absorbs part of that misfit (docs/inverse-dynamics.md).  ``vs`` and the
linear coefficients are then fitted on all rows.  The delay's standard deviation
comes from the curvature of the profile, ``var(d) = 2 sigma^2 / RSS''(d)`` (the
Gauss-Newton variance of the one nonlinear parameter).  ``d`` may be negative down to -0.5 sample (a log whose
command is stamped after it acts).

Asymmetry
---------
Coulomb asymmetry while moving, ``fc+ [v > 0] - fc- [v < 0]``, equals
``fc sign(v) + offset`` with ``fc = (fc+ + fc-)/2`` and ``offset = (fc+ - fc-)/2``:
the base model already holds it, and a constant force and a direction-dependent
Coulomb level cannot be told apart from a log that is never at rest (the two
columns differ only where ``v = 0``).  :func:`RichFit.derived` reports both
readings' levels ``fc_pos = fc + offset`` and ``fc_neg = fc - offset``.  Viscous
asymmetry needs its own column, ``|qd|``: ``B_pos = B + dB``, ``B_neg = B - dB``.

Selection (without the test set)
--------------------------------
Blocked K-fold cross-validation on the decimated rows of the identification
log(s): K contiguous blocks; each block in turn is predicted by the model fitted
on the other rows, leaving out ``gap`` rows on each side of the block (the
decimation filter and the position filter correlate neighbouring rows, so a
random split would let the training rows see the test rows).  The nonlinear
parameters (``d``, ``vs``) are chosen inside each fold on its training rows
only.  Among all term sets the simplest (fewest parameters; ties: lowest CV
error) whose CV mean squared error is within one standard error of the minimum
is chosen (the one-standard-error rule of Hastie, Tibshirani & Friedman,
section 7.10), with the standard error of each candidate's excess over the best
taken fold by fold (paired): the folds' own errors differ far more between
stretches of the log than two models' errors on one stretch, so the unpaired
standard error would hide every term.  A candidate also counts as equivalent to
the best when its excess is below :data:`MIN_RELATIVE_GAIN` of the best's error:
on long logs the paired rule alone keeps terms worth a few tenths of a percent
(docs/inverse-dynamics.md).  Why not BIC: the residuals of decimated inverse-dynamics rows are
correlated (unmodelled dynamics, filtered quantisation noise), so the row count
overstates the information and BIC's penalty is too weak; blocked CV measures
prediction on unseen stretches of the log directly.

Modules
-------
* :mod:`~commission.identify.richer.settings`: the terms (:data:`TERMS`), the delay grid and the
  selection's settings;
* :mod:`~commission.identify.richer.result`: :class:`RichFit` and :class:`Selection`;
* :mod:`~commission.identify.richer.design`: the regressor of a term set at the delayed kinematics;
* :mod:`~commission.identify.richer.model`: :class:`RichModel` (fit, profiled delay, blocked CV),
  :func:`select_model`, :func:`relative_error_on`;
* :mod:`~commission.identify.richer.simulate`: :func:`force_model`, :func:`simulate_position`,
  :func:`published_form`.
"""

from __future__ import annotations

from commission.identify.richer.settings import (DELAY_GRID, GAP_ROWS, MIN_RELATIVE_GAIN, N_FOLDS, REVERSAL_FRACTION,
    SIM_INIT_SAMPLES, STRIBECK_XI, TERM_COEFFICIENTS, TERM_NONLINEAR, TERMS)
from commission.identify.richer.result import RichFit, Selection
from commission.identify.richer.design import n_parameters
from commission.identify.richer.model import RichModel, candidate_sets, relative_error_on, select_model
from commission.identify.richer.simulate import PositionSimulation, force_model, published_form, simulate_position

__all__ = ["DELAY_GRID", "GAP_ROWS", "MIN_RELATIVE_GAIN", "N_FOLDS", "REVERSAL_FRACTION", "SIM_INIT_SAMPLES",
           "STRIBECK_XI", "TERM_COEFFICIENTS", "TERM_NONLINEAR", "TERMS", "RichFit", "Selection", "n_parameters",
           "RichModel", "candidate_sets", "relative_error_on", "select_model", "PositionSimulation", "force_model",
           "published_form", "simulate_position"]
