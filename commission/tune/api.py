"""The entry points of ``commission tune``: resolve the spec for this identification
(:func:`resolve_spec`), load the inputs (:func:`load_tune_inputs`), run :func:`tune`, and
write tuning.json (:func:`run_tune`)."""

from __future__ import annotations

import datetime as _dt
import os
from dataclasses import dataclass
from typing import Any
import cma
import numpy as np
import commission
from commission.artifacts import Identification
from commission.controllers.arc import ArcGains, arc_pack
from commission.controllers.design import (
    KIND_ARC,
    KIND_PID,
    DesignError,
    FeasibilityReport,
    discrete_feasibility,
    observer_design,
    theorem1_check,
)
from commission.controllers.pid import pid_pack
from commission.errors import IdentifiabilityError, SpecError, UsageError
from commission.jsonio import read_json, sha256_file
from commission.robustness import BoxArcCheck, margin_table
from commission.scenarios import (
    check_run_length,
    check_user_length,
    horizon_notes,
    identified_plant,
    resolve_quantization,
    trajectories,
    tuning_scenarios,
)
from commission.spec import Spec, read_spec_toml, spec_from_mapping
from commission.gate import search_infeasible_line
from commission.tuning import Guarantee, Provenance, SearchRecord, Tuning
from commission.tune.defaults import (
    check_moves_against_drive,
    check_spec_against_ident,
    fit_disturbance_to_drive,
    rate_scaled_envelope,
    default_envelope,
    default_gate_limits,
    reference_envelope,
    log_sample_rate,
)
from commission.tune.gains import base_arc_gains, free_gains
from commission.tune.objective import Progress, Evaluator, HoldoutGate, cost
from commission.tune.baseline import (bandwidth_factor, noise_bandwidth_factor, pid_candidates, pid_within_evidence,
                                      pid_yardstick)
from commission.tune.candidate import SearchResult
from commission.tune.optimiser import HoldoutChoice, Problem, search, select_on_holdout
from commission.tune.settings import DEFAULT_SETTINGS, TuneSettings
from commission.tune.guarantees import _summary, guarantees
from commission.tune.box import box_guarantees, fit_force_to_drive, fit_payload_to_drive, narrow_default_payload, validity_of
from commission.infra.blas import on_one_blas_thread


@dataclass(frozen=True)
class _Runs:
    """The runs discrete feasibility is checked on: the paper's Case 1 and Case 2 and the machine's
    moves when given (:func:`commission.scenarios.trajectories`), over the theta box."""

    ident: Identification
    spec: Spec
    names: list[str]
    trajs: list[Any]

    @classmethod
    def of(cls, ident: Identification, spec: Spec) -> "_Runs":
        named = trajectories(spec)
        return cls(ident, spec, [name for name, _ in named], [tr.render(spec.period) for _, tr in named])

    def feasibility(self, kind: int, pack: np.ndarray, *, estimate_corners: bool = False) -> FeasibilityReport:
        """:func:`commission.controllers.design.discrete_feasibility` of a packed controller on these runs."""
        return discrete_feasibility(kind, pack, self.ident.theta.min, self.ident.theta.max, self.trajs,
                                    margin=self.spec.margin, estimate_corners=estimate_corners)

    def arc(self, g: ArcGains) -> FeasibilityReport:
        """The search's discrete-feasibility constraint: the ARC with frozen estimates."""
        return self.feasibility(KIND_ARC, arc_pack(g))


def _report(progress: Progress | None, done: int, total: int) -> None:
    if progress is not None:
        progress(done, total)


