"""The desired trajectories of the scenarios: Case 1 and Case 2 of the paper scaled to the
spec's reference envelope, and the machine's own moves (``user``); their horizons within the
sample cap (:data:`commission.spec.MAX_TRAJECTORY_SAMPLES`) and the refusals of runs too long.

Scaling (paper: travel 0.4 m, v_max 1 m/s, a_max 12 m/s^2): see :mod:`commission.scenarios`.
"""

from __future__ import annotations

import math

from commission.controllers import trajectory as _traj
from commission.errors import SpecError
from commission.scenarios.scenario import TrajectorySpec
from commission.spec import MAX_TRAJECTORY_SAMPLES, Spec, check_trajectory_samples

#: Rest after the last Case-2 move, s (the paper: 8 s - 5.9 s).
CASE2_TAIL = 2.1
#: Case-1 minimum duration, s (paper: 10 s).
CASE1_DURATION = 10.0

#: Case 1's peak reference speed A omega as a fraction of v_max (0.2 m/s of the paper's 1 m/s).
#: Filter (58) starts at rest, so q_dd(0) = beta1 A omega: 20 m/s^2 for the paper, above its a_max.
CASE1_SPEED_FRACTION = 0.2
#: The paper's two trajectories, on every axis (``"user"`` joins them with the machine's moves).
CASES = ("case1", "case2")


def max_horizon(sample_rate: float) -> float:
    """The longest run, s, whose samples at ``sample_rate`` Hz stay within the cap
    :data:`commission.spec.MAX_TRAJECTORY_SAMPLES` (rounded down to the millisecond)."""
    return math.floor(MAX_TRAJECTORY_SAMPLES / sample_rate * 1000.0) / 1000.0


def _case1_full_duration(spec: Spec) -> tuple[float, float, float]:
    A = spec.travel / 8.0
    omega = min(CASE1_SPEED_FRACTION * spec.case_v_max / A, math.sqrt(spec.case_a_max / (15.0 * A)))
    return A, omega, max(CASE1_DURATION, 4.0 * 2.0 * math.pi / omega)


def case1_trajectory(spec: Spec) -> TrajectorySpec:
    """Case 1 scaled to the envelope (:mod:`commission.scenarios`); the paper's 0.05 sin(4t), 10 s by default.

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

