"""Judge what ``commission run`` emits on the TRUE axis (issue 30, "yield").

The gate predicts on the identified model; this module measures what happens on the
machine.  For a simulated axis whose truth is known (:class:`commission.synth.AxisTruth`:
its modes, delay, encoder noise and rail), :func:`judge_axis` runs the product's default
pipeline on the axis's log (:func:`commission.pipeline.run_all`, as ``commission run``
does), then simulates what was **emitted** -- controller.json's gains through the
runtime's own step (:func:`commission.controllers.arc.arc_pack`, the kernel the runtime,
validate and the generated code share) -- on the true plant, in validate's default
trajectories (Case 1 and Case 2 of the tuned spec), nominal and with one more sample of
input delay, against a PID calibrated on the true plant (:func:`true_pid`).

The counts (:class:`Judgement`):

* **works**: emitted, and on all four runs (two cases x nominal/+1 sample) the ARC does
  not diverge, keeps ``c_u <= 1`` and has a smaller e_rms than the true-plant PID in the
  same run;
* **false certification**: emitted, and does not work;
* **false refusal**: refused, although a candidate of the tool's own search works on the
  true plant.  tuning.json keeps every candidate's objective but not its gains, so the
  candidate judged is the one the search chose: the tuned gains with the runtime guards,
  exactly what validate simulated (:attr:`commission.validate.ValidationResult.arc_gains`),
  forced through.  A refusal before tuning (an exit-2 error) leaves no candidate: it is
  counted apart (:attr:`Judgement.candidate` is False), never as a false refusal.

The yardstick, :func:`true_pid`: the paper's PID (57), its three poles placed at ``-w`` for
the TRUE mass, ``w`` walked down from ``0.3 f_s`` by factors of 0.9; the first (fastest)
``w`` whose linearised loop on the TRUE
sampled plant (modes and delay, :func:`commission.controllers.margins.loop_margins`) keeps
validate's default margin floors (:class:`commission.robustness.MarginFloors`: 6 dB, 30
deg, one sample of delay, modulus 0.5) and whose simulation on the four runs neither
diverges nor exceeds ``c_u = 1``.  Within the family, e_rms falls as ``w`` rises, so the
fastest such PID is the best one a drive vendor's auto-tuner could deliver under the same
floors.  Its feedback is calibrated with a knowledge of the plant the tool never has (true
mass, modes, delay): a demanding yardstick, as intended.  Its feedforward (mass, viscous and
friction compensation of (57)) is what the tool identified from the log
(:class:`Feedforward`, from ident.json: what any auto-tuner given this log would use), so
the ARC is measured against the feedback a PID could have, not against a model the log
cannot give; without an identification (:func:`judge_gains` called alone) it is the
truth's.

When the tool refuses before tuning (an exit-2 error), the yardstick is still computed, on
the default spec at the axis's rate and rail, to say whether a working controller existed.

Why a verdict missed, :class:`ToolYardstick`: the PID the *tool* held the ARC to
(tuning.json's ``pid``, chosen on the identified model) is run on the true plant too -- the
same floors, the same four runs.  A false refusal whose tool yardstick misses the floors on the
true plant was refused against a PID the machine could not run (the identified model flattered
it); one whose tool yardstick runs as well as the true-plant PID was refused by the gate's
robustness checks, not by its comparison.  It is a diagnosis only: the counts do not read it.

Each run draws the encoder's noise once, as one run on the machine would.  Where a loop's error
is a limit cycle of friction and quantisation, its e_rms changes from draw to draw by more than
two controllers differ, so :func:`draws_ratio` (asked with ``noise_draws``) compares the median
e_rms over several draws: a second diagnosis, not read by the counts either.
"""

from __future__ import annotations

import math
import os
import tempfile
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from commission.controllers.arc import ArcGains, arc_pack
from commission.controllers.linear import sampled_plant
from commission.controllers.margins import linearize_pid, loop_margins
from commission.controllers.pid import PidGains, pid_pack, pid_place_poles
from commission.controllers.plant import P_DELAY
from commission.controllers.simulate import KIND_ARC, KIND_PID, simulate
from commission.robustness import MarginFloors, floor_violations
from commission.scenarios import case1_trajectory, case2_trajectory, plant_substeps
from commission.spec import Spec
from commission.synth import AxisTruth

if TYPE_CHECKING:
    from commission.identification import IdentifyOptions

