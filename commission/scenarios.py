"""The scenario matrix shared by ``commission tune`` and ``commission validate``.

A :class:`Scenario` is one closed-loop run: a plant (the
:mod:`commission.controllers.plant` vector), a desired trajectory, an input
disturbance, the initial position and the encoder resolution.  It is defined
only from an :class:`~commission.artifacts.Identification` and a
:class:`~commission.spec.Spec`, so that ``validate`` re-creates exactly the
plants ``tune`` optimised on, plus the Monte-Carlo sample.

Full matrix of :func:`scenario_matrix` (validate), for each trajectory
``case1`` (sinusoid through filter (58)) and ``case2`` (trapezoidal
back-and-forth moves), both scaled to the spec's envelope:

``<case>/nominal``
    The identified plant.
``<case>/payload_light``, ``<case>/payload_heavy``
    Mass at the theta_1 bounds: M = 1/theta_max[0] and M = 1/theta_min[0]
    (viscous B, friction and offset unchanged: a payload changes the mass only).
``<case>/friction_low``, ``<case>/friction_high``
    The identified friction curve B v + Ff(v) scaled by 0.8 and 1.2
    (B, fc, fs scaled; vs, xi kept).
``<case>/disturbance``
    The identified plant with an input step of ``delta_d * M`` u-unit (the
    Assumption-1 bound, as an input) on from 22 % to 72 % of the run (the
    paper's 2.2 s to 7.2 s of 10 s).
``<case>/delay+1``
    The identified plant with one more sample of input delay than identified
    (a drive's computation or bus delay that the log cannot show).
``<case>/mode_low``, ``<case>/mode_high``, ``<case>/mode_damping_half``
    When the plant has a structural mode: its frequency at 0.8 and 1.2 times
    and its damping halved (what the identification's errors and a changed
    load can do to it); a second identified mode moves with the first.  Without a known mode, the stability margins
    (:mod:`commission.robustness`) stand in for it.
``mc/NNN``
    ``n_monte_carlo`` plants from the theta box (a defaulted payload or load-force range only
    where the log supports it: :func:`monte_carlo_support`), alternating case1 and case2,
    drawn from the passed Generator: theta1 uniform in the box (M = 1/theta1),
    the viscous B and the disturbance force d_n = -offset uniform in the ranges
    the box admits at every mass (:func:`viscous_range`, :func:`force_range`),
    the identified friction curve.  Every drawn theta lies in the box.

Every non-Monte-Carlo scenario carries the tag ``"tune"``.  :func:`tuning_scenarios`
(what ``tune`` optimises on) is these 12, plus the 16 corners of the theta box
on both trajectories (``corner/<case>/<bits>``, tune-only: the deterministic
extremes of the box the Monte-Carlo sample draws from), plus the identified
plant with the largest force of :func:`force_range` of either sign
(``offset/<case>/lo|hi``, tune-only), plus ``spec.monte_carlo`` Monte-Carlo plants.

The machine's own moves (``user/...``)
--------------------------------------
When the spec gives the machine's moves (``[trajectory] file`` or ``[[trajectory.move]]``,
:mod:`commission.moves`), a third trajectory ``user`` joins Case 1 and Case 2 everywhere
above: ``user/nominal`` ... ``user/disturbance``, ``user/delay+1`` (and the mode variants),
the box corners, largest forces and interior payloads of tune (``corner/user/...``,
``offset/user/...``, ``payload/user/...``), and every third Monte-Carlo plant (the sample
cycles through case1, case2, user).  The profile is rendered as it is, without filter (58):
the drive follows its own generator's q, v, a; it is held at rest :data:`CASE2_TAIL` s after
its end.  Case 1 and Case 2 stay as the paper's reference scenarios, scaled to
``spec.case_v_max``/``case_a_max`` (the spec's ``reference_v_max``/``reference_a_max``;
``tune`` derives them for this drive when not given: :func:`commission.tune.defaults.reference_envelope`).

Trajectory scaling (paper: travel 0.4 m, v_max 1 m/s, a_max 12 m/s^2)
---------------------------------------------------------------------
v_max and a_max here are the reference envelope ``spec.case_v_max``, ``spec.case_a_max``
(the spec's v_max, a_max unless the machine's moves are given).
Case 1: amplitude A = travel/8 and omega = min(0.2 v_max / A, sqrt(a_max / (15 A)))
(both 4 rad/s for the paper's envelope, A = 0.05 m), 10 s or four periods,
whichever is longer.  Case 2: ``moves`` moves of ``travel`` at v_max, a_max
with ``dwell`` rests, then 2.1 s at rest (8 s for the paper's envelope), so
that e_F measures the standstill accuracy.
"""

from __future__ import annotations

import hashlib
import math
from dataclasses import dataclass
from typing import Any, Sequence

import numpy as np

from commission.artifacts import Identification
from commission.controllers import trajectory as _traj
from commission.controllers.plant import (
    NP,
    P_DELAY,
    P_MODE2_DAMPING,
    P_MODE2_HZ,
    P_MODE_DAMPING,
    P_MODE_HZ,
    P_B,
    P_FC,
    P_FS,
    P_M,
    P_OFFSET,
    plant_vector,
)
from commission.moves import UserProfile
from commission.errors import SpecError
from commission.spec import DEFAULT_QUANTIZATION, MAX_TRAJECTORY_SAMPLES, Spec, check_trajectory_samples

