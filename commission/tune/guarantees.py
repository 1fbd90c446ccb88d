"""Which of the paper's guarantees the chosen gains keep, and which implementability trades
(the statement recorded in tuning.json)."""

from __future__ import annotations

import math
from typing import Sequence
from commission.controllers.arc import ArcGains
from commission.controllers.design import FeasibilityReport
from commission.tuning import FeasibilitySummary, Guarantee


def _summary(rep: FeasibilityReport, names: Sequence[str],
             robust: FeasibilityReport | None = None) -> FeasibilitySummary:
    w = rep.worst
    return FeasibilitySummary(holds=rep.holds, margin=rep.margin, rho_max=rep.rho_max, worst_corner=w.corner,
                              worst_trajectory=names[w.trajectory], worst_t=w.t, n_points=len(rep.points),
                              rho_adaptive_max=rep.rho_adaptive_max,
                              rho_any_estimate_max=robust.rho_max if robust is not None else math.nan)


def guarantees(arc: ArcGains, t1, feas: FeasibilitySummary) -> dict[str, Guarantee]:
    """Which of the paper's guarantees hold as tuned, and which are traded for implementability."""
    return {
        "theorem1_condition": Guarantee(
            t1.holds, f"c_phi_kr^2 >= w_k w2 / (2 c_theta2_r^2) for k = 1, 2, r = 1..3: smallest ratio "
                      f"{t1.min_ratio:.3g} (>= 1 holds)"),
        "projection_P1": Guarantee(
            True, "theta_hat stays in the identified box exactly: each discrete adaptation step is clipped to "
                  "[theta_min, theta_max]"),
        "projection_P2_continuous": Guarantee(
            False, "traded: the discontinuous projection (19)-(20) is replaced by clipping the Euler step "
                   "theta_hat + Ts Gamma tau to the box (for diagonal Gamma the Gamma^-1-weighted projection); "
                   "the continuous-time argument (A.8) does not carry over verbatim"),
        "exact_observer_filters": Guarantee(
            True, "filters (12), (18) advanced by exact matrix exponentials each sample (the sampled inputs "
                  "held as the controllers.arc law states); observer poles at -p give k1 = 2p, k2 = p^2 and P of (11)"),
        "robust_gains_37_47": Guarantee(
            math.isinf(arc.k1s_max) and math.isinf(arc.k2s_max),
            f"traded: the nonlinear gains K1 (28)+(37)+(38) and K2 (43)+(47) are capped at k1s_max = "
            f"{arc.k1s_max:.4g} 1/s and k2s_max = {arc.k2s_max:.4g} 1/s; conditions (33), (35), (46) hold only "
            f"while a cap is inactive, so the prescribed final accuracy of (51) is not guaranteed"),
        "sampled_data_stability": Guarantee(
            feas.holds, f"Theorem 1 is continuous-time; instead the sampled loop (exact ZOH plant + discrete "
                        f"controller; friction, ripple, quantization, saturation and sign nonlinearities excluded) "
                        f"is linearised at the 8 corners of the theta box along both trajectories, with theta_hat "
                        f"at the value reached and at each box corner: spectral radius <= {feas.rho_max:.4g} with "
                        f"the estimates frozen (need < {1 - feas.margin:.4g}), <= {feas.rho_adaptive_max:.6g} with "
                        f"the theta3 adaptation in the loop (need < 1)"),
        "stability_for_any_estimate_in_box": Guarantee(
            feas.rho_any_estimate_max < 1.0,
            f"informational: with theta_hat frozen at any of the 8 corners of the box (which the projection "
            f"allows) instead of the values the runs reached, the largest spectral radius is "
            f"{feas.rho_any_estimate_max:.4g} along the trajectories (< 1: stable whatever the estimate there); "
            f"over every plant of the box see stability_over_box_any_estimate"),
        "input_limit": Guarantee(
            math.isinf(arc.u_max), f"traded: the paper assumes an unbounded input; here |u| <= u_max = "
                                   f"{arc.u_max:g} (the lambda filter is driven by the applied u*)"),
        "zero_initial_V2_remark4": Guarantee(
            True, "q_d(0) = y(0), filters at rest at y(0): z1(0) = z2(0) = 0, i.e. V2(0) = 0"),
    }
