"""The ARC's gains: :class:`ArcGains`, its checks, and the paper's sec. 4.3 parameters.

:class:`ArcGains` holds every number the law of :mod:`commission.controllers.arc.step`
needs, checked on construction (:class:`ArcGainsError` names the field);
:func:`commission.controllers.arc.pack.arc_pack` turns it into the packed vector the
compiled step takes.  :func:`paper_gains_as_printed` is sec. 4.3 as printed and
:func:`paper_gains_implementable` the same made implementable at 2.5 kHz, for the
reasons below.

Why the paper's robust terms are capped (implementable gains)
-------------------------------------------------------------
The example robust functions (37), (38), (47) with the printed levels
eps11 = eps12 = 5e-5, eps21 = 1e-3, eps22 = 1, together with C_theta2 = 1e5 I and
Gamma = 1e5 diag[5, 3, 20], are continuous-time gains far beyond what a
sampled loop supports: K2 contains (d alpha1/dy)^2/(4 eps22) and grows with
the error, while a gain K is usable at period Ts only while K Ts is of order 1.
Three limits bound what is implementable at a given rate and encoder:

* Noise: the direct gain from y to u is about K2 K1/theta1min, so the
  encoder's quantisation sets c_u = ||du||/||u||; gain above g1, g2 must be
  confined to transients.
* The sampled v-loop: u* feeds back v2 = lambda_2, which integrates the held
  u* over each period with the rate R = K2 - th1 d(alpha1)/dy.  Its sampled
  pole is about 1 - R Ts, so the loop is unstable when R Ts > 2 whatever the
  plant, and stability depends on the *estimate* theta_hat1.  Hence the guard:
  when ``k2s_max`` is finite, K2 <= V_LOOP_RATE_LIMIT/Ts + th1 d(alpha1)/dy
  (floored at 0), i.e. R Ts <= 1.75.  K2 does not enter alpha_1, so the
  partials of alpha_1 are unaffected.
* The theta3 adaptation is the loop's integral action; its gain grows like
  Gamma3/theta_hat1, which bounds Gamma3 over the box.

``docs/implementability.md`` records the measurements behind these limits on
the reference plant, and the Table-1 figures of
:func:`commission.paper.paper_gains_implementable`.

Hence the caps: ``k1s_max`` bounds K1 (the whole gain of alpha_1s =
-(K1/theta1min) z1, g1 included) and ``k2s_max`` bounds K2 (the whole gain of
u*_s = -K2 z2, g2 included): K = min(K_raw, cap), then the v-loop guard on K2.
Where a cap is active its gradient is zero, and the partials of alpha_1 are
exact for the capped function.  With a cap or the guard active the Lyapunov
inequality (A.5) is no longer guaranteed; the paper's law is recovered with
``math.inf`` for both caps (no cap, no guard).
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass


class ArcGainsError(ValueError):
    """An :class:`ArcGains` field is out of its admissible range."""


#: ArcGains fields of the runtime guards (optional everywhere: absent = off).
RUNTIME_GUARDS = ("dy_max", "dy_fault", "n_reject_max", "e_max", "freeze_on_saturation",
                  "accel_max", "y_err", "n_frozen_max", "u_free")


#: A vector of the law: the diagonal of one of the paper's diagonal 3 x 3 matrices, or a
#: point of the parameter space, ordered like theta = [1/M, B/M, d_n/M].
ThetaVector = tuple[float, float, float]


def _vec3(name: str, v) -> ThetaVector:
    t = tuple(float(x) for x in v)
    if len(t) != 3:
        raise ArcGainsError(f"ArcGains.{name}: needs 3 entries, got {len(t)}")
    return t  # type: ignore[return-value]


def _positive(v: float) -> bool:
    return v > 0 and not math.isnan(v)


#: The checks of ArcGains' scalar fields, in the order they run: (fields, admissible(value), what
#: the message says a value must be).
_SCALAR_RULES = (
    (("Ts", "k1", "k2", "w1", "w2", "g1", "g2", "fric_level", "fric_slope"), math.isfinite, "finite"),
    (("Ts", "k1", "k2", "w1", "w2", "g1", "g2"), lambda v: v > 0, "> 0"),
    (("fric_level", "fric_slope"), lambda v: not v < 0, ">= 0"),
    (("eps11", "eps12", "eps21", "eps22", "u_max"), _positive, "> 0 (inf allowed)"),
    (("dy_max", "dy_fault", "e_max"), _positive, "> 0 m (inf allowed)"),
    (("accel_max",), _positive, "> 0 m/s^2 (inf allowed)"),
    (("y_err", "u_free"), lambda v: math.isfinite(v) and v >= 0, "finite and >= 0"),
    (("n_reject_max", "n_frozen_max"), lambda n: not (math.isnan(n) or n < 1 or (math.isfinite(n) and n != int(n))),
     "an integer >= 1 (inf allowed)"),
)


@dataclass(frozen=True)
class ArcGains:
    """Every number the discrete output-feedback ARC needs.

    "u-unit" is the command unit (V in the paper).  Vectors are the diagonals
    of the paper's diagonal matrices, ordered like theta = [1/M, B/M, d_n/M].

    Attributes
    ----------
    Ts : float
        Sample period, s.
    k1, k2 : float
        Observer gains of A0 (10), 1/s and 1/s^2 (paper: 400, 4e4, both roots at -200).
    w1, w2 : float
        Weights of V1 (30) and V2 (41), dimensionless (paper: 1, 0.1).
    g1, g2 : float
        Minimum nonlinear gains of (28) and (43), 1/s (paper: 600, 850).
    eps11, eps12, eps21, eps22 : float
        Attenuation levels of the robust terms (37), (38) and (47) (u*_s2, u*_s3);
        > 0, ``math.inf`` switches the term off (paper: 5e-5, 5e-5, 1e-3, 1).
    C_phi1, C_phi2 : tuple of 3 float
        Diagonals of C_phi1 (28) and C_phi2 (43) (paper: 1e-5 [5, 0.5, 10]).
    C_theta2 : tuple of 3 float
        Diagonal of C_theta2 (43) (paper: 1e5 each).
    Gamma : tuple of 3 float
        Diagonal adaptation rate of (19) (paper: 1e5 [5, 3, 20]).
    theta_min, theta_max : tuple of 3 float
        Box Omega_theta of (8): theta1 in m/(u-unit s^2), theta2 in 1/s,
        theta3 in m/s^2 (paper: [8.3, 2.4, -50], [50, 17.5, 50]).
    theta0 : tuple of 3 float
        Initial estimates, inside the box (paper: [30, 10, 0]).
    fric_level : float
        Friction-compensation level, u-unit: F_hat(v) = level (2/pi) atan(slope v) (5)
        evaluated at the desired velocity (paper: 0.1).
    fric_slope : float
        Friction-compensation slope, s/m (paper: 900).
    k1s_max : float
        Cap on K1, the total gain of alpha_1s = -(K1 / theta1min) z1, 1/s
        (``math.inf``: no cap, the paper as written); must be >= g1.
    k2s_max : float
        Cap on K2, the total gain of u*_s = -K2 z2, 1/s (``math.inf``: no cap); >= g2.
        When finite, K2 is also held below the sampled v-loop guard
        V_LOOP_RATE_LIMIT/Ts + theta_hat1 d alpha1/dy (module docstring).
    u_max : float
        Symmetric output saturation, u-unit (``math.inf``: none).
    dy_max : float
        Runtime guard: largest plausible change of the measurement in one sample,
        m; a y farther than ``dy_max (1 + r)`` from the last accepted y (r: samples
        rejected since) is rejected as a glitch (``math.inf``: no check).
    dy_fault : float
        Runtime guard: a y farther than this from the last accepted y latches a
        fault at once, m (``math.inf``: never).
    n_reject_max : float
        Runtime guard: this many rejected measurements in a row latch a fault
        (a count >= 1; ``math.inf``: never).
    e_max : float
        Runtime guard: tracking-error watchdog on the accepted |y - q_d|, m; beyond
        it a fault latches (``math.inf``: none).
    freeze_on_saturation : bool
        Runtime guard: no adaptation in a sample whose command is at ``+-u_max``.
        The adaptation is always frozen while y is rejected.

    accel_max : float
        Runtime guard: largest plausible acceleration of the axis, m/s^2, in the
        innovation bound of the measurement prediction (``math.inf``: no such check).
    y_err : float
        Runtime guard: largest error of one reading (half an encoder step, noise), m;
        also the half-width of a "still" reading for the frozen-encoder guard (>= 0).
    n_frozen_max : float
        Runtime guard: evidence of still readings while the axis must move that latches
        the frozen-encoder fault (>= 1; ``math.inf``: never).
    u_free : float
        Runtime guard: the largest command that may leave the axis at rest, u-unit; a
        larger one pushes it (0: unknown, no push counts as evidence).

    The runtime guards default to "off", which is the law as it was before
    they existed bit for bit; ``commission validate`` sets them
    (:func:`commission.validate.runtime_guards`) and simulates with them.
    """

    Ts: float
    k1: float
    k2: float
    w1: float
    w2: float
    g1: float
    g2: float
    eps11: float
    eps12: float
    eps21: float
    eps22: float
    C_phi1: ThetaVector
    C_phi2: ThetaVector
    C_theta2: ThetaVector
    Gamma: ThetaVector
    theta_min: ThetaVector
    theta_max: ThetaVector
    theta0: ThetaVector
    fric_level: float
    fric_slope: float
    k1s_max: float
    k2s_max: float
    u_max: float
    dy_max: float = math.inf
    dy_fault: float = math.inf
    n_reject_max: float = math.inf
    e_max: float = math.inf
    freeze_on_saturation: bool = False
    accel_max: float = math.inf
    y_err: float = 0.0
    n_frozen_max: float = math.inf
    u_free: float = 0.0

    def __post_init__(self) -> None:
        for name in ("C_phi1", "C_phi2", "C_theta2", "Gamma", "theta_min", "theta_max", "theta0"):
            object.__setattr__(self, name, _vec3(name, getattr(self, name)))
        for names, admissible, what in _SCALAR_RULES:
            for name in names:
                val = getattr(self, name)
                if not admissible(val):
                    raise ArcGainsError(f"ArcGains.{name}: must be {what}, got {val}")
        if not isinstance(self.freeze_on_saturation, bool):
            raise ArcGainsError(f"ArcGains.freeze_on_saturation: must be a bool, got {self.freeze_on_saturation!r}")
        for name, floor in (("k1s_max", "g1"), ("k2s_max", "g2")):
            val = getattr(self, name)
            if math.isnan(val) or val < getattr(self, floor):
                raise ArcGainsError(f"ArcGains.{name}: must be >= {floor} = {getattr(self, floor)} (inf allowed), got {val}")
        for name in ("C_phi1", "C_phi2", "C_theta2", "Gamma"):
            for i, val in enumerate(getattr(self, name)):
                if not (math.isfinite(val) and val >= 0):
                    raise ArcGainsError(f"ArcGains.{name}[{i}]: must be finite and >= 0, got {val}")
        for i in range(3):
            lo, hi, t0 = self.theta_min[i], self.theta_max[i], self.theta0[i]
            if not (math.isfinite(lo) and math.isfinite(hi) and lo < hi):
                raise ArcGainsError(f"ArcGains.theta_min/theta_max[{i}]: need finite min < max, got {lo}, {hi}")
            if not lo <= t0 <= hi:
                raise ArcGainsError(f"ArcGains.theta0[{i}]: {t0} outside [{lo}, {hi}]")
        if not self.theta_min[0] > 0:
            raise ArcGainsError(f"ArcGains.theta_min[0]: theta1 = 1/M needs a positive lower bound, got {self.theta_min[0]}")


def paper_gains_as_printed(Ts: float = 1 / 2500) -> ArcGains:
    """The ARC parameters of sec. 4.3 exactly as printed (they diverge in discrete time).

    k1 = 400, k2 = 4e4, w1 = 1, w2 = 0.1, g1 = 600, g2 = 850,
    eps11 = eps12 = 5e-5, eps21 = 1e-3, eps22 = 1, C_phi1 = C_phi2 = 1e-5 diag[5, 0.5, 10],
    C_theta2 = 1e5 I, Gamma = 1e5 diag[5, 3, 20], theta bounds (53), theta_hat(0) = [30, 10, 0],
    F_hat = (0.2/pi) atan(900 dq_d); no caps and no saturation (the paper states none).

    Parameters
    ----------
    Ts : float
        Sample period, s (paper: 1/2500).
    """
    return ArcGains(
        Ts=Ts, k1=400.0, k2=4.0e4, w1=1.0, w2=0.1, g1=600.0, g2=850.0,
        eps11=5e-5, eps12=5e-5, eps21=1e-3, eps22=1.0,
        C_phi1=(5e-5, 5e-6, 1e-4), C_phi2=(5e-5, 5e-6, 1e-4), C_theta2=(1e5, 1e5, 1e5),
        Gamma=(5e5, 3e5, 2e6),
        theta_min=(8.3, 2.4, -50.0), theta_max=(50.0, 17.5, 50.0), theta0=(30.0, 10.0, 0.0),
        fric_level=0.1, fric_slope=900.0,
        k1s_max=math.inf, k2s_max=math.inf, u_max=math.inf,
    )


def paper_gains_implementable(Ts: float = 1 / 2500) -> ArcGains:
    """The sec. 4.3 ARC parameters made implementable at 2.5 kHz with a 1 um encoder.

    Kept as printed: k1 = 400, k2 = 4e4 (observer), w1 = 1, w2 = 0.1, g1 = 600,
    eps11 = eps12 = 5e-5, C_phi1, the theta bounds (53), theta_hat(0) = [30, 10, 0]
    and the friction compensation (0.2/pi) atan(900 dq_d).  Changed (the measurements
    behind each choice are in docs/implementability.md, "The choices of
    paper_gains_implementable"):

    * ``k1s_max`` inf -> 600 = g1: K1 = g1 constant (eps11, eps12, C_phi1 are
      computed but add no gain).  K1 sets the rate th1 K1/theta1min of the sampled
      v-loop and the direct noise gain; more K1 is neither stable over the box nor
      quiet enough for the noise limit on c_u.
    * ``g2`` 850 -> 800: less constant K2, so that the transient gain below fits
      under the noise limit on c_u on Set 1.
    * ``eps21`` 1e-3 -> inf, ``eps22`` 1 -> inf, ``C_theta2`` 1e5 I -> 0,
      ``C_phi2`` 1e-5 [5, 0.5, 10] -> [8e-6, 0, 0]: of the robust part of K2 only
      the first entry of ||C_phi2 Gamma phi2||^2 (43) is kept.  phi2_1 =
      (w1/w2) z1 - (d alpha1/dy) v2 ~ (K1/theta1min) v2 grows with v2, the
      filtered command, i.e. with the force demanded: K2 = 800 + (80 phi2_1)^2
      stays near g2 while tracking, rises while a step of the force is compensated
      and reaches the v-loop guard in a start-up that demands a large force.  The
      dropped terms contain psi_2 (-> k1/k2 at rest) or (d alpha1/dy)^2 and would
      add large constant gain.  Theorem 1's condition on C_phi, C_theta2 is given
      up with them; with the eps terms off and caps on, Theorem 1 does not apply
      anyway.
    * ``Gamma`` 1e5 [5, 3, 20] -> [1e7, 3e5, 5e6]: theta1 20x faster, so that the
      Set 2 payload is learnt during the start-up; theta3, the loop's integral
      action, 2.5x: a round value below the largest for which the loop linearised
      at rest is stable over the whole box.  A still faster theta1 lowers the Set 2
      peak error a little more, but then constant offsets make the adaptation
      burst (limit cycles) on more plants.
    * ``k2s_max`` inf -> 4000: finite, which switches the sampled v-loop guard
      on; the guard is what bounds K2 over the box.
    * ``u_max`` inf -> 10 V, the +-10 V range of the paper's DS1103 outputs.

    Parameters
    ----------
    Ts : float
        Sample period, s (paper: 1/2500).
    """
    return dataclasses.replace(
        paper_gains_as_printed(Ts),
        g2=800.0, eps21=math.inf, eps22=math.inf,
        C_phi2=(8e-6, 0.0, 0.0), C_theta2=(0.0, 0.0, 0.0),
        Gamma=(1e7, 3e5, 5e6),
        k1s_max=600.0, k2s_max=4000.0, u_max=10.0,
    )