#: Extra input delays of the true-plant runs, samples: as logged, and one more (a drive that
#: applies each command a sample late).
EXTRA_DELAYS = (0.0, 1.0)
#: Fastest pole of the true-plant PID's walk, as a fraction of the sample rate (rad/s per Hz).
PID_POLE_START = 0.3
#: Ratio between successive poles of the walk, and its length.
PID_POLE_STEP = 0.9
PID_POLE_STEPS = 60
#: Friction-compensation slope of the true-plant PID, s/m (the paper's (57)).
PID_FRICTION_SLOPE = 900.0
#: Encoder-noise draws of the noise-averaged comparison (:func:`draws_ratio`), the judged one included.
NOISE_DRAWS = 5


@dataclass(frozen=True)
class TrueRun:
    """One simulation on the true plant.

    Only the numbers the judgement reads (:attr:`ok`, and e_rms against the true-plant PID's in
    the same run) are kept, not the traces: an axis is judged on many runs.

    Attributes
    ----------
    case : str
        Validate's default trajectory it ran: ``"case1"`` or ``"case2"``.
    extra_delay : float
        Input delay added to the true plant's, samples.
    diverged : bool
        The run aborted (tracking error beyond the spec's travel, or non-finite).
    e_rms : float
        RMS tracking error, m (NaN when diverged).
    c_u : float
        Chattering index du_rms / u_rms, dimensionless (NaN when diverged).
    stopped : float
        When the command went to exactly 0 for good, s, if it did so before the run's last
        half (the runtime's guards latched a fault: the safe command 0 until a reset; the
        axis then stands while the reference moves); NaN otherwise.
    """

    case: str
    extra_delay: float
    diverged: bool
    e_rms: float
    c_u: float
    stopped: float = math.nan

    @property
    def ok(self) -> bool:
        """Did not diverge, did not stop on a fault, and ``c_u <= 1``."""
        return ((not self.diverged) and math.isnan(self.stopped) and math.isfinite(self.c_u)
                and self.c_u <= 1.0)


@dataclass(frozen=True)
class TruePid:
    """The true-plant yardstick (:func:`true_pid`).

    Attributes
    ----------
    gains : PidGains or None
        None when no pole of the walk met the floors and the runs.
    pole : float
        Triple pole magnitude ``w``, rad/s (NaN without gains).
    runs : tuple of TrueRun
        Its four runs, in :func:`true_runs` order.
    """

    gains: PidGains | None
    pole: float
    runs: tuple[TrueRun, ...] = ()


def worst_ratio(runs: Sequence[TrueRun], ref: Sequence[TrueRun]) -> float:
    """Worst e_rms of ``runs`` over ``ref``'s, run by run: NaN without both, inf where one of ``runs`` diverged."""
    if not runs or not ref:
        return math.nan
    return max((math.inf if a.diverged else a.e_rms / p.e_rms) for a, p in zip(runs, ref))


def runs_beat(runs: Sequence[TrueRun], ref: Sequence[TrueRun]) -> bool:
    """Every run of ``runs`` is ok (no divergence, ``c_u <= 1``, no fault) and below ``ref``'s e_rms, run by run
    (the definition of "works" against a PID, :attr:`Judgement.arc_works`)."""
    return bool(runs) and all(a.ok and a.e_rms < p.e_rms for a, p in zip(runs, ref))


@dataclass(frozen=True)
class ToolYardstick:
    """The tool's own PID yardstick (tuning.json's ``pid``) on the true plant (module docstring).

    Attributes
    ----------
    pole : float
        Its triple pole, rad/s (tuning.json's ``pid_pole``).
    violations : tuple of str
        Validate's default margin floors it misses on the TRUE sampled plant (empty: none).
    runs : tuple of TrueRun
        Its four runs on the true plant, in :func:`true_runs` order.
    """

    pole: float
    violations: tuple[str, ...]
    runs: tuple[TrueRun, ...]

    @property
    def ok(self) -> bool:
        """Keeps the floors on the true plant and its four runs are :attr:`TrueRun.ok`."""
        return not self.violations and all(r.ok for r in self.runs)

    def ratio_to(self, pid: TruePid) -> float:
        """Worst e_rms of this PID over the true-plant PID's, run by run (NaN without the latter;
        inf when this one diverged)."""
        return worst_ratio(self.runs, pid.runs)

    def describe(self, pid: TruePid) -> str:
        """One line: ``"tool PID 68 rad/s on the true plant: misses the floors (unstable (...)); e_rms x1.90 of
        the true-plant PID's"``."""
        if self.violations:
            how = "misses the floors (" + self.violations[0] + ")"
        elif any(r.diverged for r in self.runs):
            how = "keeps the floors, diverges"
        elif not all(r.ok for r in self.runs):
            how = f"keeps the floors, c_u {max(r.c_u for r in self.runs):.2f} or a fault"
        else:
            how = "keeps the floors"
        than = (f"e_rms x{self.ratio_to(pid):.2f} of the true-plant PID's" if pid.runs else
                "no true-plant PID keeps the floors to compare with")
        return f"tool PID {self.pole:.0f} rad/s on the true plant: {how}; {than}"


