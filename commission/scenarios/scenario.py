"""What one closed-loop run is: :class:`Scenario` (a plant vector, a desired trajectory, an input
disturbance, the initial position, the encoder), with its trajectory (:class:`TrajectorySpec`)
and disturbance (:class:`StepDisturbance`)."""

from __future__ import annotations

import hashlib
from dataclasses import dataclass
from typing import Any

import numpy as np

from commission.controllers import trajectory as _traj
from commission.controllers.plant import NP
from commission.moves import UserProfile
from commission.spec import DEFAULT_QUANTIZATION


@dataclass(frozen=True)
class TrajectorySpec:
    """A desired trajectory, rendered at the controller rate by :meth:`render`.

    Attributes
    ----------
    kind : str
        ``"case1"`` (sinusoid through (58)), ``"case2"`` (back-and-forth trapezoids) or
        ``"user"`` (the machine's own moves, :mod:`commission.moves`).
    duration : float
        Length of the run, s.
    amplitude, omega : float
        Case 1: reference ``amplitude sin(omega t)``, m and rad/s (0 for case2).
    travel, v_max, a_max, dwell : float
        Case 2: move length (m), speed (m/s), acceleration (m/s^2), rest (s).
    moves : int
        Case 2: number of moves.
    beta1, beta2 : float
        Filter (58) / smoothing coefficients, 1/s and 1/s^2.
    profile : UserProfile or None
        ``"user"``: the profile, rendered as it is (no filter) and held at rest after its end.
    """

    kind: str
    duration: float
    amplitude: float = 0.0
    omega: float = 0.0
    travel: float = 0.0
    v_max: float = 0.0
    a_max: float = 0.0
    dwell: float = 0.0
    moves: int = 0
    beta1: float = 100.0
    beta2: float = 2500.0
    profile: UserProfile | None = None

    def render(self, Ts: float, y0: float = 0.0) -> _traj.Trajectory:
        """Sample q_d, dq_d, ddq_d every ``Ts`` s starting with q_d(0) = ``y0`` (m)."""
        if self.kind == "user" and self.profile is not None:
            return self.profile.render(self.duration, Ts, y0)
        if self.kind == "case1":
            return _traj.sinusoid(self.duration, Ts, amplitude=self.amplitude, omega=self.omega,
                                  beta1=self.beta1, beta2=self.beta2, y0=y0)
        if self.kind == "case2":
            return _traj.back_and_forth(self.duration, Ts, travel=self.travel, v_max=self.v_max,
                                        a_max=self.a_max, dwell=self.dwell, n_moves=self.moves,
                                        b1=self.beta1, b2=self.beta2, start=y0)
        raise ValueError(f"TrajectorySpec.kind: expected 'case1', 'case2' or 'user', got {self.kind!r}")

    def to_dict(self) -> dict[str, Any]:
        out = {k: getattr(self, k) for k in self.__dataclass_fields__ if k != "profile"}
        if self.profile is not None:
            out["profile"] = {"kind": self.profile.kind, "sha256": self.profile.sha256, "end": self.profile.end,
                              "v_peak": self.profile.v_peak, "a_peak": self.profile.a_peak, "span": self.profile.span}
        return out


@dataclass(frozen=True)
class StepDisturbance:
    """An input disturbance ``amplitude`` (u-unit) added to u for ``t_on <= t < t_off`` (s)."""

    amplitude: float = 0.0
    t_on: float = 0.0
    t_off: float = 0.0

    def samples(self, t: np.ndarray) -> np.ndarray:
        """The disturbance held over each sample period starting at ``t`` (s), u-unit."""
        t = np.asarray(t, dtype=np.float64)
        return np.where((t >= self.t_on) & (t < self.t_off), self.amplitude, 0.0)

    def to_dict(self) -> dict[str, float]:
        return {"amplitude": self.amplitude, "t_on": self.t_on, "t_off": self.t_off}


NO_DISTURBANCE = StepDisturbance()


def read_only_plant(plant: Any, owner: str) -> np.ndarray:
    """A read-only float64 copy of a plant vector (:mod:`commission.controllers.plant` layout).

    The frozen records that hold a plant (:class:`Scenario`, :class:`commission.tuning.Tuning`)
    store this copy, so that neither the caller's array nor anyone after can change what the
    record says.  A vector that is not ``NP`` entries long is a :class:`ValueError` naming
    ``owner`` and the shape.
    """
    p = np.array(plant, dtype=np.float64)
    if p.shape != (NP,):
        raise ValueError(f"{owner}: plant must have {NP} entries, got shape {p.shape}")
    p.setflags(write=False)
    return p


@dataclass(frozen=True)
class Scenario:
    """One closed-loop run of the matrix.

    Plain data -- the plant, the motion, the disturbance and the encoder -- with the encoder
    noise seeded by the name (:meth:`noise`), so that ``tune`` and ``validate`` simulate a
    scenario of the same name alike.

    Attributes
    ----------
    name : str
        Unique name, e.g. ``"case1/payload_heavy"`` or ``"mc/007"``.
    plant : numpy.ndarray
        float64[NP] plant vector (:func:`commission.controllers.plant.plant_vector`
        layout), read-only.
    trajectory : TrajectorySpec
        Desired motion.
    disturbance : StepDisturbance
        Input disturbance, u-unit.
    y0 : float
        Initial position (and q_d(0)), m.
    tags : tuple of str
        ``case1``/``case2``, the variant, ``"tune"`` (in the tuning subset),
        ``"monte_carlo"``.
    quantization : float
        Encoder resolution, m (0: none).
    noise_std : float
        Standard deviation of the encoder's position noise before quantization, m (0: none);
        :meth:`noise` draws it, the same for a scenario name in ``tune`` and ``validate``.
    """

    name: str
    plant: np.ndarray
    trajectory: TrajectorySpec
    disturbance: StepDisturbance = NO_DISTURBANCE
    y0: float = 0.0
    tags: tuple[str, ...] = ()
    quantization: float = DEFAULT_QUANTIZATION
    noise_std: float = 0.0

    def noise(self, n: int) -> np.ndarray | None:
        """``n`` samples of encoder noise, m, seeded by the scenario's name (None when there is none)."""
        if not self.noise_std > 0:
            return None
        seed = int.from_bytes(hashlib.sha256(self.name.encode()).digest()[:8], "little")
        return np.random.default_rng(seed).normal(0.0, self.noise_std, n)

    def __post_init__(self) -> None:
        object.__setattr__(self, "plant", read_only_plant(self.plant, f"Scenario {self.name}"))
        object.__setattr__(self, "tags", tuple(self.tags))

    def reference(self, Ts: float):
        """The desired trajectory sampled every ``Ts`` s (:class:`controllers.trajectory.Trajectory`)."""
        return self.trajectory.render(Ts, self.y0)

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready description (for reports)."""
        return {
            "name": self.name,
            "plant": [float(x) for x in self.plant],
            "trajectory": self.trajectory.to_dict(),
            "disturbance": self.disturbance.to_dict(),
            "y0": self.y0,
            "tags": list(self.tags),
            "quantization": self.quantization,
            "noise_std": self.noise_std,
        }
