"""The candidate plants of the fit: the rigid body, a load-side or a motor-side mode, extra modes.

A structure is evaluated with the exact sampled response behind the zero-order hold and an
input delay (:meth:`commission.controllers.linear.SampledPlant.frequency_response`); a fit of
one (:class:`StructureFit`) carries its parameters, their standard deviations and its
information criterion.  :class:`ExtraMode` is one more unit-DC-gain mode factor.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from commission.controllers.linear import SampledPlant, _hold, continuous_model
from commission.controllers.plant import plant_vector


@dataclass(frozen=True)
class ExtraMode:
    """A structural mode beyond the first, as an input-side factor of the fitted response.

    ``kind`` ``"load"``: ``(2 zeta w s + w^2) / (s^2 + 2 zeta w s + w^2)`` (a resonance only, as a
    mode seen across the structure); ``"motor"``: ``(w / w_a)^2 (s^2 + 2 zeta_a w_a s + w_a^2) /
    (s^2 + 2 zeta w s + w^2)`` with ``w_a = w sqrt(1 - r)``, ``zeta_a = zeta sqrt(1 - r)`` (an
    anti-resonance below the resonance, as a mode seen next to the force).  Both have unit gain at
    DC, so the rigid body and the first mode keep their meaning.

    Attributes
    ----------
    kind : {"load", "motor"}
        How the mode enters the response (above): across the structure, or next to the force.
    hz : float
        Resonance, Hz.
    damping : float
        Damping ratio, -.
    ratio : float
        Load fraction r of the anti-resonance (0.5, not identified, for ``"load"``), -.
    hz_std, damping_std, ratio_std : float or None
        One standard deviation from the fit's covariance, Hz, -, -.
    """

    kind: str
    hz: float
    damping: float
    ratio: float = 0.5
    hz_std: float | None = None
    damping_std: float | None = None
    ratio_std: float | None = None


@dataclass(frozen=True)
class StructureFit:
    """One candidate structure fitted to the measured response.

    Attributes
    ----------
    structure : str
        ``"rigid"``, ``"load_side_mode"`` or ``"motor_side_mode"``: the first mode, as the
        simulator's two-mass plant.
    mass_scale : float
        Mass of the fitted plant over the rigid fit's M.
    delay_samples : float
        Input delay beyond the zero-order hold, samples.
    mode_hz, mode_damping, mode_ratio : float or None
        First mode of the fitted plant (Hz, -, -); None for rigid.
    cost : float
        Sum of squared normalised residuals (about the number of residuals for a right model).
    n_residuals : int
        Residuals the fit weighed (two per frequency bin: log magnitude and phase), count.
    n_params : int
        Parameters fitted, count.
    mode_hz_std, mode_damping_std, mode_ratio_std : float or None
        One standard deviation of the first mode's parameters (Hz, -, -) from the fit's
        covariance ``(J^T J)^-1``, scaled by the reduced chi-square when that exceeds 1.
    delay_std : float or None
        Of the delay, samples.
    extra : tuple of ExtraMode
        Further modes, as input-side factors.
    """

    structure: str
    mass_scale: float
    delay_samples: float
    mode_hz: float | None
    mode_damping: float | None
    mode_ratio: float | None
    cost: float
    n_residuals: int
    n_params: int
    mode_hz_std: float | None = None
    mode_damping_std: float | None = None
    mode_ratio_std: float | None = None
    delay_std: float | None = None
    extra: tuple[ExtraMode, ...] = ()

    @property
    def n_modes(self) -> int:
        return (0 if self.structure == "rigid" else 1) + len(self.extra)

    @property
    def all_modes(self) -> list[ExtraMode]:
        """Every fitted mode, the first (the two-mass plant's) as an :class:`ExtraMode` too."""
        if self.structure == "rigid" or self.mode_hz is None or self.mode_damping is None:
            return list(self.extra)
        first = ExtraMode("motor" if self.structure == "motor_side_mode" else "load", self.mode_hz,
                          self.mode_damping, self.mode_ratio if self.mode_ratio is not None else 0.5,
                          self.mode_hz_std, self.mode_damping_std, self.mode_ratio_std)
        return [first, *self.extra]

    @property
    def score(self) -> float:
        """Bayesian information criterion with the residuals' scale unknown: ``n ln(cost / n) + k ln n``.

        The residuals are normalised by the coherence's variance, so for a right model
        ``cost ~ n``; a model the data reject (closed-loop bias, a missed mode) has a larger
        cost, and the unknown-scale form stays fair between structures then.  Lower is better.
        """
        n = max(self.n_residuals, 1)
        return n * math.log(max(self.cost, 1e-300) / n) + self.n_params * math.log(n)

    def plant(self, M: float, B: float, Ts: float) -> np.ndarray:
        """The fitted plant vector (linear part only: no friction; the first mode only)."""
        return _plant(self.structure, M * self.mass_scale, B, Ts, self.delay_samples,
                      self.mode_hz or 0.0, self.mode_damping or 0.0, self.mode_ratio or 0.5)

    def response(self, M: float, B: float, Ts: float, f: np.ndarray) -> np.ndarray:
        """Sampled response of the fitted model at ``f`` (Hz), every mode included, m per u-unit."""
        return _model_response(self.structure, M * self.mass_scale, B, Ts, self.delay_samples,
                               self.mode_hz or 0.0, self.mode_damping or 0.0, self.mode_ratio or 0.5,
                               self.extra, f)


def _plant(structure: str, M: float, B: float, Ts: float, delay_samples: float, mode_hz: float,
           damping: float, ratio: float) -> np.ndarray:
    if structure == "rigid":
        return plant_vector(M, B, delay=delay_samples * Ts)
    return plant_vector(M, B, mode_hz=mode_hz, mode_damping=damping, mode_ratio=ratio,
                        mode_load_side=structure == "load_side_mode", delay=delay_samples * Ts)


def _factor(m: ExtraMode) -> tuple[np.ndarray, np.ndarray, np.ndarray, float]:
    """State space ``(A, B, C, D)`` of an extra mode's factor (:class:`ExtraMode`), scaled states.

    States ``x1``, ``x2 = x1' / w`` with ``x1'' + 2 zeta w x1' + w^2 x1 = w^2 u``: then
    ``load = x1 + 2 zeta x2`` and ``motor = (w/wa)^2 (s^2 + 2 zeta_a wa s + wa^2) / den =
    (1 - 1/c) (x1 + 2 zeta x2) + u / c`` with ``c = 1 - r`` (the two-mass plant's motor-side
    numerator ``(m2 s^2 + c s + k) / k``).  Both have unit gain at DC.
    """
    w = 2.0 * math.pi * m.hz
    A = np.array([[0.0, w], [-w, -2.0 * m.damping * w]])
    B = np.array([[0.0], [w]])
    C = np.array([[1.0, 2.0 * m.damping]])
    if m.kind == "load":
        return A, B, C, 0.0
    c = 1.0 - m.ratio
    return A, B, C * (1.0 - 1.0 / c), 1.0 / c


def _sampled_response(A: np.ndarray, Bm: np.ndarray, C: np.ndarray, Ts: float, tau: float,
                      f: np.ndarray) -> np.ndarray:
    """Response at ``f`` (Hz) of ``(A, Bm, C)`` behind a zero-order hold and ``tau`` samples of input delay.

    The discretisation of :func:`commission.controllers.linear.sampled_plant` (modified
    z-transform), for any continuous model.
    """
    n = int(math.floor(tau + 1e-9))
    fr = tau - n
    if fr < 1e-9:
        fr = 0.0
    Phi_a, G_a = _hold(A, Bm, (1.0 - fr) * Ts)
    if fr > 0:
        Phi_b, G_b = _hold(A, Bm, fr * Ts)
        G1 = Phi_a @ G_b
        Phi = Phi_a @ Phi_b
    else:
        G1 = np.zeros_like(G_a)
        Phi = Phi_a
    return SampledPlant(Phi=Phi, G0=G_a, G1=G1, C=C, n=n, Ts=float(Ts)).frequency_response(f)


def _model_response(structure: str, M: float, B: float, Ts: float, delay_samples: float, mode_hz: float,
                    damping: float, ratio: float, extra: tuple[ExtraMode, ...], f: np.ndarray) -> np.ndarray:
    """Sampled response of the two-mass plant (first mode) behind the extra modes' factors, m per u-unit."""
    A, Bm, C = continuous_model(_plant(structure, M, B, Ts, 0.0, mode_hz, damping, ratio))
    for m in extra:
        Af, Bf, Cf, Df = _factor(m)
        nf, nx = Af.shape[0], A.shape[0]
        A2 = np.zeros((nf + nx, nf + nx))
        A2[:nf, :nf] = Af
        A2[nf:, :nf] = Bm @ Cf
        A2[nf:, nf:] = A
        B2 = np.vstack([Bf, Bm * Df])
        C2 = np.hstack([np.zeros((1, nf)), C])
        A, Bm, C = A2, B2, C2
    return _sampled_response(A, Bm, C, Ts, delay_samples, f)


def _layout(structure: str, extra_kinds: tuple[str, ...]) -> list[int]:
    """Parameters per mode: 0 (rigid), 2 (load side: f, zeta) or 3 (motor side: f, zeta, r)."""
    first = {"rigid": 0, "load_side_mode": 2, "motor_side_mode": 3}[structure]
    return [first] + [3 if k == "motor" else 2 for k in extra_kinds]


def _unpack(structure: str, x: np.ndarray, extra_kinds: tuple[str, ...] = ()
            ) -> tuple[float, float, float, float, float, tuple[ExtraMode, ...]]:
    """x -> (mass_scale, delay_samples, mode_hz, damping, ratio, extra modes)."""
    scale, delay = math.exp(x[0]), x[1]
    lay = _layout(structure, extra_kinds)
    i = 2
    fr = z = 0.0
    r = 0.5
    if lay[0]:
        fr, z = math.exp(x[2]), math.exp(x[3])
        r = x[4] if lay[0] == 3 else 0.5
    i += lay[0]
    extra = []
    for kind, k in zip(extra_kinds, lay[1:]):
        extra.append(ExtraMode(kind, math.exp(x[i]), math.exp(x[i + 1]), float(x[i + 2]) if k == 3 else 0.5))
        i += k
    return scale, delay, fr, z, r, tuple(extra)
