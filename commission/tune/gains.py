"""The ARC's gains as the search sees them.

:func:`base_arc_gains` carries the paper's §4.3 gains over to this axis (rate and
command-unit scaling, which leave Theorem 1's condition invariant); :class:`FreeGains`
are the coordinates the search moves (log-scaled multipliers of the caps, g1, g2,
Gamma, w2 and theta_hat1(0)), and :func:`apply_free` maps them back to gains.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from typing import Sequence
from commission.artifacts import Identification
from commission.controllers.arc import ArcGains, paper_gains_as_printed, paper_gains_implementable
from commission.controllers.design import observer_design
from commission.spec import Spec
from commission.tune.settings import DEFAULT_SETTINGS, PAPER_RATE, PAPER_THETA1, TuneSettings


def paper_implementable_start(settings: TuneSettings = DEFAULT_SETTINGS) -> tuple[float, ...]:
    """:func:`controllers.arc.paper_gains_implementable` as relative free gains.

    Its caps, g and Gamma relative to the printed paper gains (the base of
    :func:`base_arc_gains` for the paper's axis), clipped to ``settings.free_bounds``.
    """
    pr, im = paper_gains_as_printed(), paper_gains_implementable()
    x = (im.k1s_max / pr.g1, im.k2s_max / pr.g2, im.g1 / im.k1s_max, im.g2 / im.k2s_max,
         im.Gamma[0] / pr.Gamma[0], im.Gamma[1] / pr.Gamma[1], im.Gamma[2] / pr.Gamma[2], im.w2 / pr.w2,
         im.theta0[0] / PAPER_THETA1)
    return tuple(min(max(v, b[1]), b[2]) for v, b in zip(x, settings.free_bounds))


@dataclass(frozen=True)
class FreeGains:
    """The gains the search chooses (absolute values).

    Attributes
    ----------
    k1s_max, k2s_max : float
        Caps on the total nonlinear gains K1 (28)+(37)+(38) and K2 (43)+(47), 1/s:
        the bound that makes the robust terms implementable.
    g1, g2 : float
        Minimum nonlinear gains of (28) and (43), 1/s (<= the caps).
    Gamma : tuple of 3 float
        Diagonal adaptation rate of (19).
    w2 : float
        Weight of (41) (w1 = 1).
    theta1_0 : float
        Initial estimate theta_hat1(0), m/(u-unit s^2) (inside the theta box).
    """

    k1s_max: float
    k2s_max: float
    g1: float
    g2: float
    Gamma: tuple[float, float, float]
    w2: float
    theta1_0: float

    def as_dict(self) -> dict[str, float]:
        return {"k1s_max": self.k1s_max, "k2s_max": self.k2s_max, "g1": self.g1, "g2": self.g2,
                "Gamma1": self.Gamma[0], "Gamma2": self.Gamma[1], "Gamma3": self.Gamma[2], "w2": self.w2,
                "theta1_0": self.theta1_0}


#: Length of the free vector (the order of :func:`apply_free` and of
#: :attr:`commission.tune.settings.TuneSettings.free_bounds`).
N_FREE = 9

#: Index of theta_hat1(0) in the free vector.
I_THETA1_0 = 8


def base_arc_gains(ident: Identification, spec: Spec, bandwidth: float = 1.0) -> ArcGains:
    """The paper's §4.3 ARC gains carried over to this axis (module docstring, step 3).

    With c = 37 / theta1_nominal (command-unit scale) and r = f_s / 2500 Hz:
    w1 = 1, w2 = 0.1 / c^2; g1 = 600 r, g2 = 850 r (1/s); eps11 = 5e-5, eps12 = 5e-5 / r,
    eps21 = 1e-3, eps22 = c^2 r; C_phi1 = 1e-5 [5 c, 0.5, 10]; C_phi2 = 1e-5 [5, 0.5/c, 10/c];
    C_theta2 = 1e5 [1/c^2, 1/c, 1/c]; Gamma = 1e5 [5/c^2, 3, 20]; caps k1s_max = g1,
    k2s_max = g2 (the robust terms bounded: see
    :attr:`commission.tune.settings.TuneSettings.free_start`).

    ``bandwidth`` (dimensionless, at most 1) scales g1, g2 and Gamma down with the axis'
    achievable bandwidth when its plant, not its rate, sets it
    (:func:`commission.tune.baseline.bandwidth_factor`); the search box is relative to these.
    """
    c = PAPER_THETA1 / ident.theta.nominal[0]
    r = spec.sample_rate / PAPER_RATE
    ob = observer_design(spec.observer_pole, spec.period)
    g1, g2 = 600.0 * r * bandwidth, 850.0 * r * bandwidth
    return ArcGains(
        Ts=spec.period, k1=ob.k1, k2=ob.k2, w1=1.0, w2=0.1 / c ** 2, g1=g1, g2=g2,
        eps11=5e-5, eps12=5e-5 / r, eps21=1e-3, eps22=c ** 2 * r,
        C_phi1=(5e-5 * c, 5e-6, 1e-4), C_phi2=(5e-5, 5e-6 / c, 1e-4 / c),
        C_theta2=(1e5 / c ** 2, 1e5 / c, 1e5 / c),
        Gamma=(5e5 / c ** 2 * bandwidth, 3e5 * bandwidth, 2e6 * bandwidth),
        theta_min=tuple(ident.theta.min), theta_max=tuple(ident.theta.max),  # type: ignore[arg-type]
        theta0=tuple(ident.theta.nominal),  # type: ignore[arg-type]
        fric_level=ident.fric_level, fric_slope=ident.fric_slope,
        k1s_max=g1, k2s_max=g2, u_max=spec.u_max,
    )


def apply_free(base: ArcGains, x: Sequence[float]) -> ArcGains:
    """ARC gains for the relative free gains ``x`` (order of :attr:`TuneSettings.free_bounds`)."""
    k1 = base.g1 * x[0]
    k2 = base.g2 * x[1]
    # Theorem 1 needs c_theta2_r^2 >= w_k w2 / (2 c_phi_kr^2): a larger w2 scales C_theta2 by
    # sqrt(w2 / w2_base), which keeps every ratio of the condition at least the base's (5).
    ct = math.sqrt(max(1.0, x[7]))
    # theta_hat1(0) as a multiple of the nominal (base.theta0), kept inside the box.
    th10 = min(max(base.theta0[0] * x[8], base.theta_min[0]), base.theta_max[0])
    return dataclasses.replace(
        base, k1s_max=k1, k2s_max=k2, g1=k1 * x[2], g2=k2 * x[3],
        Gamma=(base.Gamma[0] * x[4], base.Gamma[1] * x[5], base.Gamma[2] * x[6]), w2=base.w2 * x[7],
        C_theta2=tuple(c * ct for c in base.C_theta2),  # type: ignore[arg-type]
        theta0=(th10, base.theta0[1], base.theta0[2]))


def free_gains(arc: ArcGains) -> FreeGains:
    """The free gains of ``arc``."""
    return FreeGains(k1s_max=arc.k1s_max, k2s_max=arc.k2s_max, g1=arc.g1, g2=arc.g2, Gamma=arc.Gamma, w2=arc.w2,
                     theta1_0=arc.theta0[0])