@on_one_blas_thread
def tune(ident: Identification, spec: Spec, *, rng: np.random.Generator, seed: int, ident_sha256: str,
         ident_path: str = "ident.json", log_sha256: str | None = None, progress: Progress | None = None,
         workers: int | None = None, created_utc: str | None = None, observer_free: bool = False,
         pid_free: bool = False, settings: TuneSettings = DEFAULT_SETTINGS) -> Tuning:
    """Tune the ARC (and the PID baseline) for an identified axis.

    Parameters
    ----------
    ident : Identification
    spec : Spec
        Already validated (:func:`commission.spec.load_spec`).
    rng : numpy.random.Generator
        The only source of randomness (the optimiser's seed and the hold-out plants).
    seed : int
        Recorded in the provenance.
    ident_sha256 : str
        sha256 of ident.json.
    ident_path : str
        Recorded in the provenance.
    log_sha256 : str, optional
        Of the excitation log, when known.
    progress : callable(done, total), optional
        Called after each generation of the search and each final stage.
    workers : int, optional
        Batch-simulator threads.
    created_utc : str, optional
        Time stamp (default: now).
    observer_free : bool
        ``spec.observer_pole`` was defaulted, not given: the search may move it (within the
        settings' ``observer_factor_bounds``).  The pole used is the one recorded in ``observer``.
    pid_free : bool
        ``spec.pid_pole`` was defaulted: the PID baseline is the yardstick of
        :func:`commission.tune.baseline.pid_yardstick` (the fastest PID of (57) that keeps the
        margin floors on the identified plant), its pole recorded in ``pid_pole`` and how it was
        chosen in ``pid_yardstick``.
    settings : TuneSettings
        The knobs of the search, its objective and the baseline
        (:data:`commission.tune.settings.DEFAULT_SETTINGS`).

    Returns
    -------
    Tuning
    """
    check_spec_against_ident(spec, ident, settings=settings)
    ev = Evaluator(tuning_scenarios(ident, spec, rng=rng), spec, workers=workers, settings=settings)
    total = spec.budget + 3  # the search's candidates, the hold-out choice, two reports
    gate = default_gate_limits(ident, spec)
    baseline, yardstick = pid_yardstick(ident, spec, ev, gate.c_u, pid_free, settings)
    baseline = pid_within_evidence(baseline, ident, spec, ev, pid_free, settings)
    pid, pid_scores = baseline.gains, baseline.scores
    runs = _Runs.of(ident, spec)
    # A floors' pole below the rate-scaled grid says the plant, not the rate, sets the bandwidth.
    bw = bandwidth_factor(yardstick, spec, settings)
    target_hz = pid_candidates(ident, spec, [baseline.pole])[0].margins.crossover_hz
    search_seed = int(rng.integers(1, 2 ** 31 - 1))

    def search_at(factor: float, prog: Progress | None, prog_total: int) -> SearchResult:
        problem = Problem(base_arc_gains(ident, spec, factor), ev, spec, ident, pid_scores, gate, runs.arc,
                          observer_free=observer_free, settings=settings,
                          observer_scale=factor, plant_sets_bandwidth=factor < 1.0, target_crossover_hz=target_hz)
        return search(problem, spec.budget, search_seed, prog, prog_total, settings)

    res = search_at(bw, progress, total)
    searched = spec.budget
    other: dict[str, Any] | None = None
    noise_bw = noise_bandwidth_factor(yardstick, spec, settings)
    if res.n_feasible == 0 and noise_bw is not None:
        # No gains at the floors' bandwidth are feasible, and the encoder's noise held the PID yardstick
        # further down: the noise, not the plant, may limit this axis, so the ARC is searched again where it
        # limited the PID (the same seed, a second budget; the progress total grows by it).  The search
        # kept is the one whose best candidate comes first in the search's own feasibility-first order
        # (feasible before not, then the smaller violation; the floors' on a tie); the other is recorded.
        total += spec.budget
        again = search_at(noise_bw, None if progress is None else (lambda d, t: progress(d + searched, total)),
                          spec.budget)
        searched += spec.budget
        if min(c.rank_key() for c in again.candidates) < min(c.rank_key() for c in res.candidates):
            other = {"bandwidth_factor": bw, "n_evaluations": len(res.candidates), "n_feasible": res.n_feasible}
            res, bw = again, noise_bw
        else:
            other = {"bandwidth_factor": noise_bw, "n_evaluations": len(again.candidates),
                     "n_feasible": again.n_feasible}
    hg = HoldoutGate(ident, spec, ev, pid, pid_scores, rng=rng, workers=workers, settings=settings)
    choice = select_on_holdout(res, hg, settings)
    best = choice.chosen
    chosen = best.gains
    arc_scores = best.scores if best.scores is not None else ev.scores(KIND_ARC, [arc_pack(chosen)])[0]
    chosen_rep = best.feasibility or runs.arc(chosen)
    _report(progress, searched + 1, total)
    pid_rep = runs.feasibility(KIND_PID, pid_pack(pid))
    _report(progress, total - 1, total)
    t1 = theorem1_check(chosen.w1, chosen.w2, chosen.C_phi1, chosen.C_phi2, chosen.C_theta2)
    robust = runs.feasibility(KIND_ARC, arc_pack(chosen), estimate_corners=True)
    feas = {"arc": _summary(chosen_rep, runs.names, robust), "pid": _summary(pid_rep, runs.names)}
    cost_best = best.objective if best.scores is not None else cost(arc_scores, spec, pid_scores, ev.weights, gate,
                                                                     settings)
    record = _search_record(res, choice, spec, seed, cost_best, bw, other)
    # The whole box (a defaulted payload range was narrowed before the search, resolve_spec).
    box = BoxArcCheck(ident, spec)(chosen)
    validity = validity_of(ident)
    out = Tuning(provenance=_provenance(ident_sha256, log_sha256, created_utc, seed, ident_path), spec=spec,
                 identification=ident, plant=identified_plant(ident, spec),
                 quantization=resolve_quantization(ident, spec), arc=chosen, pid=pid, pid_pole=baseline.pole,
                 pid_design_mass=baseline.design_mass,
                 observer=observer_design(spec.observer_pole * best.observer_factor, spec.period), theorem1=t1,
                 feasibility=feas,
                 guarantees={**guarantees(chosen, t1, feas["arc"]), **box_guarantees(box, spec, validity),
                             "search_feasible": _search_guarantee(record)},
                 scores={name: {"arc": a, "pid": p} for name, a, p in zip(ev.names, arc_scores, pid_scores)},
                 search=record, margins=margin_table(chosen, pid, ident, spec), box=box, validity=validity,
                 pid_yardstick=yardstick.to_dict())
    _report(progress, total, total)
    return out