#: Fraction of the run at which the disturbance step switches on / off (paper: 2.2 s, 7.2 s of 10 s).
DISTURBANCE_ON = 0.22
DISTURBANCE_OFF = 0.72
#: Friction scaling of the friction scenarios (+-20 % of the identified curve).
FRICTION_SCALE = 0.2
#: Rest after the last Case-2 move, s (the paper: 8 s - 5.9 s).
CASE2_TAIL = 2.1
#: Case-1 minimum duration, s (paper: 10 s).
CASE1_DURATION = 10.0

#: Case 1's peak reference speed A omega as a fraction of v_max (0.2 m/s of the paper's 1 m/s).
#: Filter (58) starts at rest, so q_dd(0) = beta1 A omega: 20 m/s^2 for the paper, above its a_max.
CASE1_SPEED_FRACTION = 0.2

#: Plant sub-steps per controller sample at and below the paper's 2.5 kHz (a 40 us plant step there).
PLANT_SUBSTEPS = 10
#: Longest plant integration step above 2.5 kHz, s: the paper's 10 sub-steps of 400 us.
PLANT_STEP = 4e-5


def plant_substeps(sample_rate: float) -> int:
    """Plant sub-steps per controller sample in tune's and validate's simulations.

    :data:`PLANT_SUBSTEPS` (10) at and below the paper's 2.5 kHz, where the paper's Table 1
    is reproduced with them; above, as many as keep the plant step at or below the paper's
    40 us (:data:`PLANT_STEP`): 7 at 4 kHz, 5 at 5 kHz.  A finer step there bought no
    accuracy the encoder shows and cost a third of a 5-kHz tuning's time.

    Parameters
    ----------
    sample_rate : float
        Controller sample rate, Hz.
    """
    if sample_rate <= 2500.0:
        return PLANT_SUBSTEPS
    return max(1, math.ceil(1.0 / (sample_rate * PLANT_STEP) - 1e-9))


CASES = ("case1", "case2")
VARIANTS = ("nominal", "payload_light", "payload_heavy", "friction_low", "friction_high", "disturbance")


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