def tool_yardstick(truth: AxisTruth, pid: PidGains, pole: float, spec: Spec, *, trajectories=None,
                   noise_seed: int = 0, floors: MarginFloors | None = None) -> ToolYardstick:
    """The tool's PID yardstick ``pid`` (pole ``pole`` rad/s) judged on the true plant: floors and runs."""
    floors = MarginFloors() if floors is None else floors
    plant = sampled_plant(truth.plant(), truth.period)
    v = floor_violations(loop_margins(linearize_pid(pid_pack(pid)), plant), floors)
    runs = true_runs(truth, KIND_PID, pid_pack(pid), spec, trajectories=trajectories, noise_seed=noise_seed)
    return ToolYardstick(float(pole), tuple(v), runs)


@dataclass(frozen=True)
class Judgement:
    """What the tool did on one axis, judged on the true plant.

    Attributes
    ----------
    emitted : bool
        controller.json was written (the gate passed).
    verdict : str
        ``"emitted"``, ``"refused: <first gate failure>"`` or ``"error: <exit-2 message>"``.
    candidate : bool
        There were gains to judge (emitted, or tuned and refused by the gate).
    arc_runs : tuple of TrueRun
        The emitted (or forced-through) ARC's four runs on the true plant.
    pid : TruePid
        The yardstick.
    tool_pid : ToolYardstick or None
        The PID the tool held the ARC to, on the true plant (a diagnosis; None when not asked or
        refused before tuning).
    draws_ratio : float
        :func:`draws_ratio` of the judged ARC and the yardstick (a diagnosis the counts do not read;
        NaN when not asked, or without both).
    """

    emitted: bool
    verdict: str
    candidate: bool
    arc_runs: tuple[TrueRun, ...] = ()
    pid: TruePid = field(default_factory=lambda: TruePid(None, math.nan))
    tool_pid: ToolYardstick | None = None
    draws_ratio: float = math.nan

    @property
    def arc_works(self) -> bool:
        """The judged gains work: four runs without divergence, ``c_u <= 1``, e_rms below the PID's."""
        if not self.arc_runs:
            return False
        if self.pid.gains is None:  # no PID keeps the floors on this plant: nothing to beat
            return all(r.ok for r in self.arc_runs)
        return runs_beat(self.arc_runs, self.pid.runs)

    @property
    def works(self) -> bool:
        """Emitted, and works on the true plant."""
        return self.emitted and self.arc_works

    @property
    def false_certification(self) -> bool:
        """Emitted, and does not work."""
        return self.emitted and not self.arc_works

    @property
    def false_refusal(self) -> bool:
        """Refused, although the search's chosen gains work on the true plant."""
        return (not self.emitted) and self.candidate and self.arc_works

    @property
    def ratio(self) -> float:
        """Worst ARC/PID e_rms ratio over the four runs (NaN without both; inf when the ARC diverged)."""
        return worst_ratio(self.arc_runs, self.pid.runs)


def median_ratio(arc_draws: Sequence[Sequence[TrueRun]], pid_draws: Sequence[Sequence[TrueRun]]) -> float:
    """The worst, over the runs, of the median ARC e_rms over the median PID e_rms across noise draws.

    ``arc_draws[k][j]`` is run ``j`` of draw ``k`` (:func:`true_runs` order), ``pid_draws`` alike.
    ``inf`` where the ARC diverged in a draw; NaN where the PID diverged in every draw of a run.
    """
    worst = -math.inf
    for j in range(len(arc_draws[0])):
        if any(r[j].diverged for r in arc_draws):
            return math.inf
        p = [r[j].e_rms for r in pid_draws if not r[j].diverged]
        if not p:
            return math.nan
        worst = max(worst, float(np.median([r[j].e_rms for r in arc_draws])) / float(np.median(p)))
    return worst