def _provenance(ident_sha256: str, log_sha256: str | None, created_utc: str | None, seed: int,
                ident_path: str) -> Provenance:
    """tuning.json's ``provenance``: the inputs' hashes, this tool's version, the time (default: now), the seed."""
    return Provenance(ident_sha256=ident_sha256, log_sha256=log_sha256, tool_version=commission.__version__,
                      created_utc=created_utc or _dt.datetime.now(_dt.timezone.utc).strftime("%Y-%m-%dT%H:%M:%SZ"),
                      seed=int(seed), ident_path=ident_path)


def _search_record(res: SearchResult, choice: HoldoutChoice, spec: Spec, seed: int, cost_best: float,
                   bandwidth: float = 1.0, other: dict[str, Any] | None = None) -> SearchRecord:
    """tuning.json's ``search``: every candidate's objective, violation and level, and the choice.

    ``cost_best`` is the chosen gains' objective (computed on their scores when the search did not
    simulate them on every tuning scenario); ``bandwidth`` the factor the ARC's carried-over design
    was scaled by in the search kept, ``other`` the summary of a search at another factor, not kept.
    """
    best = choice.chosen
    return SearchRecord(n_evaluations=len(res.candidates), budget=spec.budget, seed=int(seed),
                        cost_initial=res.candidates[0].objective, cost_best=cost_best,
                        free=free_gains(best.gains).as_dict(),
                        history=tuple(c.objective for c in res.candidates),
                        holdout_plants=choice.n_plants, holdout_failures=choice.failures,
                        optimiser=f"CMA-ES (pycma {cma.__version__}), feasibility-first ranking",
                        generations=res.generations, n_feasible=res.n_feasible,
                        violations=tuple(c.violation for c in res.candidates),
                        levels=tuple(c.level for c in res.candidates),
                        chosen_level=best.level, chosen_violation=best.violation,
                        screened=tuple(c.screened for c in res.candidates),
                        bandwidth_factor=float(bandwidth), other_search=other)


def _search_guarantee(record: SearchRecord) -> Guarantee:
    """tuning.json's ``guarantees.search_feasible``: did the search find gains meeting its constraints?

    The chosen gains are written either way (validate then names what they miss), but a search
    that found nothing feasible says so here, in the words of the report's refusal
    (:func:`commission.gate.search_infeasible_line`).
    """
    miss = search_infeasible_line(record)
    if miss is None:
        return Guarantee(True, f"the chosen gains meet every constraint of the search ({record.n_feasible} of "
                               f"{record.n_evaluations} candidates did): the margin floors on the identified "
                               f"plant and over the whole theta box, the evidence bound, discrete feasibility "
                               f"and the gate on the tuning scenarios")
    return Guarantee(False, miss)