@dataclass(frozen=True)
class Scenario:
    """One closed-loop run of the matrix.

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
        p = np.array(self.plant, dtype=np.float64)
        if p.shape != (NP,):
            raise ValueError(f"Scenario {self.name}: plant must have {NP} entries, got shape {p.shape}")
        p.setflags(write=False)
        object.__setattr__(self, "plant", p)
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


def _num(x: Any) -> float | None:
    if isinstance(x, dict):  # {"value": ..., "std": ...}
        x = x.get("value")
    if isinstance(x, (int, float)) and not isinstance(x, bool) and math.isfinite(x):
        return float(x)
    return None


def _ripple(ident: Identification) -> tuple[float, float]:
    """Force ripple (amplitude u-unit, pitch m) recorded in ident.json's extra fields, if any.

    Read from ``extra["model"]["ripple_amp"]`` / ``["ripple_pitch"]`` (what
    ``commission identify`` writes) or ``extra["ripple"] = {"amplitude", "pitch"}``.
    """
    model = ident.extra.get("model")
    if isinstance(model, dict):
        amp, pitch = _num(model.get("ripple_amp")), _num(model.get("ripple_pitch"))
        if amp is not None and pitch is not None and pitch > 0:
            return abs(amp), pitch
    r = ident.extra.get("ripple")
    if isinstance(r, dict):
        amp, pitch = _num(r.get("amplitude", r.get("amp"))), _num(r.get("pitch"))
        if amp is not None and pitch is not None and pitch > 0:
            return abs(amp), pitch
    return 0.0, 0.0


def plant_dynamics(ident: Identification, spec: Spec | None) -> dict[str, float]:
    """The structural modes and input delay of the plant (:func:`plant_vector` keywords).

    From ident.json's ``frequency_response.model`` (what ``commission identify``
    found in the log's broadband content: one mode, or two as two appendages on the motor,
    ``mode2_*``); without a delay there, the input delay of ``model.inverse_dynamics`` when
    its ``delay`` term was chosen (a negative one counts as none); each entry overridden by
    the spec's ``[plant]`` section when given there (a spec that states the mode's frequency,
    load fraction or encoder drops the log's second mode: it belonged to the log's first);
    rigid and delay-free when neither says
    otherwise.  Every scenario plant of ``tune`` and ``validate`` carries them (a
    payload moves the mass, not the mode: its frequency and load fraction are kept).
    """
    out: dict[str, float] = {}
    fr = ident.extra.get("frequency_response")
    model = fr.get("model") if isinstance(fr, dict) else None
    if isinstance(model, dict):
        for m in ("mode", "mode2"):  # the second mode only beside the first
            f = _num(model.get(f"{m}_hz"))
            if f is None or f <= 0:
                break
            out[f"{m}_hz"] = f
            for key in (f"{m}_damping", f"{m}_ratio"):
                v = _num(model.get(key))
                if v is not None:
                    out[key] = v
            out[f"{m}_load_side"] = bool(model.get(f"{m}_load_side"))
        d = _num(model.get("delay_s"))
        if d is not None and d > 0:
            out["delay"] = d
    if "delay" not in out:
        # No delay from a broadband segment: the one the delay-aware least squares chose, if any.
        m = ident.extra.get("model")
        inv = m.get("inverse_dynamics") if isinstance(m, dict) else None
        if isinstance(inv, dict) and "delay" in (inv.get("terms") or []):
            d = _num(inv.get("delay_s"))
            if d is not None and d > 0:
                out["delay"] = d
    if spec is not None:
        if any(v is not None for v in (spec.plant_mode_hz, spec.plant_mode_ratio, spec.plant_encoder)):
            # The spec states its own mode: the log's second mode belonged to the log's first.
            for key in ("mode2_hz", "mode2_damping", "mode2_ratio", "mode2_load_side"):
                out.pop(key, None)
        if spec.plant_mode_hz is not None:
            out["mode_hz"] = spec.plant_mode_hz
        if spec.plant_mode_damping is not None:
            out["mode_damping"] = spec.plant_mode_damping
        if spec.plant_mode_ratio is not None:
            out["mode_ratio"] = spec.plant_mode_ratio
        if spec.plant_encoder is not None:
            out["mode_load_side"] = spec.plant_encoder == "load"
        if spec.plant_delay_samples is not None:
            out["delay"] = spec.plant_delay_samples * spec.period
    return out


def identified_plant(ident: Identification, spec: Spec | None = None) -> np.ndarray:
    """The plant vector of the identified model (CONTRACT §2 parameters).

    A Coulomb-only model (``fs`` absent) gets ``fs = fc`` (vs, xi then
    irrelevant).  Ripple comes from ``ident.extra["ripple"]`` =
    ``{"amplitude": u-unit, "pitch": m}`` when present.  The mode and the input
    delay are :func:`plant_dynamics` of ``ident`` and ``spec``.
    """
    par = ident.parameters
    fc = max(ident.value("fc"), 0.0)
    fs = par["fs"].value if par.get("fs") is not None else fc  # type: ignore[union-attr]
    vs = par["vs"].value if par.get("vs") is not None else 0.01  # type: ignore[union-attr]
    xi = par["xi"].value if par.get("xi") is not None else 2.0  # type: ignore[union-attr]
    amp, pitch = _ripple(ident)
    return plant_vector(M=ident.value("M"), B=max(ident.value("B"), 0.0), fc=fc, fs=max(fs, 0.0),
                        vs=vs if vs > 0 else 0.01, xi=xi if xi > 0 else 2.0,
                        offset=ident.value("offset"), ripple_amp=amp, ripple_pitch=pitch,
                        **plant_dynamics(ident, spec))  # type: ignore[arg-type]


def resolve_quantization(ident: Identification, spec: Spec) -> float:
    """Encoder resolution used in simulation, m.

    The spec's ``controller.quantization``; else ident.json's
    ``extra["encoder"]["quantization"]`` (what ``commission identify`` writes) or
    ``extra["quantization"]``; else :data:`commission.spec.DEFAULT_QUANTIZATION` (1 um).
    """
    if spec.quantization is not None:
        return float(spec.quantization)
    enc = ident.extra.get("encoder")
    for q in ((enc.get("quantization") if isinstance(enc, dict) else None), ident.extra.get("quantization")):
        v = _num(q)
        if v is not None and v >= 0:
            return v
    return DEFAULT_QUANTIZATION


def resolve_encoder_noise(ident: Identification, spec: Spec) -> float:
    """Encoder noise simulated, m rms: the spec's ``[plant] noise_std``, else ident.json's
    ``extra["encoder"]["noise_std"]``, else 0 (quantization only)."""
    if spec.plant_noise_std is not None:
        return float(spec.plant_noise_std)
    enc = ident.extra.get("encoder")
    v = _num(enc.get("noise_std")) if isinstance(enc, dict) else None
    return v if v is not None and v >= 0 else 0.0


def max_horizon(sample_rate: float) -> float:
    """The longest run, s, whose samples at ``sample_rate`` Hz stay within the cap
    :data:`commission.spec.MAX_TRAJECTORY_SAMPLES` (rounded down to the millisecond)."""
    return math.floor(MAX_TRAJECTORY_SAMPLES / sample_rate * 1000.0) / 1000.0


def _case1_full_duration(spec: Spec) -> tuple[float, float, float]:
    A = spec.travel / 8.0
    omega = min(CASE1_SPEED_FRACTION * spec.case_v_max / A, math.sqrt(spec.case_a_max / (15.0 * A)))
    return A, omega, max(CASE1_DURATION, 4.0 * 2.0 * math.pi / omega)


def case1_trajectory(spec: Spec) -> TrajectorySpec:
    """Case 1 scaled to the envelope (module docstring); the paper's 0.05 sin(4t), 10 s by default.

    Its length is four periods of the sinusoid (at least :data:`CASE1_DURATION`), cut at
    :func:`max_horizon` where a high rate would take it past the sample cap (a slow envelope at
    10 kHz: 34.88 s = 348,800 samples); :func:`horizon_notes` says so.
    """
    A, omega, duration = _case1_full_duration(spec)
    duration = min(duration, max_horizon(spec.sample_rate))
    return TrajectorySpec("case1", duration=duration, amplitude=A, omega=omega,
                          beta1=spec.beta1, beta2=spec.beta2)


def _case2_duration(spec: Spec, moves: int) -> float:
    sched = _traj.trapezoid_moves(spec.travel, spec.case_v_max, spec.case_a_max, spec.dwell, moves)
    return round(float(sched.t_switch[-1]) + CASE2_TAIL, 6)


#: Fewest Case-2 moves a shortened run keeps: a move and its return.
CASE2_MIN_MOVES = 2


def _case2_moves(spec: Spec) -> int:
    """``spec.moves``, or fewer (down to :data:`CASE2_MIN_MOVES`) while the run would exceed
    :func:`max_horizon`; a run that does not fit even then is refused by :func:`check_run_length`."""
    cap = max_horizon(spec.sample_rate)
    n = spec.moves
    while n > CASE2_MIN_MOVES and _case2_duration(spec, n) > cap:
        n -= 1
    return n


def case2_trajectory(spec: Spec) -> TrajectorySpec:
    """Case 2 on the envelope: ``moves`` moves of ``travel``, then :data:`CASE2_TAIL` s at rest.

    Where a high rate would take the run past the sample cap, fewer moves are run (as many as fit
    in :func:`max_horizon`, at least a move and its return); :func:`horizon_notes` says so.
    """
    n = _case2_moves(spec)
    return TrajectorySpec("case2", duration=_case2_duration(spec, n), travel=spec.travel, v_max=spec.case_v_max,
                          a_max=spec.case_a_max, dwell=spec.dwell, moves=n,
                          beta1=spec.beta1, beta2=spec.beta2)


def horizon_notes(spec: Spec) -> tuple[str, ...]:
    """One line per trajectory whose horizon was shortened to stay within the sample cap (empty: none).

    For the report and the commands' ``note:`` lines: the validation then covers a shorter run
    than the envelope's full Case 1 or Case 2.
    """
    out = []
    _, omega, full = _case1_full_duration(spec)
    c1 = case1_trajectory(spec).duration
    if c1 < full:
        out.append(f"Case 1 runs {c1:.4g} s ({c1 * omega / (2 * math.pi):.2g} periods) instead of {full:.4g} s: "
                   f"at {spec.sample_rate:g} Hz the full run would exceed the {MAX_TRAJECTORY_SAMPLES} samples "
                   f"a simulation accepts")
    n = _case2_moves(spec)
    if n < spec.moves:
        out.append(f"Case 2 runs {n} of the {spec.moves} moves ({_case2_duration(spec, n):.4g} s instead of "
                   f"{_case2_duration(spec, spec.moves):.4g} s): at {spec.sample_rate:g} Hz the full run would "
                   f"exceed the {MAX_TRAJECTORY_SAMPLES} samples a simulation accepts")
    return tuple(out)


def user_trajectory(spec: Spec) -> TrajectorySpec | None:
    """The machine's own moves (``spec.profile``), then :data:`CASE2_TAIL` s at rest; None without them."""
    if spec.profile is None:
        return None
    return TrajectorySpec("user", duration=round(spec.profile.end + CASE2_TAIL, 6), beta1=spec.beta1,
                          beta2=spec.beta2, profile=spec.profile)