def draws_ratio(truth: AxisTruth, arc: ArcGains, pid: PidGains, spec: Spec, *, trajectories=None,
                noise_seed: int = 0, draws: int = NOISE_DRAWS,
                judged: tuple[Sequence[TrueRun], Sequence[TrueRun]] | None = None) -> float:
    """ARC against PID with the encoder's noise averaged out: :func:`median_ratio` over ``draws``
    noise draws.

    The judgement (:attr:`Judgement.arc_works`) compares one draw of the encoder's noise, as one
    run on the machine would.  Where a loop's error is a limit cycle of friction and quantisation,
    its e_rms varies from draw to draw by more than the two controllers differ, and one draw can
    decide the count; this figure says whether the ARC wins on the typical draw.  Draws use the
    noise seeds ``noise_seed .. noise_seed + draws - 1`` (the judged one first); ``judged``, the ARC's
    and the PID's runs of the first draw when already simulated, spares simulating it again.
    """
    trajs = trajectories if trajectories is not None else _trajectories(spec, truth.period)
    first = 0 if judged is None else 1
    arcs = [true_runs(truth, KIND_ARC, arc_pack(arc), spec, trajectories=trajs, noise_seed=noise_seed + k)
            for k in range(first, draws)]
    pids = [true_runs(truth, KIND_PID, pid_pack(pid), spec, trajectories=trajs, noise_seed=noise_seed + k)
            for k in range(first, draws)]
    if judged is not None:
        arcs, pids = [judged[0], *arcs], [judged[1], *pids]
    return median_ratio(arcs, pids)


def _trajectories(spec: Spec, Ts: float):
    return [("case1", case1_trajectory(spec).render(Ts, 0.0)), ("case2", case2_trajectory(spec).render(Ts, 0.0))]


def _stopped(u: np.ndarray, Ts: float) -> float:
    """Time from which ``u`` is exactly 0 to the end, s, when that covers the last half; else NaN."""
    nz = np.flatnonzero(u != 0.0)
    last = int(nz[-1]) + 1 if nz.size else 0
    return last * Ts if last <= u.size // 2 else math.nan


def true_runs(truth: AxisTruth, kind: int, ctrl: np.ndarray, spec: Spec, *,
              trajectories=None, noise_seed: int = 0) -> tuple[TrueRun, ...]:
    """Simulate a packed controller on the true plant: Case 1 and Case 2, each as logged and +1 sample.

    Parameters
    ----------
    truth : AxisTruth
        The plant (modes, delay), encoder step ``lsb`` (m), noise ``noise_std`` (m rms) and
        rail ``u_max`` (u-unit) are the truth's.
    kind : int
        :data:`~commission.controllers.simulate.KIND_ARC` or ``KIND_PID``.
    ctrl : ndarray
        Packed gains at the truth's sample period.
    spec : Spec
        The tuned spec: its Case 1 and Case 2 (validate's default trajectories) and its
        travel (the abort threshold, m, as validate's).
    trajectories : list of (name, Trajectory), optional
        Pre-rendered trajectories (``spec``'s at the truth's period).
    noise_seed : int
        Seed of the encoder noise (the same for every controller judged on an axis).

    Returns
    -------
    tuple of TrueRun
        ``case1``, ``case1`` +1, ``case2``, ``case2`` +1.
    """
    Ts = truth.period
    trajs = trajectories if trajectories is not None else _trajectories(spec, Ts)
    out = []
    for i, (name, ref) in enumerate(trajs):
        noise = (np.random.default_rng([noise_seed, i]).normal(0.0, truth.noise_std, ref.n)
                 if truth.noise_std > 0 else None)
        for extra in EXTRA_DELAYS:
            p = truth.plant()
            p[P_DELAY] += extra * Ts
            r = simulate(p, kind, ctrl, ref, substeps=plant_substeps(truth.sample_rate), quant=truth.lsb,
                         noise=noise, u_sat=truth.u_max, e_abort=spec.travel)
            if r.diverged or r.indexes is None:
                out.append(TrueRun(name, extra, True, math.nan, math.nan))
            else:
                out.append(TrueRun(name, extra, False, float(r.indexes.e_rms), float(r.indexes.c_u),
                                   _stopped(r.u, Ts)))
    return tuple(out)