def _log_sha256(ident: Identification) -> str | None:
    """The excitation log's sha256 if ident.json records one (``extra.source.sha256``)."""
    src = ident.extra.get("source")
    if isinstance(src, dict) and isinstance(src.get("sha256"), str):
        return src["sha256"]
    v = ident.extra.get("log_sha256")
    return v if isinstance(v, str) else None


@dataclass(frozen=True)
class TuneInputs:
    """Everything ``commission tune`` reads, checked (see :func:`load_tune_inputs`)."""

    ident: Identification
    spec: Spec
    ident_path: str
    ident_sha256: str
    log_sha256: str | None
    seed: int
    notes: tuple[str, ...] = ()
    observer_free: bool = False
    pid_free: bool = False


@dataclass(frozen=True)
class ResolvedSpec:
    """What ``tune`` runs with, after the defaults were fitted to the axis (:func:`resolve_spec`).

    Attributes
    ----------
    spec : Spec
        The spec with its defaults fitted to the axis (rates, horizons, budget).
    ident : Identification
        The identification tune designs for: the input one, or a copy whose theta3 box was
        narrowed to the drive (:func:`fit_disturbance_to_drive`).
    notes : tuple of str
        One line per default that was lowered or narrowed.
    observer_free : bool
        ``controller.observer_pole`` was not given: tune's search may move it.
    pid_free : bool
        ``pid.pole`` was not given: tune may lower the PID baseline's pole (:func:`deployable_pid`).
    """

    spec: Spec
    ident: Identification
    notes: tuple[str, ...]
    observer_free: bool = False
    pid_free: bool = False


def resolve_spec(spec_data: dict, spec_name: str, ident: Identification, *,
                 ident_name: str = "ident.json", settings: TuneSettings = DEFAULT_SETTINGS) -> ResolvedSpec:
    """The spec ``tune`` runs with, for this identification; no simulation runs here.

    The sample rate defaults to the log's (:func:`log_sample_rate`), the envelope's
    defaulted keys are scaled to that rate (:func:`rate_scaled_envelope`), a defaulted
    load-force bound that leaves no room for any envelope is narrowed
    (:func:`fit_disturbance_to_drive`), the envelope's defaulted keys are lowered to
    what the drive can move (:func:`default_envelope`),
    then :func:`check_spec_against_ident` and the observer design check the result.

    Raises
    ------
    IdentifiabilityError
        The identification lacks what tune needs (a parameter not identified), naming it.
    SpecError
        Naming the key.
    """
    gaps = ident.tuning_gaps(ident_name)
    if gaps:
        raise IdentifiabilityError(gaps[0])
    spec = spec_from_mapping(spec_data, spec_name, sample_rate_default=log_sample_rate(ident))
    traj = spec_data.get("trajectory")
    given = set(traj) if isinstance(traj, dict) else set()
    if spec.profile is not None:
        # The machine's moves set the envelope: no derivation from u_max (the paper's Case 1 and
        # Case 2 get theirs in reference_envelope).  Their length and force first: they name the moves.
        given |= {"v_max", "a_max", "travel"}
        check_user_length(spec, spec_name)
        check_moves_against_drive(spec, ident, spec_name, settings=settings)
    spec, rate_notes = rate_scaled_envelope(spec, given, ident.units)
    ident, box_notes = fit_disturbance_to_drive(spec, ident, given, settings=settings)
    ident, force_notes = fit_force_to_drive(spec, ident, given, spec_name, settings=settings)
    box_notes = box_notes + force_notes
    ident, drive_notes = fit_payload_to_drive(spec, ident, given, spec_name, settings=settings)
    spec, notes = default_envelope(spec, ident, given, spec_name, settings=settings)
    spec, ref_notes = reference_envelope(spec, ident, given, spec_name, settings=settings)
    notes = notes + ref_notes
    check_spec_against_ident(spec, ident, spec_name, settings=settings)
    check_run_length(spec, spec_name)  # the envelope may have been lowered, lengthening the runs
    try:
        observer_design(spec.observer_pole, spec.period)
    except DesignError as exc:
        raise SpecError(f"{spec_name}: controller.observer_pole: {exc}") from None
    ctrl = spec_data.get("controller")
    observer_free = not (isinstance(ctrl, dict) and "observer_pole" in ctrl)
    pid = spec_data.get("pid")
    pid_free = not (isinstance(pid, dict) and "pole" in pid)
    # A defaulted payload range the search's start points cannot certify is narrowed to one they can.
    ident, payload_notes = narrow_default_payload(ident, spec, settings)
    return ResolvedSpec(spec, ident, rate_notes + box_notes + drive_notes + notes + horizon_notes(spec)
                        + payload_notes, observer_free, pid_free)