def trajectories(spec: Spec) -> list[tuple[str, TrajectorySpec]]:
    """``[(case, trajectory)]``: Case 1, Case 2 and, when the spec gives the machine's moves, ``"user"``."""
    out = [("case1", case1_trajectory(spec)), ("case2", case2_trajectory(spec))]
    u = user_trajectory(spec)
    if u is not None:
        out.append(("user", u))
    return out


def case_names(spec: Spec) -> tuple[str, ...]:
    """The trajectory names of :func:`trajectories` (:data:`CASES`, plus ``"user"`` with the machine's moves)."""
    return CASES + (("user",) if spec.profile is not None else ())


def _variant(base: np.ndarray, variant: str, ident: Identification) -> np.ndarray:
    p = base.copy()
    if variant == "payload_light":
        p[P_M] = 1.0 / ident.theta.max[0]
    elif variant == "payload_heavy":
        p[P_M] = 1.0 / ident.theta.min[0]
    elif variant in ("friction_low", "friction_high"):
        k = 1.0 - FRICTION_SCALE if variant == "friction_low" else 1.0 + FRICTION_SCALE
        for i in (P_B, P_FC, P_FS):
            p[i] *= k
    return p


def check_run_length(spec: Spec, source: str, prefix: str = "") -> None:
    """Refuse a spec whose Case 1 or Case 2 would exceed :data:`commission.spec.MAX_TRAJECTORY_SAMPLES`.

    Called by ``tune`` (after the defaults were fitted to the axis) and ``validate``
    (on tuning.json's spec) before any simulation.

    Raises
    ------
    SpecError
        Naming ``controller.sample_rate`` and the trajectory.
    """
    check_user_length(spec, source, prefix)
    check_trajectory_samples(source, prefix, spec.sample_rate,
                             {"Case 1": case1_trajectory(spec).duration, "Case 2": case2_trajectory(spec).duration})