@dataclass(frozen=True)
class Feedforward:
    """Feedforward of the yardstick PID (57): mass (u-unit s^2/m), viscous (u-unit s/m),
    friction compensation level (u-unit) and slope (s/m)."""

    M_hat: float
    B_hat: float
    fric_level: float
    fric_slope: float = PID_FRICTION_SLOPE

    @classmethod
    def of_truth(cls, truth: AxisTruth) -> "Feedforward":
        """The truth's M, B and Coulomb level."""
        return cls(truth.M, truth.B, truth.fc)

    @classmethod
    def identified(cls, ident) -> "Feedforward":
        """What ident.json identified (as tune's own PID baseline uses it)."""
        return cls(float(ident.value("M")), max(float(ident.value("B")), 0.0), float(ident.fric_level),
                   float(ident.fric_slope))


def true_pid_gains(truth: AxisTruth, pole: float, ff: Feedforward | None = None) -> PidGains:
    """The PID (57) with its triple pole at ``-pole`` rad/s for the truth's M, feedforward ``ff``
    (default: the truth's), the truth's rail."""
    ff = Feedforward.of_truth(truth) if ff is None else ff
    Kp, Ki, Kd = pid_place_poles(truth.M, -pole)
    return PidGains(Ts=truth.period, M_hat=ff.M_hat, B_hat=ff.B_hat, Kp=Kp, Ki=Ki, Kd=Kd, fric_level=ff.fric_level,
                    fric_slope=ff.fric_slope, u_max=truth.u_max)


def true_pid(truth: AxisTruth, spec: Spec, *, floors: MarginFloors | None = None, trajectories=None,
             noise_seed: int = 0, feedforward: Feedforward | None = None) -> TruePid:
    """The yardstick: the fastest PID (57) that keeps the margin floors on the TRUE plant (module docstring).

    Parameters
    ----------
    truth : AxisTruth
    spec : Spec
        The tuned spec (trajectories and abort threshold).
    floors : MarginFloors, optional
        Default: validate's defaults.
    trajectories, noise_seed
        As :func:`true_runs`.
    feedforward : Feedforward, optional
        Default: the truth's.

    Returns
    -------
    TruePid
    """
    floors = MarginFloors() if floors is None else floors
    plant = sampled_plant(truth.plant(), truth.period)
    trajs = trajectories if trajectories is not None else _trajectories(spec, truth.period)
    w = PID_POLE_START * truth.sample_rate
    for _ in range(PID_POLE_STEPS):
        g = true_pid_gains(truth, w, feedforward)
        if not floor_violations(loop_margins(linearize_pid(pid_pack(g)), plant), floors):
            runs = true_runs(truth, KIND_PID, pid_pack(g), spec, trajectories=trajs, noise_seed=noise_seed)
            if all(r.ok for r in runs):
                return TruePid(g, w, runs)
        w *= PID_POLE_STEP
    return TruePid(None, math.nan)


def judge_gains(truth: AxisTruth, arc: ArcGains, spec: Spec, *, emitted: bool, verdict: str,
                noise_seed: int = 0, feedforward: Feedforward | None = None,
                tool_pid: tuple[PidGains, float] | None = None, noise_draws: int = 1) -> Judgement:
    """Judge ARC gains (emitted or forced through) on the true axis against :func:`true_pid`.

    Parameters
    ----------
    truth : AxisTruth
    arc : ArcGains
        What the runtime would run (controller.json's gains).
    spec : Spec
        The tuned spec.
    emitted : bool
        Whether the tool emitted them.
    verdict : str
        The tool's verdict, for the record.
    noise_seed : int
    feedforward : Feedforward, optional
        The yardstick's (default: the truth's).
    tool_pid : (PidGains, float), optional
        The tool's PID yardstick and its pole, rad/s: judged too (:attr:`Judgement.tool_pid`).
    noise_draws : int
        More than 1: :attr:`Judgement.draws_ratio` over that many noise draws.

    Returns
    -------
    Judgement
    """
    if abs(arc.Ts - truth.period) > 1e-9 * truth.period:
        raise ValueError(f"judge_gains: the gains run at {1.0 / arc.Ts:g} Hz, the axis at {truth.sample_rate:g} Hz")
    trajs = _trajectories(spec, truth.period)
    runs = true_runs(truth, KIND_ARC, arc_pack(arc), spec, trajectories=trajs, noise_seed=noise_seed)
    pid = true_pid(truth, spec, trajectories=trajs, noise_seed=noise_seed, feedforward=feedforward)
    tool = (None if tool_pid is None else
            tool_yardstick(truth, tool_pid[0], tool_pid[1], spec, trajectories=trajs, noise_seed=noise_seed))
    dr = (draws_ratio(truth, arc, pid.gains, spec, trajectories=trajs, noise_seed=noise_seed, draws=noise_draws,
                      judged=(runs, pid.runs))
          if noise_draws > 1 and pid.gains is not None else math.nan)
    return Judgement(emitted=emitted, verdict=verdict, candidate=True, arc_runs=runs, pid=pid, tool_pid=tool,
                     draws_ratio=dr)


