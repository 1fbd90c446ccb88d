"""Desired trajectories ``q_d, dq_d, ddq_d`` sampled at the controller rate.

Every generator is exact at the samples (no integration error) and returns a
:class:`Trajectory`.

Modules
-------
* :mod:`~commission.controllers.trajectory.core`: :class:`Trajectory`, :class:`TrajectoryError`,
  :func:`sample_grid` and the compiled :func:`expm_small`;
* :mod:`~commission.controllers.trajectory.schedules`: piecewise-polynomial references,
  :class:`AccelSchedule` (acceleration steps) and :class:`JerkSchedule` (jerk steps);
* :mod:`~commission.controllers.trajectory.paper`: the paper's cases, the reference filter
  (58) (:func:`filter58`, Case 1 :func:`sinusoid`) and the smoothed trapezoidal moves of
  Case 2 (:func:`trapezoid_moves`, :func:`smooth`, :func:`back_and_forth`);
* :mod:`~commission.controllers.trajectory.scurve`: the machine's own moves, S-curves
  (:func:`scurve_segments`, :class:`Move`, :func:`scurve_schedule`, :func:`scheduled`) and
  sampled profiles (:func:`resampled`).
"""

from __future__ import annotations

from commission.controllers.trajectory.core import Trajectory, TrajectoryError, expm_small, sample_grid
from commission.controllers.trajectory.schedules import AccelSchedule, JerkSchedule
from commission.controllers.trajectory.paper import back_and_forth, filter58, sinusoid, smooth, trapezoid_moves
from commission.controllers.trajectory.scurve import Move, resampled, scheduled, scurve_schedule, scurve_segments

__all__ = ["Trajectory", "TrajectoryError", "expm_small", "sample_grid", "AccelSchedule", "JerkSchedule",
           "back_and_forth", "filter58", "sinusoid", "smooth", "trapezoid_moves", "Move", "resampled", "scheduled",
           "scurve_schedule", "scurve_segments"]
