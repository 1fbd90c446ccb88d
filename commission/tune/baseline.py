"""The PID baseline of eq. (57): poles placed at the spec's pole on the lightest mass of the
box, lowered (when defaulted) to the fastest pole whose command stays within validate's
chattering limit (:func:`deployable_pid`), so that the ARC is compared with a PID a user could
deploy; and the notes that say when the baseline chatters or was moved.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from typing import Any, Callable, Mapping, Sequence

from commission.artifacts import Identification
from commission.controllers.design import KIND_PID
from commission.controllers.pid import PidGains, pid_pack, pid_place_poles
from commission.spec import Spec
from commission.scenarios.identified import plant_holds_fit
from commission.controllers.metrics import Indexes
from commission.tuning import Tuning, gains_to_dict
from commission.tune.defaults import default_gate_limits
from commission.tune.objective import Evaluator
from commission.tune.settings import DEFAULT_SETTINGS, TuneSettings


def pid_baseline(ident: Identification, spec: Spec) -> tuple[PidGains, float]:
    """The paper's PID (57): poles of (56) at ``-spec.pid_pole`` for M_min = 1/theta_max[0].

    Feedforward M_hat, B_hat = the identified M, B; friction compensation = the
    identified one; output limit ``spec.u_max``.  Returns ``(gains, M_min)``.
    """
    m_min = 1.0 / ident.theta.max[0]
    Kp, Ki, Kd = pid_place_poles(m_min, -spec.pid_pole)
    return PidGains(Ts=spec.period, M_hat=ident.value("M"), B_hat=max(ident.value("B"), 0.0), Kp=Kp, Ki=Ki,
                    Kd=Kd, fric_level=ident.fric_level, fric_slope=ident.fric_slope, u_max=spec.u_max), m_min


def _pid_at(ident: Identification, spec: Spec, pole: float) -> PidGains:
    """The PID of (57) at ``pole`` (rad/s) instead of ``spec.pid_pole``."""
    return pid_baseline(ident, dataclasses.replace(spec, pid_pole=float(pole)))[0]


def _within_c_u(scores: Sequence[Indexes], c_u_limit: float) -> bool:
    """Every run bounded and its c_u finite and at most ``c_u_limit``."""
    return all(math.isfinite(s.c_u) and s.c_u <= c_u_limit and not s.diverged for s in scores)


@dataclass(frozen=True)
class PidBaseline:
    """The PID baseline of (57) as tune runs it (:func:`deployable_pid`).

    Attributes
    ----------
    gains : PidGains
        The PID of (57) at ``pole``: Kp (u-unit/m), Ki, Kd and its friction compensation.
    pole : float
        Triple closed-loop pole of (56), rad/s.
    design_mass : float
        M_min = 1/theta_max[0], u-unit s^2/m.
    scores : list of Indexes
        On the tuning scenarios, in the Evaluator's order.
    """

    gains: PidGains
    pole: float
    design_mass: float
    scores: list[Indexes]


def deployable_pid(ident: Identification, spec: Spec, ev: Evaluator, c_u_limit: float,
                   pole_free: bool, settings: TuneSettings = DEFAULT_SETTINGS) -> PidBaseline:
    """The paper's PID (57) at ``spec.pid_pole``, or at the fastest pole the gate's c_u allows.

    The baseline the ARC must beat should be one a user could deploy.  The default pole,
    0.12 f_s, carries the paper's -300 rad/s at 2.5 kHz to other rates; the PID's
    backward-difference derivative turns each encoder step q into a velocity step q f_s, so
    on a coarse encoder at a high rate that PID chatters beyond validate's c_u limit by
    itself (docs/robustness.md, "Tune's defaults, measured").  When the pole was defaulted
    (``pole_free``) and that PID exceeds ``c_u_limit`` on a tuning scenario, the pole is
    lowered to the fastest of ``spec.pid_pole x settings.pid_pole_step**k`` (k = 1 ..
    ``settings.pid_pole_steps``) whose PID stays within it on every tuning scenario: the
    strongest PID of the paper's family that the gate's chattering limit accepts.  The
    candidates are simulated in one batch.  When none does, or the pole was set in the
    spec, the spec's pole is kept (``tune`` then warns when its gate fails).
    """
    pid, m_min = pid_baseline(ident, spec)
    scores = ev.scores(KIND_PID, [pid_pack(pid)])[0]
    if not pole_free or _within_c_u(scores, c_u_limit):
        return PidBaseline(pid, spec.pid_pole, m_min, scores)
    poles = [spec.pid_pole * settings.pid_pole_step ** k for k in range(1, settings.pid_pole_steps + 1)]
    cands = [_pid_at(ident, spec, w) for w in poles]
    for w, g, sc in zip(poles, cands, ev.scores(KIND_PID, [pid_pack(g) for g in cands])):
        if _within_c_u(sc, c_u_limit):
            return PidBaseline(g, w, m_min, sc)
    return PidBaseline(pid, spec.pid_pole, m_min, scores)


def pid_within_evidence(baseline: PidBaseline, ident: Identification, spec: Spec, ev: Evaluator,
                        pole_free: bool, settings: TuneSettings = DEFAULT_SETTINGS) -> PidBaseline:
    """The baseline, or the fastest PID of its family whose loop holds the evidence bound.

    A yardstick beyond the evidence certifies nothing (:mod:`commission.evidence`): when the pole
    was defaulted (``pole_free``) and the baseline's ``||W T||`` on the identified plant is 1 or
    more, its pole is lowered along ``pole x settings.evidence_pole_step**k`` down to
    ``settings.evidence_pole_floor x pole`` to the first that holds it (checked on the linearised loop, no
    simulation), and that PID is simulated on the tuning scenarios.  When none holds, or the pole
    was set in the spec, the baseline is kept (validate's gate then names the evidence).
    """
    from commission.evidence import EvidenceBound

    bound = EvidenceBound(ident, spec)
    if not pole_free or not bound.evidence.applies or bound.pid_row(baseline.gains).holds:
        return baseline
    w = baseline.pole
    while w * settings.evidence_pole_step >= settings.evidence_pole_floor * baseline.pole:
        w *= settings.evidence_pole_step
        g = _pid_at(ident, spec, w)
        if bound.pid_row(g).holds:
            return PidBaseline(g, w, baseline.design_mass, ev.scores(KIND_PID, [pid_pack(g)])[0])
    return baseline


@dataclass(frozen=True)
class PidChatter:
    """Where the PID baseline exceeds the default gate's c_u on the tuning scenarios.

    ``tune`` warns with it when its gains still fail the gate on the hold-out plants: if the
    paper's PID itself chatters beyond the limit, the encoder's step at this sample rate, not
    the ARC's tuning, sets the chattering floor.

    Attributes
    ----------
    limit : float
        The gate's c_u limit (du_rms / u_rms, dimensionless).
    count : int
        Scenarios where the PID's c_u exceeds it.
    worst : float
        The PID's largest c_u, dimensionless.
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
    """One line for the user when the PID baseline runs away from the spec's pole.

    Either the yardstick search (:func:`pid_yardstick`, recorded in ``tuning.pid_yardstick``)
    chose it, or a defaulted pole chattered (:func:`deployable_pid`, tunings without the record).
    """
    ys = tuning.pid_yardstick
    if ys is not None and ys.get("method") == "margin_search":
        m = ys.get("margins", {})
        xo = m.get("crossover_hz")
        return (f"the PID yardstick is the fastest PID of (57) that keeps the margin floors on the identified "
                f"plant and is stable with one more sample of delay: pid.pole = {tuning.pid_pole:.3g} rad/s"
                f"{f' (crossover {xo:.3g} Hz)' if xo is not None else ''}, "
                f"{ys.get('admissible')} of {ys.get('candidates')} poles admissible "
                f"(the paper's formula at the defaulted {tuning.spec.pid_pole:.3g} rad/s: set pid.pole)")
    if ys is not None and not ys.get("is_yardstick", True):
        return (f"the PID baseline at pid.pole = {tuning.pid_pole:.3g} rad/s misses the margin floors on the "
                f"identified plant ({'; '.join(ys.get('violations', []))}): it is not a fair yardstick")
    if not tuning.pid_pole < tuning.spec.pid_pole:
        return None
    return (f"the PID baseline runs at pid.pole = {tuning.pid_pole:.3g} rad/s instead of the defaulted "
            f"{tuning.spec.pid_pole:.3g}: there it exceeds validate's default c_u limit on a tuning scenario "
            f"(encoder step {tuning.quantization * 1e6:.3g} um at {tuning.spec.sample_rate:g} Hz); "
            f"set pid.pole to compare with another PID")


# --------------------------------------------------------------------------- the PID yardstick

@dataclass(frozen=True)
class PidCandidate:
    """One PID of the yardstick's family, checked on the identified plant.

    Attributes
    ----------
    pole : float
        Triple closed-loop pole of (56) at M_min, rad/s.
    margins : Margins
        On the identified plant (mode and delay included).
    radius_plus_one : float
        Spectral radius of the same loop with one more sample of input delay (< 1: stable).
    violations : tuple of str
        The margin floors it misses (and ``"unstable with +1 sample"``); empty: admissible.
    """

    pole: float
    margins: Any
    radius_plus_one: float
    violations: tuple[str, ...]

    @property
    def admissible(self) -> bool:
        return not self.violations


@dataclass(frozen=True)
class YardstickChoice:
    """How the PID the ARC is judged against was chosen (tuning.json ``pid_yardstick``).

    Attributes
    ----------
    method : str
        ``"margin_search"`` (the fastest PID of the family that keeps the floors on the identified
        plant, is stable with one more sample of delay and stays within the gate's c_u),
        ``"spec_pole"`` (``[pid] pole`` given in the spec: the paper's formula (57) at that pole,
        today's behaviour) or ``"none_admissible"`` (no pole of the family keeps the floors: the
        paper's pole, lowered for chattering as before and into the evidence where it can be, is
        kept and flagged).
    pole : float
        The chosen pole, rad/s.
    candidates : int
        Poles checked on the identified plant.
    admissible : int
        Of them, those that keep every floor and are stable with +1 sample.
    simulated : int
        Candidates simulated on the tuning scenarios (c_u check).
    margins : Margins
        The chosen PID's margins on the identified plant.
    radius_plus_one : float
        Its closed-loop spectral radius with one more sample of delay.
    violations : tuple of str
        The floors the chosen PID misses (empty for ``margin_search``).
    fastest_admissible : float or None
        For ``margin_search``, the fastest pole that keeps the floors, rad/s: the bandwidth the
        plant allows a PID of (57).  The chosen pole sits below it when the gate's c_u (the
        encoder's noise in the command) held the PID down.  None for the other methods and in
        records written before it was kept.
    unbacked : (float, PidGains) or None
        Where only the evidence bound held the yardstick down (:func:`unbacked_pid`): the pole
        (rad/s) and gains of the fastest PID the identified plant admits (floors, +1 sample, c_u)
        that the log does not back.  Validate's gate holds the ARC to beat it on the identified
        plant too (:func:`commission.gate.arc_vs_pid_nominal_checks`): a drive's auto-tuner does
        not stop at the band the log backs.  None otherwise and in older records.
    """

    method: str
    pole: float
    candidates: int
    admissible: int
    simulated: int
    margins: Any
    radius_plus_one: float
    violations: tuple[str, ...] = ()
    fastest_admissible: float | None = None
    unbacked: tuple[float, PidGains] | None = None

    @property
    def is_yardstick(self) -> bool:
        """The chosen PID keeps the floors and is stable with one more sample of delay."""
        return not self.violations

    def to_dict(self) -> dict[str, Any]:
        return {"method": self.method, "pole": self.pole, "candidates": self.candidates,
                "admissible": self.admissible, "simulated": self.simulated,
                "margins": self.margins.to_dict(), "radius_plus_one_sample": float(self.radius_plus_one),
                "violations": list(self.violations), "is_yardstick": self.is_yardstick,
                **({} if self.fastest_admissible is None
                   else {"fastest_admissible_pole": float(self.fastest_admissible)}),
                **({} if self.unbacked is None
                   else {"unbacked_pid": {"pole": float(self.unbacked[0]), "gains": gains_to_dict(self.unbacked[1])}})}

    @classmethod
    def from_dict(cls, d: Mapping[str, Any]) -> "YardstickChoice":
        from commission.robustness import LoopMargins
        m = LoopMargins.from_dict({"plant": "nominal", "controller": "pid", **d["margins"]}).margins
        return cls(method=str(d["method"]), pole=float(d["pole"]), candidates=int(d["candidates"]),
                   admissible=int(d["admissible"]), simulated=int(d["simulated"]), margins=m,
                   radius_plus_one=float(d["radius_plus_one_sample"]),
                   violations=tuple(str(v) for v in d.get("violations", ())),
                   fastest_admissible=(None if d.get("fastest_admissible_pole") is None
                                       else float(d["fastest_admissible_pole"])),
                   unbacked=(None if d.get("unbacked_pid") is None
                             else (float(d["unbacked_pid"]["pole"]), pid_gains_of(d["unbacked_pid"]["gains"]))))


def pid_gains_of(d: Mapping[str, Any]) -> PidGains:
    """PidGains from :func:`commission.tuning.gains_to_dict`'s record (null: infinite); every field required."""
    return PidGains(**{f.name: (math.inf if d[f.name] is None else float(d[f.name])) for f in dataclasses.fields(PidGains)})


def bandwidth_factor(choice: YardstickChoice, spec: Spec, settings: TuneSettings = DEFAULT_SETTINGS) -> float:
    """How far below the rate-scaled design this axis' yardstick sits (1: not below), dimensionless.

    The ARC's carried-over gains (:func:`commission.tune.gains.base_arc_gains`) and its default
    observer pole scale with the sample rate, as the paper's PID pole does.  When no PID of the
    rate-scaled grid (``settings.yardstick_pole_fractions``) keeps the floors and a slower one
    below it does (``settings.yardstick_low_fractions``), the axis' bandwidth is set by its
    plant (a heavy load, a low structural mode), and the ARC's gains, adaptation rates and
    observer are scaled by the same factor: the fastest pole that keeps the floors over the
    grid's lowest.  A PID held further down by the gate's c_u does not scale the ARC: the
    encoder's noise limits a PID of (57), whose gains all grow with its pole, not the plant's
    bandwidth, and the ARC's search holds its own gains to the same c_u.  Otherwise (the floors
    admit a pole of the grid, a ``[pid] pole`` given, none admissible) 1.
    """
    low = settings.yardstick_pole_fractions[0] * spec.sample_rate
    floors = choice.pole if choice.fastest_admissible is None else choice.fastest_admissible
    if choice.method != "margin_search" or not choice.is_yardstick or floors >= low:
        return 1.0
    return floors / low


def noise_bandwidth_factor(choice: YardstickChoice, spec: Spec,
                           settings: TuneSettings = DEFAULT_SETTINGS) -> float | None:
    """The factor of a yardstick the gate's c_u held below the grid and below the floors' pole, or None.

    When the encoder's noise, not the floors, holds the PID yardstick down (its pole below
    :attr:`YardstickChoice.fastest_admissible` and below the rate-scaled grid), the ARC's design
    stays at the floors' bandwidth (:func:`bandwidth_factor`); this factor -- the yardstick's pole
    over the grid's lowest -- is where the ARC's search goes only when no gains at the floors'
    bandwidth are feasible (:func:`commission.tune.api.tune_from`): the noise then limits the ARC
    as it limited the PID.  None when the yardstick is not noise-held below the grid.
    """
    low = settings.yardstick_pole_fractions[0] * spec.sample_rate
    if (choice.method != "margin_search" or not choice.is_yardstick or choice.fastest_admissible is None
            or not choice.pole < min(low, choice.fastest_admissible)):
        return None
    return choice.pole / low


def pid_candidates(ident: Identification, spec: Spec, poles: Sequence[float]) -> list[PidCandidate]:
    """Check the PID of (57) at each pole on the identified plant and with one more sample of delay.

    The plant is :func:`commission.scenarios.identified_plant` (the identified mode and delay
    included), the floors the spec's ``[margins]`` (:class:`commission.robustness.MarginFloors`):
    the same loop and the same floors the ARC is held to.  Linear checks only (no simulation).
    """
    from commission.infra.blas import one_blas_thread
    from commission.controllers.linear import sampled_plant
    from commission.controllers.margins import closed_loop_radius, frequency_grid, linearize_pid, loop_margins
    from commission.robustness import MarginFloors, floor_violations
    from commission.scenarios import identified_plant

    floors = MarginFloors.from_spec(spec)
    p = identified_plant(ident, spec)
    out = []
    with one_blas_thread():
        sp = sampled_plant(p, spec.period)
        sp1 = sampled_plant(p, spec.period, extra_delay=1.0)
        f = frequency_grid(spec.period)
        resp = sp.frequency_response(f)
        for w in poles:
            lin = linearize_pid(pid_pack(_pid_at(ident, spec, w)))
            m = loop_margins(lin, sp, f, resp)
            r1 = closed_loop_radius(lin, sp1)
            v = floor_violations(m, floors)
            if not r1 < 1.0:
                v.append(f"unstable with one more sample of delay (spectral radius {r1:.4f})")
            out.append(PidCandidate(float(w), m, r1, tuple(v)))
    return out


def _within_evidence(cands: list[PidCandidate], ident: Identification, spec: Spec) -> list[PidCandidate]:
    """``cands`` with the evidence bound as one more admissibility test (:mod:`commission.evidence`).

    Where the log backs the model only up to a band (the evidence applies), a PID whose loop has
    ``||W T|| >= 1`` reaches beyond it and certifies nothing: it gets the violation ``"beyond the
    evidence ..."``, so that :func:`pid_yardstick` never records a yardstick that
    :func:`pid_within_evidence` would then lower (tuning.json's ``pid_yardstick`` is the final PID).
    """
    from commission.evidence import EvidenceBound

    bound = EvidenceBound(ident, spec)
    if not bound.evidence.applies:
        return cands
    out = []
    for c in cands:
        if c.admissible:
            row = bound.pid_row(_pid_at(ident, spec, c.pole))
            if not row.holds:
                c = dataclasses.replace(c, violations=c.violations + (
                    f"beyond the evidence (peak ||W T|| {row.peak:.3g} >= 1)",))
        out.append(c)
    return out


def pid_yardstick(ident: Identification, spec: Spec, ev: Evaluator, c_u_limit: float,
                  pole_free: bool, settings: TuneSettings = DEFAULT_SETTINGS) -> tuple[PidBaseline, YardstickChoice]:
    """The PID the ARC is judged against: the best PID of (57) under the ARC's own margin floors.

    A drive vendor's auto-tuner delivers the fastest PID that keeps its margins on the
    identified plant; that, not a fixed pole, is what the ARC has to beat.  The family is the
    paper's (57) with the triple pole of (56) at M_min, its pole swept over
    ``settings.yardstick_pole_fractions`` x f_s, and below it (``settings.yardstick_low_fractions``)
    when none of those keeps the floors on the identified plant (the plant sets the bandwidth; not
    when only the evidence bound excludes them, a PID slowed to the log's band being no measure of
    the machine's, nor when that plant dropped modes of the fit,
    :func:`commission.scenarios.identified.plant_holds_fit`).  A pole is admissible when the PID
    keeps every floor of the spec's ``[margins]`` on the identified plant (mode and delay included) and the loop
    is stable with one more sample of delay (:func:`pid_candidates`) and, where the log backs the
    model only up to a band, holds the evidence bound ``||W T|| < 1`` (:func:`_within_evidence`,
    the test :func:`pid_within_evidence` applies after the choice, so the two agree); a PID that
    is unstable on the identified model or with +1 sample is never the yardstick.  Of the admissible poles the
    fastest (the largest bandwidth) whose simulated PID stays within ``c_u_limit`` and bounded on
    every tuning scenario is chosen (up to ``settings.yardstick_batches`` batches of
    ``settings.yardstick_batch``, simulated together).  When none of those does, the PID is held to
    the ARC's own c_u all the same -- a chattering PID is no controller a user could deploy, and
    an ARC refused for losing to one is refused for nothing -- so the fastest admissible pole within
    it is bisected among the slower ones, on the grid and below it (``yardstick_low_fractions``,
    :func:`_fastest_within_c_u`); only when none is found there, the slowest of the first ones.

    With ``pole_free`` False (``[pid] pole`` given) the paper's PID at that pole is kept (today's
    behaviour, eq. (57)) and its margins are recorded; when no pole is admissible the previous
    default (:func:`deployable_pid`), lowered into the evidence where it can be
    (:func:`pid_within_evidence`), is kept and checked as the grid is, the evidence bound included.
    Either way the choice says whether the PID is a yardstick (:attr:`YardstickChoice.is_yardstick`);
    validate holds the ARC to no PID that is not one (:func:`commission.gate.comparison_reported`).
    """
    if not pole_free:
        base = deployable_pid(ident, spec, ev, c_u_limit, False, settings)
        c = pid_candidates(ident, spec, [base.pole])[0]
        return base, YardstickChoice("spec_pole", base.pole, 1, int(c.admissible), 1, c.margins,
                                     c.radius_plus_one, c.violations)
    poles = [fr * spec.sample_rate for fr in settings.yardstick_pole_fractions]
    on_model = pid_candidates(ident, spec, poles)
    cands = _within_evidence(on_model, ident, spec)
    ok = sorted((c for c in cands if c.admissible), key=lambda c: -c.pole)
    if not ok and not any(c.admissible for c in on_model) and plant_holds_fit(ident, spec):
        # The identified plant itself, not the evidence, rules out every pole of the grid: the plant, not
        # the rate, sets this axis' bandwidth, so the grid is continued below.  Where the model admits a
        # pole of the grid and only the evidence bound excludes it, a slower PID would be a yardstick of
        # the log's band, not of the machine (whose own PID may run faster than the log can back): the
        # grid stops there, and the remedy is a log that backs a higher band (``commission excite``).
        # Nor where the simulator's plant dropped modes of the fit: its missed floors may be that
        # plant's, not the machine's, and a yardstick slowed to them would be as weak.
        low = [fr * spec.sample_rate for fr in settings.yardstick_low_fractions]
        cands = cands + _within_evidence(pid_candidates(ident, spec, low), ident, spec)
        ok = sorted((c for c in cands if c.admissible), key=lambda c: -c.pole)
    if not ok:
        # The fallback is checked as its candidates were (floors, +1 sample, and the evidence bound after
        # pid_within_evidence has lowered it), so that the record never calls a PID beyond the evidence a
        # yardstick.
        base = deployable_pid(ident, spec, ev, c_u_limit, True, settings)
        base = pid_within_evidence(base, ident, spec, ev, True, settings)
        c = _within_evidence(pid_candidates(ident, spec, [base.pole]), ident, spec)[0]
        return base, YardstickChoice("none_admissible", base.pole, len(cands), 0, 1, c.margins,
                                     c.radius_plus_one, c.violations)
    m_min = 1.0 / ident.theta.max[0]
    simulated = 0
    tried: list[tuple[PidCandidate, PidGains, list[Indexes]]] = []
    n = settings.yardstick_batch
    for b in range(settings.yardstick_batches):
        batch = ok[b * n:(b + 1) * n]
        if not batch:
            break
        gains = [_pid_at(ident, spec, c.pole) for c in batch]
        scores = ev.scores(KIND_PID, [pid_pack(g) for g in gains])
        simulated += len(batch)
        for c, g, sc in zip(batch, gains, scores):
            tried.append((c, g, list(sc)))
            if _within_c_u(sc, c_u_limit):
                ub = unbacked_pid(on_model, c.pole, ok[0].pole, ident, spec, ev, c_u_limit)
                return (PidBaseline(g, c.pole, m_min, list(sc)),
                        YardstickChoice("margin_search", c.pole, len(cands), len(ok), simulated, c.margins,
                                        c.radius_plus_one, fastest_admissible=ok[0].pole, unbacked=ub))
    # None of the fastest is within c_u: a chattering PID is no yardstick, the ARC being held to the same
    # c_u.  The fastest admissible pole within it is looked for further down, on the grid and below it.
    slowest = min(c.pole for c in ok)
    below = [fr * spec.sample_rate for fr in settings.yardstick_low_fractions if fr * spec.sample_rate < slowest]
    low_ok = sorted((c for c in _within_evidence(pid_candidates(ident, spec, below), ident, spec) if c.admissible),
                    key=lambda c: -c.pole)
    pool = ok[len(tried):] + low_ok
    hit = _fastest_within_c_u(pool, lambda c: ev.scores(KIND_PID, [pid_pack(_pid_at(ident, spec, c.pole))])[0],
                              c_u_limit)
    simulated += hit.simulated
    if hit.index is not None:
        c = pool[hit.index]
        ub = unbacked_pid(on_model, c.pole, ok[0].pole, ident, spec, ev, c_u_limit)
        return (PidBaseline(_pid_at(ident, spec, c.pole), c.pole, m_min, hit.scores),
                YardstickChoice("margin_search", c.pole, len(cands) + len(below), len(ok) + len(low_ok), simulated,
                                c.margins, c.radius_plus_one, fastest_admissible=ok[0].pole, unbacked=ub))
    c, g, sc = tried[-1]
    return (PidBaseline(g, c.pole, m_min, sc),
            YardstickChoice("margin_search", c.pole, len(cands), len(ok), simulated, c.margins, c.radius_plus_one,
                            fastest_admissible=ok[0].pole))


def unbacked_pid(on_model: Sequence[PidCandidate], chosen: float, fastest_backed: float, ident: Identification,
                 spec: Spec, ev: Evaluator, c_u_limit: float) -> tuple[float, PidGains] | None:
    """The fastest PID the identified plant admits beyond the evidence, where only the evidence held the yardstick.

    When the yardstick is the fastest pole that holds the evidence bound (``chosen ==
    fastest_backed``: neither the floors nor the c_u held it lower) and faster poles keep every
    floor on the identified plant and +1 sample (``on_model``, :func:`pid_candidates`), only the
    band the log backs excluded them.  A drive vendor's auto-tuner knows nothing of that band: it
    would deliver one of those faster PIDs, and an ARC held within the evidence that loses to it
    is no better than what the user already has.  Of those poles the fastest whose simulated PID
    stays within ``c_u_limit`` and bounded on every tuning scenario is returned with its gains
    (:func:`_fastest_within_c_u`), None when there is none or the yardstick was not held by the
    evidence.
    """
    if chosen < fastest_backed:
        return None
    faster = sorted((c for c in on_model if c.admissible and c.pole > chosen), key=lambda c: -c.pole)
    if not faster:
        return None
    hit = _fastest_within_c_u(faster, lambda c: ev.scores(KIND_PID, [pid_pack(_pid_at(ident, spec, c.pole))])[0],
                              c_u_limit)
    if hit.index is None:
        return None
    pole = faster[hit.index].pole
    return float(pole), _pid_at(ident, spec, pole)


@dataclass(frozen=True)
class _CuHit:
    index: int | None
    scores: list
    simulated: int


def _fastest_within_c_u(pool: Sequence[PidCandidate], simulate: Callable[[PidCandidate], Sequence[Indexes]],
                        c_u_limit: float) -> _CuHit:
    """The fastest of ``pool`` (ordered fastest first) whose simulated PID is within ``c_u_limit``.

    The PID of (57) amplifies the encoder's noise into the command in proportion to its gains, so
    its c_u falls as its pole does, while a pole slow enough loses the trajectory (a run that
    diverges or leaves the travel).  The boundary between the poles that chatter and those that do
    not is bisected, a handful of simulations for a pool of dozens, and the first pole past it is
    taken when it is also bounded; otherwise none (no index).  Where c_u is not monotone in the
    pole, the pole taken is past a boundary of the bisection, not necessarily the fastest within.
    """
    n = 0
    memo: dict[int, list] = {}

    def run(i: int) -> list:
        nonlocal n
        if i not in memo:
            memo[i] = list(simulate(pool[i]))
            n += 1
        return memo[i]

    def chatters(i: int) -> bool:
        sc = run(i)
        return all(not s.diverged and math.isfinite(s.c_u) for s in sc) and not _within_c_u(sc, c_u_limit)

    lo, hi = -1, len(pool)  # every index <= lo chatters (the simulated ones, or taken to); hi: not known to
    while hi - lo > 1:
        mid = (lo + hi) // 2
        if chatters(mid):
            lo = mid
        else:
            hi = mid
    if hi < len(pool) and _within_c_u(run(hi), c_u_limit):
        return _CuHit(hi, memo[hi], n)
    return _CuHit(None, [], n)
