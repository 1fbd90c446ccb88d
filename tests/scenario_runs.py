"""An emitted controller on one of the paper's experiments, on a known plant: the figures the end-to-end tests judge.

Shared by the tests that check what ``commission run`` emitted against the truth
(``test_run_true_axis.py``, ``test_run_unseen_mode.py``), so that both measure e_rms, e_M and
c_u the same way as validate does: the scenario's trajectory and disturbance, a 1 um encoder,
the drive's saturation, and an abort beyond 1 cm of error.
"""

from __future__ import annotations

import numpy as np

from commission.controllers.simulate import simulate
from commission.paper import scenario


def run_scenario(plant: np.ndarray, kind: int, ctrl: np.ndarray, name: str, Ts: float, u_max: float):
    """``(diverged, e_rms m, e_M m, c_u -, the simulation)`` of packed controller ``ctrl`` on scenario ``name``."""
    sc = scenario(name, Ts)
    r = simulate(plant, kind, ctrl, sc.traj, quant=1e-6, disturbance=sc.disturbance, u_sat=u_max, e_abort=0.01)
    e = r.y - r.qd
    du = np.diff(r.u)
    c_u = float(np.sqrt(np.mean(du ** 2)) / np.sqrt(np.mean(r.u ** 2)))
    return bool(r.diverged), float(np.sqrt(np.mean(e ** 2))), float(np.max(np.abs(e))), c_u, r