def check_user_length(spec: Spec, source: str, prefix: str = "") -> None:
    """Refuse machine moves whose run (+ :data:`CASE2_TAIL` s at rest) exceeds the sample cap, naming them.

    Raises
    ------
    SpecError
        Naming ``trajectory.file`` (the path) or ``trajectory.move``, the duration, the samples at
        ``controller.sample_rate`` and the longest profile accepted.
    """
    u = user_trajectory(spec)
    if u is not None:
        n = u.duration * spec.sample_rate
        if not n <= MAX_TRAJECTORY_SAMPLES:
            p = u.profile
            assert p is not None
            where = f"{prefix}trajectory.file = {p.path!r}" if p.kind == "file" else f"{prefix}trajectory.move"
            longest = MAX_TRAJECTORY_SAMPLES / spec.sample_rate - CASE2_TAIL
            raise SpecError(
                f"{source}: {where}: the machine's moves last {p.end:.6g} s (+ {CASE2_TAIL:g} s at rest) = "
                f"{n:.0f} samples per run at controller.sample_rate = {spec.sample_rate:g} Hz, more than the "
                f"{MAX_TRAJECTORY_SAMPLES} accepted; give at most {longest:.6g} s of moves (the part that "
                f"matters: one cycle of the machine), or lower controller.sample_rate")


def disturbance_step(ident: Identification, duration: float) -> StepDisturbance:
    """The Assumption-1-sized step: ``delta_d * M`` u-unit over 22 %..72 % of ``duration``."""
    return StepDisturbance(ident.delta_d * ident.value("M"), DISTURBANCE_ON * duration,
                           DISTURBANCE_OFF * duration)


def force_range(ident: Identification) -> tuple[float, float]:
    """Range of the nominal disturbance force d_n = -offset that the box admits at every mass, u-unit.

    theta3 = d_n / M must stay in [theta3_min, theta3_max] for every M in
    [1/theta1_max, 1/theta1_min]; the binding end is the lightest mass, so
    d_n in [theta3_min, theta3_max] / theta1_max.  (A payload adds mass, not force.)
    """
    m_light = 1.0 / ident.theta.max[0]
    return ident.theta.min[2] * m_light, ident.theta.max[2] * m_light


def viscous_range(ident: Identification) -> tuple[float, float]:
    """Range of the viscous coefficient B that the box admits at every mass, u-unit s/m.

    theta2 = B / M must stay in [theta2_min, theta2_max] for every M in
    [1/theta1_max, 1/theta1_min]: B >= theta2_min / theta1_min (heaviest mass) and
    B <= theta2_max / theta1_max (lightest).  This is the inverse of the interval
    arithmetic that built the box (:mod:`commission.identify.bounds`), so for a box
    built by ``commission identify`` it returns the viscous range it was built from.
    A payload adds mass, not viscous friction: pairing the heaviest payload with the
    largest theta2 (B = theta2_max / theta1_min) would ask for up to
    theta1_max / theta1_min times the largest B the empty axis may have.  When the
    box admits no B at every mass (lower end above the upper), the identified B
    (clipped to zero) is returned as a point range.
    """
    lo = ident.theta.min[1] / ident.theta.min[0]
    hi = ident.theta.max[1] / ident.theta.max[0]
    if lo > hi:
        b = max(ident.value("B"), 0.0)
        return b, b
    return lo, hi


def clip_to_box(plants: np.ndarray, ident: Identification) -> np.ndarray:
    """Clip B and the offset of plant vectors (rows) so that theta2, theta3 lie in the box at each row's mass."""
    out = np.array(plants, dtype=np.float64, copy=True)
    m = out[:, P_M]
    out[:, P_B] = np.clip(out[:, P_B], ident.theta.min[1] * m, ident.theta.max[1] * m)
    # theta3 = d_n / M with d_n = -offset
    out[:, P_OFFSET] = -np.clip(-out[:, P_OFFSET], ident.theta.min[2] * m, ident.theta.max[2] * m)
    return out


def monte_carlo_support(ident: Identification) -> tuple[float, float, float, float]:
    """The part of the theta box the Monte-Carlo sample draws from: ``(theta1_lo, theta1_hi, d_lo, d_hi)``.

    The whole box (theta1 in [theta1_min, theta1_max], d_n in :func:`force_range`), except where
    ident.json records a range as the tool's default rather than the user's statement
    (``bounds.payload_defaulted``, ``bounds.disturbance_bound_defaulted``):

    * a defaulted payload: masses up to the unloaded heavy end only (theta1 >= 1 / (M_hi - payload_max),
      the mass the identification itself supports, with its spread and model margin);
    * a defaulted load-force bound: d_n within the Assumption-1 load step about the identified
      constant force, ``-offset +- delta_d M`` (the step the ``disturbance`` scenario applies), cut to
      :func:`force_range`.

    Why: the Monte-Carlo plants certify performance (the ARC-vs-yardstick quantiles,
    :mod:`commission.gate`, "What each scenario certifies"), which rests on what the log supports;
    a default payload of up to three times the mass and a load of ten times the stiction are guesses,
    whose corners the fixed scenarios (``payload_heavy``, ``disturbance``) and the whole-box margins
    still hold to safety.  A stated range is drawn in full.
    """
    t_lo, t_hi = ident.theta.min[0], ident.theta.max[0]
    d_lo, d_hi = force_range(ident)
    b = ident.extra.get("bounds") if isinstance(ident.extra, dict) else None
    if not isinstance(b, dict):
        return t_lo, t_hi, d_lo, d_hi
    pr = b.get("payload_range")
    if b.get("payload_defaulted") is True and isinstance(pr, list) and len(pr) == 2:
        m_unloaded = 1.0 / t_lo - float(pr[1])
        if m_unloaded > 0:
            t_lo = min(max(t_lo, 1.0 / m_unloaded), t_hi)
    if b.get("disturbance_bound_defaulted") is True and ident.delta_d is not None:
        p = identified_plant(ident)
        dn, r = -float(p[P_OFFSET]), abs(float(ident.delta_d) * float(p[P_M]))
        lo, hi = max(d_lo, dn - r), min(d_hi, dn + r)
        if lo <= hi:
            d_lo, d_hi = lo, hi
    return t_lo, t_hi, d_lo, d_hi