def load_tune_inputs(ident_path: str | os.PathLike[str], *, spec_path: str | os.PathLike[str] | None = None,
                     seed: int = 0) -> TuneInputs:
    """Read and check every input of ``commission tune``; no simulation runs here.

    Raises
    ------
    InputFileError, SchemaError, SpecError, UsageError
        Bad input (the CLI's exit 2), naming the file and the key.
    """
    if seed < 0:
        raise UsageError(f"--seed: must be a non-negative integer, got {seed}")
    ident_path = os.fspath(ident_path)
    spec_data, spec_name = read_spec_toml(spec_path)  # parse errors before reading ident.json
    spec_from_mapping(spec_data, spec_name)  # every key checked at the documented defaults
    ident = Identification.from_dict(read_json(ident_path), source=ident_path)
    rs = resolve_spec(spec_data, spec_name, ident, ident_name=str(ident_path))
    return tune_inputs(rs, ident_path=ident_path, ident_sha256=sha256_file(ident_path), log_sha256=_log_sha256(ident),
                       seed=seed)


def tune_inputs(rs: ResolvedSpec, *, ident_path: str, ident_sha256: str, log_sha256: str | None,
                seed: int) -> TuneInputs:
    """The :class:`TuneInputs` of a resolved spec.

    ``commission tune`` (:func:`load_tune_inputs`) and ``commission run``
    (:func:`commission.pipeline.run_all`) both build their inputs here and tune them with
    :func:`tune_from`, so that the same log and spec give the same tuning either way
    (``observer_free`` and ``pid_free`` included).
    """
    return TuneInputs(ident=rs.ident, spec=rs.spec, ident_path=ident_path, ident_sha256=ident_sha256,
                      log_sha256=log_sha256, seed=int(seed), notes=rs.notes, observer_free=rs.observer_free,
                      pid_free=rs.pid_free)


def tune_from(inp: TuneInputs, *, progress: Progress | None = None, workers: int | None = None) -> Tuning:
    """:func:`tune` on checked inputs, seeded with ``inp.seed`` (a fresh ``numpy.random.default_rng``)."""
    return tune(inp.ident, inp.spec, rng=np.random.default_rng(inp.seed), seed=inp.seed,
                ident_sha256=inp.ident_sha256, ident_path=inp.ident_path, log_sha256=inp.log_sha256,
                progress=progress, workers=workers, observer_free=inp.observer_free, pid_free=inp.pid_free)


def run_tune(ident_path: str | os.PathLike[str], out_path: str | os.PathLike[str], *,
             spec_path: str | os.PathLike[str] | None = None, seed: int = 0,
             progress: Progress | None = None, workers: int | None = None,
             inputs: TuneInputs | None = None) -> Tuning:
    """File-level pipeline of ``commission tune``: read, check, tune, write.

    Every input check (:func:`load_tune_inputs`: ident.json schema, spec keys
    and values, spec against the identification) runs before any simulation;
    nothing is written unless tuning completes.  ``inputs`` (already loaded)
    skips the reading.

    Raises
    ------
    InputFileError, SchemaError, SpecError, UsageError
        Bad input (the CLI's exit 2).
    """
    inp = inputs if inputs is not None else load_tune_inputs(ident_path, spec_path=spec_path, seed=seed)
    try:
        t = tune_from(inp, progress=progress, workers=workers)
    except DesignError as exc:  # a design input the spec checks let through: still bad input, exit 2
        raise SpecError(f"{os.fspath(spec_path) if spec_path else 'spec'}: {exc}") from None
    t.save(os.fspath(out_path))
    return t