def judge_axis(truth: AxisTruth, log_path: str | os.PathLike[str], *, out_dir: str | os.PathLike[str] | None = None,
               seed: int = 0, workers: int | None = 1, identify: "IdentifyOptions | None" = None,
               noise_draws: int = 1) -> Judgement:
    """``commission run`` on ``log_path`` with its defaults, then :func:`judge_gains` on the truth.

    The one thing told beyond the log is the drive's rail when it is not the default 10
    u-unit (a force-commanded axis): ``[controller] u_max`` in a spec file, as a user of such
    a drive must state it.

    Parameters
    ----------
    truth : AxisTruth
        The axis whose log ``log_path`` is (not shown to the pipeline).
    log_path : path
    out_dir : path, optional
        Where the run writes (a temporary folder by default).
    seed : int
        ``commission run --seed`` (search and Monte-Carlo).
    workers : int, optional
        validate's threads.
    identify : IdentifyOptions, optional
        ``run``'s identify flags (default: none, as a user who gives none).
    noise_draws : int
        As :func:`judge_gains`.

    Returns
    -------
    Judgement
    """
    from commission.errors import CommissionError
    from commission.pipeline import run_all
    import dataclasses

    from commission.runtime import load_controller
    from commission.spec import spec_from_mapping

    with tempfile.TemporaryDirectory() as tmp:
        out = Path(out_dir) if out_dir is not None else Path(tmp) / "out"
        spec_path = None
        default_u_max = next(f.default for f in dataclasses.fields(Spec) if f.name == "u_max")
        if truth.u_max != default_u_max:
            spec_path = Path(tmp) / "spec.toml"
            spec_path.write_text(f"[controller]\nu_max = {truth.u_max!r}\n")
        try:
            ro = run_all(log_path, out, spec_path=spec_path, seed=seed, workers=workers, force=True, identify=identify)
        except CommissionError as exc:
            data = {"controller": {"u_max": truth.u_max}} if spec_path is not None else {}
            spec = spec_from_mapping(data, "spec.toml", sample_rate_default=truth.sample_rate)
            return Judgement(emitted=False, verdict=f"error: {exc}", candidate=False,
                             pid=true_pid(truth, spec, noise_seed=seed))
        vo = ro.validation
        spec = vo.tuning.spec
        ff = Feedforward.identified(vo.tuning.identification)
        tool = (vo.tuning.pid, vo.tuning.pid_pole)
        if vo.controller is not None:
            gains = load_controller(vo.controller).config.gains
            return judge_gains(truth, gains, spec, emitted=True, verdict="emitted", noise_seed=seed, feedforward=ff,
                               tool_pid=tool, noise_draws=noise_draws)
        fails = vo.result.verdict.failures
        first = f"{fails[0].scenario} {fails[0].criterion}" if fails else "gate"
        return judge_gains(truth, vo.result.arc_gains, spec, emitted=False, verdict=f"refused: {first}",
                           noise_seed=seed, feedforward=ff, tool_pid=tool, noise_draws=noise_draws)


__all__ = ["TrueRun", "TruePid", "ToolYardstick", "tool_yardstick", "Judgement", "Feedforward", "true_runs", "true_pid",
           "true_pid_gains", "judge_gains", "judge_axis", "worst_ratio", "runs_beat", "median_ratio", "draws_ratio",
           "EXTRA_DELAYS", "NOISE_DRAWS"]