def monte_carlo_plants(ident: Identification, n: int, rng: np.random.Generator,
                       spec: Spec | None = None) -> np.ndarray:
    """``n`` plant vectors from the theta box (identified friction curve), shape (n, NP).

    theta1 is uniform in the box (M = 1/theta1), within :func:`monte_carlo_support` (a defaulted payload
    or load bound is drawn only where the log supports it); the viscous coefficient B is
    uniform in :func:`viscous_range` and the disturbance force d_n = -offset
    uniform in :func:`force_range`, the ranges the box admits at every mass, so
    that theta2 = B / M and theta3 = d_n / M lie in the box for every drawn mass.
    (Drawing theta2, theta3 uniformly instead would pair the heaviest payload with
    B = theta2_max / theta1_min and forces theta3_max / theta1_min, up to
    theta1_max / theta1_min times what the box admits for the empty axis: a
    payload adds mass, not viscous friction or force.)
    """
    base = identified_plant(ident, spec)
    lo, hi, d_lo, d_hi = monte_carlo_support(ident)
    u = rng.random((n, 3))
    b_lo, b_hi = viscous_range(ident)
    out = np.tile(base, (n, 1))
    out[:, P_M] = 1.0 / (lo + (hi - lo) * u[:, 0])
    out[:, P_B] = b_lo + (b_hi - b_lo) * u[:, 1]
    out[:, P_OFFSET] = -(d_lo + (d_hi - d_lo) * u[:, 2])
    return clip_to_box(out, ident)  # only rounding (or the point-range fallback) can leave the box


def scenario_matrix(ident: Identification, spec: Spec, *, rng: np.random.Generator,
                    n_monte_carlo: int = 64) -> list[Scenario]:
    """The full validation matrix (module docstring), deterministic for a given ``rng`` state.

    Parameters
    ----------
    ident : Identification
        Identified model, theta box and delta_d.
    spec : Spec
        Envelope, sample rate (trajectories are rendered later at ``1/spec.sample_rate``).
    rng : numpy.random.Generator
        Source of the Monte-Carlo sample (drawn only when ``n_monte_carlo > 0``).
    n_monte_carlo : int
        Monte-Carlo plants from the theta box (default 64).

    Returns
    -------
    list of Scenario
        The 12 fixed scenarios (tag ``"tune"``) followed by ``mc/000`` ...
    """
    if n_monte_carlo < 0:
        raise ValueError(f"n_monte_carlo: must be >= 0, got {n_monte_carlo}")
    base = identified_plant(ident, spec)
    qz = resolve_quantization(ident, spec)
    nz = resolve_encoder_noise(ident, spec)
    trajs = dict(trajectories(spec))
    cases = tuple(trajs)
    out: list[Scenario] = []
    for case in cases:
        tr = trajs[case]
        for variant in VARIANTS:
            dist = disturbance_step(ident, tr.duration) if variant == "disturbance" else NO_DISTURBANCE
            out.append(Scenario(f"{case}/{variant}", _variant(base, variant, ident), tr, dist, 0.0,
                                (case, variant, "tune"), qz, nz))
    out.extend(robustness_scenarios(ident, spec))
    if n_monte_carlo:
        plants = monte_carlo_plants(ident, n_monte_carlo, rng, spec)
        for i in range(n_monte_carlo):
            case = cases[i % len(cases)]
            out.append(Scenario(f"mc/{i:03d}", plants[i], trajs[case], NO_DISTURBANCE, 0.0,
                                (case, "monte_carlo"), qz, nz))
    return out


#: Bisection steps of :func:`largest_safe_payload`: the certified payload to 1/64 of the default range.
PAYLOAD_BISECTIONS = 6


