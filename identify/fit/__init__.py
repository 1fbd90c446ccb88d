"""Identification of one axis from an excitation log: :func:`fit_axis`, :func:`fit_segments` and :func:`evaluate`.

Model (contract §2), in command units (u-unit), ``u`` already multiplied by any input gain::

    u = M qdd + B qd + Ff(qd) + offset [+ A sin(2 pi q / P + phase)]
    Ff(v) = [fc + (fs - fc) exp(-|v/vs|^xi)] sign(v)      (Coulomb model: fc sign(v))

Two methods, chosen from the data:

``"dynamic"`` — the EMPS reference method (IDIM-LS), used when the log has no
usable constant-velocity legs (or ``use_steady=False``).  Filter and
differentiate the position, build the regressor ``[qdd, qd, sign(qd), 1]``
(plus the Stribeck column and ripple columns), decimate every column and the
command with the anti-alias filter, solve by least squares; for the Stribeck
model by separable nonlinear least squares over ``(vs, xi)``.  It reproduces the
published EMPS numbers exactly.  Its weakness: ``sign(qd)`` is discontinuous, the
filtered velocity crosses zero at slightly different times than the true one and
the axis sticks at reversals, so on logs with many slow reversals the filtered
friction columns do not match the filtered force.  On simulated closed-loop logs
with known truth the whole-log fit is off by up to ~9 % in ``B``, ~6 % in ``fc``
and ~60 % in ``fs``, or finds a negative Stribeck hump and is refused, where the
method below is within 0.5 %.

``"steady+dynamic"`` — used when the log contains a friction ladder:
constant-velocity legs at 3 (Coulomb) or 4 (Stribeck) distinct speeds in each
direction.  Fewer levels (EMPS's trapezoids cruise at two speeds) give a map
without redundancy, and the dynamic method is used.  Friction is taken from the
legs, mass from the dynamics:

1. **Friction map.**  :func:`commission.identify.steady.find_steady_segments`
   finds the legs; each gives one point ``(v_k, F_k)`` with ``v_k`` the position
   change over the leg divided by its duration and ``F_k`` the mean command minus
   ``M`` times the mean acceleration and minus the mean ripple force over the leg.
   No filter touches ``F_k``, so these points are unbiased.  ``B, fc, offset``
   (Coulomb) or ``B, fc, fs, vs, xi, offset`` (Stribeck, separable least squares)
   are fitted to them, with standard deviations from the map residuals.
2. **Mass.**  With the friction curve fixed, ``M`` (and the ripple ``sin``/``cos``
   coefficients) are fitted to the decimated dynamic rows
   ``D[u - B qd - Ff(qd) - offset] = M D[qdd] (+ ripple)``, leaving out every row
   whose anti-alias window saw a speed below ``reversal_speed`` (default ``3 vs``
   of the map's Stribeck curve, or 5 % of the fastest leg when the map shows no
   Stribeck hump), i.e. the reversals and stiction phases where the filtered
   friction column is wrong.  (Coulomb model: when the map shows a clear Stribeck
   hump, the legs slower than ``3 vs`` are left out of the Coulomb line, which
   would otherwise trade ~20 % of ``B`` for ~10 % of ``fc``.)
3. Steps 1-2 alternate: a first pass with a Coulomb map gives provisional ``M``
   and ripple, then three passes with the requested model (``M`` and the ripple
   enter the map points; the ripple matters on the slow legs, which cover a short
   stretch of travel where it does not average out).

Standard deviations: friction parameters from the map fit (its residuals), ``M``
and the ripple from the mass regression with the friction curve held fixed (the
cross-covariance between the two steps is neglected).

The figures of merit (relative error, condition number, residuals) are always
those of the full model on all decimated rows, as in the EMPS benchmark; the
condition number is that of the full decimated regressor at the fitted
``(vs, xi)``.

Modules
-------
* :mod:`~commission.identify.fit.result`: :class:`AxisFit` and the model force it describes;
* :mod:`~commission.identify.fit.checks`: the refusals (constant command, no reversals, M or
  the Stribeck curve not determined);
* :mod:`~commission.identify.fit.dynamic`: the dynamic (EMPS, IDIM-LS) method;
* :mod:`~commission.identify.fit.friction_map`: friction curves on a friction map
  (:func:`fit_friction_map`, :class:`MapFit`);
* :mod:`~commission.identify.fit.steady_dynamic`: the steady+dynamic method (steps 1-3);
* :mod:`~commission.identify.fit.segments`: :func:`fit_segments`, :func:`fit_axis`, :func:`evaluate`,
  :func:`evaluate_segments`, :func:`find_ripple_pitch` (:mod:`commission.identify.ripple`).
"""

from __future__ import annotations

from commission.identify.fit.result import PARAMETER_ORDER, AxisFit, Method, model_force
from commission.identify.fit.checks import (MAX_REL_STD_M, MIN_ROWS_PER_DIRECTION, MIN_STRIBECK_POINTS,
    MIN_STRIBECK_ROWS, STRIBECK_DIP_P_VALUE)
from commission.identify.fit.friction_map import MIN_LADDER_SPEEDS, PAIR_SPEED_TOLERANCE, MapFit, fit_friction_map
from commission.identify.fit.steady_dynamic import N_ALTERNATIONS
from commission.identify.fit.segments import evaluate, evaluate_segments, find_ripple_pitch, fit_axis, fit_segments

__all__ = ["PARAMETER_ORDER", "AxisFit", "Method", "model_force", "MAX_REL_STD_M", "MIN_ROWS_PER_DIRECTION",
           "MIN_STRIBECK_POINTS", "MIN_STRIBECK_ROWS", "STRIBECK_DIP_P_VALUE", "MIN_LADDER_SPEEDS",
           "PAIR_SPEED_TOLERANCE", "MapFit", "fit_friction_map", "N_ALTERNATIONS", "evaluate", "evaluate_segments",
           "fit_axis", "fit_segments", "find_ripple_pitch"]
