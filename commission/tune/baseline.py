"""The PID baseline of eq. (57): poles placed at the spec's pole on the lightest mass of the
box, lowered (when defaulted) to the fastest pole whose command stays within validate's
chattering limit (:func:`deployable_pid`), so that the ARC is compared with a PID a user could
deploy; and the notes that say when the baseline chatters or was moved.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from typing import Sequence
from commission.artifacts import Identification
from commission.controllers.design import KIND_PID
from commission.controllers.pid import PidGains, pid_pack, pid_place_poles
from commission.spec import Spec
from commission.tuning import Score, Tuning
from commission.tune.defaults import default_gate_limits
from commission.tune.objective import Evaluator


#: A *defaulted* PID pole whose baseline exceeds validate's default c_u limit on the tuning
#: scenarios is lowered along ``pid_pole x PID_POLE_STEP**k``, k = 1 .. PID_POLE_STEPS (down to 0.54 x).
PID_POLE_STEP = 0.95


PID_POLE_STEPS = 12


def pid_baseline(ident: Identification, spec: Spec) -> tuple[PidGains, float]:
    """The paper's PID (57): poles of (56) at ``-spec.pid_pole`` for M_min = 1/theta_max[0].

    Feedforward M_hat, B_hat = the identified M, B; friction compensation = the
    identified one; output limit ``spec.u_max``.  Returns ``(gains, M_min)``.
    """
    m_min = 1.0 / ident.theta.max[0]
    Kp, Ki, Kd = pid_place_poles(m_min, -spec.pid_pole)
    return PidGains(Ts=spec.period, M_hat=ident.value("M"), B_hat=max(ident.value("B"), 0.0), Kp=Kp, Ki=Ki,
                    Kd=Kd, fric_level=ident.fric_level, fric_slope=ident.fric_slope, u_max=spec.u_max), m_min


@dataclass(frozen=True)
class PidBaseline:
    """The PID baseline of (57) as tune runs it (:func:`deployable_pid`).

    Attributes
    ----------
    gains : PidGains
    pole : float
        Triple closed-loop pole of (56), rad/s.
    design_mass : float
        M_min = 1/theta_max[0], u-unit s^2/m.
    scores : list of Score
        On the tuning scenarios, in the Evaluator's order.
    """

    gains: PidGains
    pole: float
    design_mass: float
    scores: list[Score]


def deployable_pid(ident: Identification, spec: Spec, ev: Evaluator, c_u_limit: float,
                   pole_free: bool) -> PidBaseline:
    """The paper's PID (57) at ``spec.pid_pole``, or at the fastest pole the gate's c_u allows.

    The baseline the ARC must beat should be one a user could deploy.  The default pole,
    0.12 f_s, carries the paper's -300 rad/s at 2.5 kHz to other rates; the PID's
    backward-difference derivative turns each encoder step q into a velocity step q f_s, so
    on a coarse encoder at a high rate that PID chatters beyond validate's c_u limit by
    itself (random axes 0 and 27 of :func:`commission.synth.random_axis`, 0.82-0.84 um at
    4 kHz: c_u 1.12 and 1.17 at 480 rad/s, limit 1).  When the pole was defaulted
    (``pole_free``) and that PID exceeds ``c_u_limit`` on a tuning scenario, the pole is
    lowered to the fastest of ``spec.pid_pole x PID_POLE_STEP**k`` (k = 1 ..
    :data:`PID_POLE_STEPS`) whose PID stays within it on every tuning scenario: the
    strongest PID of the paper's family that the gate's chattering limit accepts.  The
    candidates are simulated in one batch.  When none does, or the pole was set in the
    spec, the spec's pole is kept (``tune`` then warns when its gate fails).
    """
    pid, m_min = pid_baseline(ident, spec)
    scores = ev.scores(KIND_PID, [pid_pack(pid)])[0]

    def within(sc: Sequence[Score]) -> bool:
        return all(math.isfinite(s.c_u) and s.c_u <= c_u_limit and not s.diverged for s in sc)

    if not pole_free or within(scores):
        return PidBaseline(pid, spec.pid_pole, m_min, scores)
    poles = [spec.pid_pole * PID_POLE_STEP ** k for k in range(1, PID_POLE_STEPS + 1)]
    cands = [pid_baseline(ident, dataclasses.replace(spec, pid_pole=w))[0] for w in poles]
    for w, g, sc in zip(poles, cands, ev.scores(KIND_PID, [pid_pack(g) for g in cands])):
        if within(sc):
            return PidBaseline(g, w, m_min, sc)
    return PidBaseline(pid, spec.pid_pole, m_min, scores)


#: Largest factor the PID's pole is lowered by to hold the evidence bound (:func:`pid_within_evidence`).
EVIDENCE_POLE_FLOOR = 0.25
#: Pole step of that lowering.
EVIDENCE_POLE_STEP = 0.9


def pid_within_evidence(baseline: PidBaseline, ident: Identification, spec: Spec, ev: Evaluator,
                        pole_free: bool) -> PidBaseline:
    """The baseline, or the fastest PID of its family whose loop holds the evidence bound.

    A yardstick beyond the evidence certifies nothing (:mod:`commission.evidence`): when the pole
    was defaulted (``pole_free``) and the baseline's ``||W T||`` on the identified plant is 1 or
    more, its pole is lowered along ``pole x EVIDENCE_POLE_STEP**k`` down to
    ``EVIDENCE_POLE_FLOOR x pole`` to the first that holds it (checked on the linearised loop, no
    simulation), and that PID is simulated on the tuning scenarios.  When none holds, or the pole
    was set in the spec, the baseline is kept (validate's gate then names the evidence).
    """
    from commission.evidence import EvidenceBound

    bound = EvidenceBound(ident, spec)
    if not pole_free or not bound.evidence.applies or bound.pid_row(baseline.gains).holds:
        return baseline
    w = baseline.pole
    while w * EVIDENCE_POLE_STEP >= EVIDENCE_POLE_FLOOR * baseline.pole:
        w *= EVIDENCE_POLE_STEP
        g = pid_baseline(ident, dataclasses.replace(spec, pid_pole=w))[0]
        if bound.pid_row(g).holds:
            return PidBaseline(g, w, baseline.design_mass, ev.scores(KIND_PID, [pid_pack(g)])[0])
    return baseline


@dataclass(frozen=True)
class PidChatter:
    """Where the PID baseline exceeds the default gate's c_u on the tuning scenarios.

    Attributes
    ----------
    limit : float
        The gate's c_u limit.
    count : int
        Scenarios where the PID's c_u exceeds it.
    worst : float
        The PID's largest c_u.
    scenario : str
        Where it occurs.
    """

    limit: float
    count: int
    worst: float
    scenario: str


def pid_chatter(tuning: Tuning) -> PidChatter | None:
    """The PID baseline's c_u above the default gate's limit on the recorded tuning scores, or None.

    When the paper's PID, placed at M_min, already chatters beyond the limit, the encoder's
    step at this sample rate, not the ARC's tuning, sets the chattering floor.
    """
    limit = default_gate_limits(tuning.identification, tuning.spec).c_u
    over = [(row["pid"].c_u, name) for name, row in tuning.scores.items()
            if math.isfinite(row["pid"].c_u) and row["pid"].c_u > limit]
    if not over:
        return None
    worst, name = max(over)
    return PidChatter(limit=limit, count=len(over), worst=worst, scenario=name)


def pid_pole_note(tuning: Tuning) -> str | None:
    """One line for the user when the PID baseline runs below the spec's pole (:func:`deployable_pid`)."""
    if not tuning.pid_pole < tuning.spec.pid_pole:
        return None
    return (f"the PID baseline runs at pid.pole = {tuning.pid_pole:.3g} rad/s instead of the defaulted "
            f"{tuning.spec.pid_pole:.3g}: there it exceeds validate's default c_u limit on a tuning scenario "
            f"(encoder step {tuning.quantization * 1e6:.3g} um at {tuning.spec.sample_rate:g} Hz); "
            f"set pid.pole to compare with another PID")