def payload_heavy_at(scenarios: Sequence[Scenario], mass: float) -> list[Scenario]:
    """The fixed ``<case>/payload_heavy`` scenarios of ``scenarios`` with the moving mass at ``mass``.

    Parameters
    ----------
    scenarios : sequence of Scenario
        A validation matrix (:func:`scenario_matrix`).
    mass : float
        Moving mass M, u-unit s^2/m (the unloaded heavy end plus a payload; viscous B, friction and
        offset unchanged, as in ``payload_heavy``).

    Returns
    -------
    list of Scenario
        Same names, trajectories, disturbances and encoder as the matrix's; only ``M`` differs.
    """
    if not (mass > 0 and math.isfinite(mass)):
        raise ValueError(f"mass: must be a finite positive u-unit s^2/m, got {mass}")
    out = []
    for s in scenarios:
        if "monte_carlo" in s.tags or not s.name.endswith("/payload_heavy"):
            continue
        p = s.plant.copy()
        p[P_M] = mass
        out.append(Scenario(s.name, p, s.trajectory, s.disturbance, s.y0, s.tags, s.quantization, s.noise_std))
    return out


def largest_safe_payload(payload_min: float, payload_max: float, safe: Any,
                         steps: int = PAYLOAD_BISECTIONS) -> float | None:
    """The largest payload in ``[payload_min, payload_max]`` at which ``safe(payload)`` holds, by bisection.

    ``validate`` calls it when the payload range was DEFAULTED and the ARC fails a safety criterion at
    the box's heavy end (issue 30, Build 1: certify the largest payload range that can be certified,
    and say so).  A heavier payload is taken as no easier (the mass scales the force the loop must
    apply and lowers the plant's gain the gains were designed around), so the bisection keeps the
    safe end: the result is ``payload_min`` plus a multiple of ``(payload_max - payload_min) / 2**steps``.

    Parameters
    ----------
    payload_min, payload_max : float
        The default payload range, u-unit s^2/m; ``safe(payload_max)`` is taken as false (the caller saw it fail).
    safe : callable(float) -> bool
        Whether every safety criterion holds with that payload.
    steps : int
        Bisection steps.

    Returns
    -------
    float or None
        None when not even ``payload_min`` is safe (nothing to certify: the gate refuses, naming the corner).
    """
    if not (payload_max > payload_min >= 0.0):
        raise ValueError(f"payload range: need 0 <= min < max, got [{payload_min}, {payload_max}]")
    if not safe(payload_min):
        return None
    lo, hi = payload_min, payload_max
    for _ in range(int(steps)):
        mid = 0.5 * (lo + hi)
        if safe(mid):
            lo = mid
        else:
            hi = mid
    return lo


#: Factors on the mode's frequency in the robustness scenarios.
MODE_FREQUENCY_FACTORS = (0.8, 1.2)
#: Factor on its damping.
MODE_DAMPING_FACTOR = 0.5


def robustness_scenarios(ident: Identification, spec: Spec) -> list[Scenario]:
    """Dynamics the identified model may have wrong, on both trajectories (module docstring).

    Tagged ``"robustness"``: ``validate`` gates them like every other scenario, and ``tune``
    holds its search to the gate on them (:func:`tuning_scenarios`).
    """
    base = identified_plant(ident, spec)
    qz = resolve_quantization(ident, spec)
    nz = resolve_encoder_noise(ident, spec)
    variants: list[tuple[str, np.ndarray]] = []
    p = base.copy()
    p[P_DELAY] += spec.period
    variants.append(("delay+1", p))
    if base[P_MODE_HZ] > 0:
        # Every identified mode moves together (a second one too, P_MODE2_HZ = 0 without it).
        for name, k in zip(("mode_low", "mode_high"), MODE_FREQUENCY_FACTORS):
            p = base.copy()
            p[P_MODE_HZ] *= k
            p[P_MODE2_HZ] *= k
            variants.append((name, p))
        p = base.copy()
        p[P_MODE_DAMPING] *= MODE_DAMPING_FACTOR
        p[P_MODE2_DAMPING] *= MODE_DAMPING_FACTOR
        variants.append(("mode_damping_half", p))
    out = []
    for case, tr in trajectories(spec):
        for name, p in variants:
            out.append(Scenario(f"{case}/{name}", p, tr, NO_DISTURBANCE, 0.0, (case, "robustness"), qz, nz))
    return out


def corner_scenarios(ident: Identification, spec: Spec) -> list[Scenario]:
    """The 8 corners of the Monte-Carlo domain on both trajectories (16 runs), identified friction.

    ``corner/<case>/<b1><b2><b3>`` with ``b = 0`` for the lower, ``1`` for the upper end of
    theta1, the viscous B of :func:`viscous_range` and the force d_n of :func:`force_range`:
    M = 1/theta1, offset = -d_n.  These are the deterministic extremes of the domain that the
    validation's Monte-Carlo sample (:func:`monte_carlo_plants`) draws from.
    """
    base = identified_plant(ident, spec)
    qz = resolve_quantization(ident, spec)
    nz = resolve_encoder_noise(ident, spec)
    lo, hi = ident.theta.min, ident.theta.max
    b_lo, b_hi = viscous_range(ident)
    d_lo, d_hi = force_range(ident)
    out: list[Scenario] = []
    for case, tr in trajectories(spec):
        for b in range(8):
            bits = ((b >> 2) & 1, (b >> 1) & 1, b & 1)
            p = base.copy()
            p[P_M] = 1.0 / (hi[0] if bits[0] else lo[0])
            p[P_B] = b_hi if bits[1] else b_lo
            p[P_OFFSET] = -(d_hi if bits[2] else d_lo)
            p = clip_to_box(p[None, :], ident)[0]
            out.append(Scenario(f"corner/{case}/{bits[0]}{bits[1]}{bits[2]}", p, tr, NO_DISTURBANCE, 0.0,
                                (case, "corner", "tune"), qz, nz))
    return out


def offset_scenarios(ident: Identification, spec: Spec) -> list[Scenario]:
    """The identified plant with the largest unknown force the box admits, both signs, both trajectories.

    ``offset/<case>/lo`` and ``offset/<case>/hi``: offset = -d_n with d_n at the
    lower and upper end of :func:`force_range`, every other parameter as
    identified (theta3 = d_n / M stays inside the box since M >= 1/theta1_max).
    These are the Monte-Carlo plants where the ARC and the PID come closest: the
    start-up transient against an unlearnt force decides e_rms, and the ARC's
    integral action (theta3 adaptation) is limited by the stability of its loop.
    """
    base = identified_plant(ident, spec)
    qz = resolve_quantization(ident, spec)
    nz = resolve_encoder_noise(ident, spec)
    d_lo, d_hi = force_range(ident)
    out: list[Scenario] = []
    for case, tr in trajectories(spec):
        for end, d in (("lo", d_lo), ("hi", d_hi)):
            p = base.copy()
            p[P_OFFSET] = -d
            out.append(Scenario(f"offset/{case}/{end}", p, tr, NO_DISTURBANCE, 0.0, (case, "offset", "tune"), qz, nz))
    return out


#: Interior payloads of :func:`payload_scenarios`: M = M_nominal (M_heavy / M_nominal)^k for these k.
PAYLOAD_STEPS = (0.25, 0.5, 0.75)


def payload_scenarios(ident: Identification, spec: Spec) -> list[Scenario]:
    """The identified plant carrying interior payloads, both trajectories (6 runs).

    ``payload/<case>/<k>``: M = M_nominal (M_heavy / M_nominal)^k for k in
    :data:`PAYLOAD_STEPS` (geometric steps between the identified mass and the heaviest of
    the box, 1/theta_min[0]); everything else as identified (a payload adds mass only).
    Why: on a payload between the ends the theta1 estimate can drift the wrong way (towards
    a lighter axis, while theta2 falls to its bound) when its adaptation rate is high, and
    the ARC loses to the PID by 10-20x there (random axes 1 and 12 of
    :func:`commission.synth.random_axis`, Case 2, payload x2), while the corners (x1 and x4)
    are fine.  The validation's Monte-Carlo sample draws such plants; the box corners alone
    do not show the drift to the search.
    """
    base = identified_plant(ident, spec)
    qz = resolve_quantization(ident, spec)
    nz = resolve_encoder_noise(ident, spec)
    m0, m_heavy = base[P_M], 1.0 / ident.theta.min[0]
    out: list[Scenario] = []
    for case, tr in trajectories(spec):
        for k in PAYLOAD_STEPS:
            p = base.copy()
            p[P_M] = m0 * (m_heavy / m0) ** k if m_heavy > m0 else m0
            p = clip_to_box(p[None, :], ident)[0]
            out.append(Scenario(f"payload/{case}/{k:g}", p, tr, NO_DISTURBANCE, 0.0, (case, "payload", "tune"), qz, nz))
    return out


def screening_indices(scenarios: Sequence[Scenario]) -> list[int]:
    """Indices of ``validate``'s fixed and robustness scenarios in a tuning set (the search's screen).

    Everything but the tune-only stand-ins (box corners, largest-force and interior payload
    plants) and Monte-Carlo plants: the part of the tuning set that validate itself runs, on
    which a candidate far off the gate is already far off, so the search simulates the rest
    only for the others (:mod:`commission.tune.optimiser`).
    """
    extra = {"corner", "offset", "payload", "monte_carlo"}
    return [i for i, s in enumerate(scenarios) if not extra.intersection(s.tags)]


def tuning_scenarios(ident: Identification, spec: Spec, *, rng: np.random.Generator,
                     n_monte_carlo: int | None = None) -> list[Scenario]:
    """The set ``tune`` optimises on.

    Every fixed scenario of :func:`scenario_matrix` (tag ``"tune"``), the robustness scenarios
    of :func:`robustness_scenarios` (one more sample of delay, the mode's variants), the 16 box corners of
    :func:`corner_scenarios` (a deterministic stand-in for the validation's
    Monte-Carlo sample, whose worst plants sit near the corners), the 4
    largest-force plants of :func:`offset_scenarios`, the 6 interior payloads of
    :func:`payload_scenarios`, and ``spec.monte_carlo`` (or ``n_monte_carlo``)
    Monte-Carlo plants drawn from ``rng``.
    """
    n = spec.monte_carlo if n_monte_carlo is None else n_monte_carlo
    matrix = scenario_matrix(ident, spec, rng=rng, n_monte_carlo=n)
    fixed = [s for s in matrix if "tune" in s.tags or "robustness" in s.tags]
    mc = [s for s in matrix if "monte_carlo" in s.tags]
    return fixed + corner_scenarios(ident, spec) + offset_scenarios(ident, spec) + payload_scenarios(ident, spec) + mc
