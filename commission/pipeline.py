"""The ``commission run`` pipeline: one log -> identify -> tune -> validate, in memory.

Orchestration only: the stages are :func:`commission.identification.identify_log`,
:func:`commission.tune.tune_from` and :func:`commission.validate.validate`; this
module checks every input before any stage runs and writes the files at the end.
"""

from __future__ import annotations

import json
import os
from dataclasses import dataclass
from pathlib import Path
from typing import Callable, Sequence

from commission.infra.background import ChildJob
from commission.errors import SpecError, UsageError
from commission.gate import load_gate, resolve_gate
from commission.jsonio import write_json_atomic
from commission.scenarios import resolve_quantization
from commission.tuning import Tuning
from commission.infra.files import Outputs
from commission.identification import IDENT_FIGURE_NAMES, IdentifyOptions, IdentifyOutcome
from commission.spec import check_flags
from commission.infra.blas import on_one_blas_thread
from commission.infra.executor import Executor, compute_scheduler, make_executor, resolve_scheduler
from commission.validate import (CONTROLLER_NAME, DEFAULT_MONTE_CARLO, FigureWriter, Progress, ValidateOutcome,
                                 output_names, validate, write_outputs)

IDENT_NAME = "ident.json"
TUNING_NAME = "tuning.json"
StageProgress = Callable[[str, int, int], None]
IdentFigureWriter = Callable[[IdentifyOutcome, Path], Sequence[Path]]


@dataclass(frozen=True)
class RunOutcome:
    """What :func:`run_all` wrote.

    Attributes
    ----------
    ident : Path
        ident.json in the output folder.
    tuning : Path
        tuning.json in the output folder.
    validation : ValidateOutcome
        What validate wrote there: report, figures, validation.json and, when the gate
        passed, controller.json.
    notes : tuple of str
        Spec defaults lowered for this axis (:func:`commission.tune.resolve_spec`).
    also_tried : str, optional
        A failed gate on a defaulted payload box whose second try (the axis as identified,
        :func:`_as_identified`) failed too: what that try gave, one sentence (the report and
        the next steps say it); None otherwise.
    """

    ident: Path
    tuning: Path
    validation: ValidateOutcome
    notes: tuple[str, ...] = ()
    also_tried: str | None = None


def run_all(log_path: str | os.PathLike[str], out_dir: str | os.PathLike[str], *,
            identify: IdentifyOptions | None = None,
            spec_path: str | os.PathLike[str] | None = None, gate_path: str | os.PathLike[str] | None = None,
            force: bool = False, seed: int = 0, n_monte_carlo: int = DEFAULT_MONTE_CARLO,
            progress: StageProgress | None = None, workers: int | None = None,
            figures: FigureWriter | None = None, sign_key: bytes | None = None,
            ident_figures: IdentFigureWriter | None = None, scheduler: str | None = None,
            executor: Executor | None = None) -> RunOutcome:
    """``commission run``: identify, tune and validate one log into ``out_dir``.

    Every check of the inputs (flags, spec, gate, the output folder, which is
    then locked; then the log and the spec against the identified axis)
    happens before anything is written; the three stages then run in memory
    and the files -- ident.json, tuning.json, validation.json, the figures,
    report.md and (gate and floors passed) controller.json -- are moved into
    place together at the end (:class:`commission.infra.files.Outputs`).  The files are byte for byte
    what ``commission identify``, ``tune`` and ``validate`` would write (up to
    time stamps): ident.json and tuning.json are round-tripped through their
    JSON form before the next stage uses them, and their sha256 are those of
    the files written.

    Parameters
    ----------
    log_path : path or sequence of paths
        Excitation log (CONTRACT §1); several files or a folder: logs of one axis, fitted
        together with each file its own segment (:func:`commission.identification.identify_log`).
    out_dir : path
    identify : IdentifyOptions, optional
        What ``commission identify`` is told about the log (its flags); default: its defaults.
    ident_figures : callable(IdentifyOutcome, folder) -> list of paths, optional
        Draws the identification figures (``identify --plot``'s) into the out-dir; the
        report links them.
    spec_path : path, optional
        Tuning spec (``commission tune --spec``); default: the paper's setting.
    gate_path : path, optional
        Gate TOML; default: :mod:`commission.gate` defaults.
    force : bool
        Overwrite existing outputs.
    seed : int
        Seed of the tuning search and of the validation's Monte-Carlo sample.
    n_monte_carlo : int
    progress : callable(stage, done, total), optional
        ``stage`` is ``"identify"``, ``"tune"`` or ``"validate"``.
    workers : int, optional
    figures : callable, optional
        As in :func:`run_validate`.
    sign_key : bytes, optional
        Signs controller.json (HMAC-SHA256).
    scheduler : str, optional
        ``--scheduler`` (else ``COMMISSION_SCHEDULER``, else the spec's ``[compute] scheduler``):
        validate's simulations run there (:mod:`commission.infra.executor`).
    executor : commission.infra.executor.Executor, optional
        An open executor for validate's simulations instead (not closed here).

    Raises
    ------
    InputFileError, DataError, SchemaError, SpecError, UsageError
        Bad input (exit 2); nothing is written.
    """
    from commission.spec import read_spec_toml, spec_from_mapping

    check_flags(seed=seed, monte_carlo=n_monte_carlo, workers=workers)
    opts = identify if identify is not None else IdentifyOptions()
    if opts.friction not in ("auto", "coulomb", "stribeck"):
        raise UsageError(f"--friction: expected auto, coulomb or stribeck, got {opts.friction!r}")
    gate = load_gate(gate_path)
    spec_data, spec_src = read_spec_toml(spec_path)
    spec_from_mapping(spec_data, spec_src)  # every key checked at the documented defaults
    address = resolve_scheduler(scheduler, compute_scheduler(spec_data, spec_src)) if executor is None else None
    from commission.identification import expand_log_paths

    # Several files (or a folder): logs of one axis, each its own segment (identify_log with a list).
    paths = expand_log_paths([os.fspath(p) for p in ([log_path] if isinstance(log_path, (str, os.PathLike))
                                                      else log_path)])
    log_path = paths[0] if len(paths) == 1 else paths
    if opts.validate_on is not None:
        expand_log_paths([os.fspath(opts.validate_on)])  # refused now (missing, one file twice), not after the lock
    outputs = Outputs(force=force, inputs=(*paths, spec_path, gate_path, opts.validate_on, opts.plan_path))
    out = outputs.add_dir(out_dir, (IDENT_NAME, TUNING_NAME, *IDENT_FIGURE_NAMES, *output_names()), "--out-dir")
    ex = executor if executor is not None else make_executor(address, workers)  # unreachable: exit 2 now
    try:
        with outputs:  # locked and proved writable before any stage runs; moved into place at the end
            written, result, tuning, notes, also_tried = _stages(
                log_path, out, outputs.staging(out), opts=opts, spec_data=spec_data, spec_src=spec_src, gate=gate,
                gate_path=gate_path, seed=seed, n_monte_carlo=n_monte_carlo, progress=progress, workers=workers,
                figures=figures, sign_key=sign_key, ident_figures=ident_figures, executor=ex)
    finally:
        if executor is None:
            ex.close()
    ctrl = out / CONTROLLER_NAME
    vo = ValidateOutcome(result, tuning, tuple(outputs.final(p) for p in written), ctrl if result.passed else None)
    return RunOutcome(out / IDENT_NAME, out / TUNING_NAME, vo, notes, also_tried)


def _stages(log_path, out: Path, staging: Path, *, opts, spec_data, spec_src, gate, gate_path, seed, n_monte_carlo,
            progress, workers, figures, sign_key, ident_figures, executor=None):
    """The three stages of :func:`run_all`, writing into ``staging``; names in the files say ``out``."""
    from commission.identification import expand_log_paths, identify_log

    def stage(name: str) -> Progress:
        return lambda done, total: progress(name, done, total) if progress is not None else None

    stage("identify")(0, 1)
    kw = opts.kwargs()
    if kw["validate_on"] is not None:  # a folder of validation logs, as identify's --validate-on
        kw["validate_on"] = expand_log_paths([str(kw["validate_on"])])
    ident_out = identify_log(log_path, **kw)  # type: ignore[arg-type]
    stage("identify")(1, 1)
    # The identification figures are drawn beside the tuning (commission.infra.background).
    ident_job = ChildJob(ident_figures, ident_out, staging) if ident_figures is not None else None
    try:
        return _after_identify(ident_out, ident_job, out, staging, spec_data=spec_data, spec_src=spec_src, gate=gate,
                               gate_path=gate_path, seed=seed, n_monte_carlo=n_monte_carlo, stage=stage,
                               workers=workers, figures=figures, sign_key=sign_key, log_path=log_path,
                               executor=executor)
    except BaseException:
        if ident_job is not None:
            ident_job.cancel()
        raise


@on_one_blas_thread
def _after_identify(ident_out, ident_job, out: Path, staging: Path, *, spec_data, spec_src, gate, gate_path, seed,
                    n_monte_carlo, stage, workers, figures, sign_key, log_path, executor=None):
    """Tune and validate the identified axis, then write every file into ``staging``."""
    from commission.artifacts import Identification
    from commission.controllers.design import DesignError
    from commission.jsonio import canonical_json, sha256_json
    from commission.tune import resolve_spec, tune_from, tune_inputs

    ident_doc = ident_out.ident.to_dict()
    ident = Identification.from_dict(json.loads(canonical_json(ident_doc)), source=str(out / IDENT_NAME))
    ident_sha = sha256_json(ident_doc)

    def attempt(idn: Identification) -> tuple[dict, Tuning, object, tuple[str, ...]]:
        rs = resolve_spec(spec_data, spec_src, idn)  # the log's rate, the drive's envelope and load
        resolve_gate(gate, lsb=resolve_quantization(idn, rs.spec), travel=rs.spec.travel, u_max=rs.spec.u_max,
                     targets=rs.spec.targets)
        # The same inputs and call as ``commission tune`` on the ident.json written below.
        inputs = tune_inputs(rs, ident_path=str(out / IDENT_NAME), ident_sha256=ident_sha,
                             log_sha256=ident_out.log.sha256 if isinstance(log_path, str) else None, seed=seed)
        try:
            tuned = tune_from(inputs, progress=stage("tune"), workers=workers)
        except DesignError as exc:
            raise SpecError(f"{spec_src}: {exc}") from None
        doc = tuned.to_dict()
        tng = Tuning.from_dict(json.loads(canonical_json(doc)), source=str(out / TUNING_NAME))
        res = validate(tng, gate, seed=seed, n_monte_carlo=n_monte_carlo, progress=stage("validate"),
                       workers=workers, executor=executor)
        return doc, tng, res, rs.notes

    tuning_doc, tuning, result, notes = attempt(ident)
    also_tried = None
    if not result.passed:
        tuning_doc, tuning, result, notes, also_tried = _as_identified(ident, attempt,
                                                                       (tuning_doc, tuning, result, notes))
    write_json_atomic(staging / IDENT_NAME, ident_doc)
    write_json_atomic(staging / TUNING_NAME, tuning_doc)
    ident_figs = list(ident_job.result()) if ident_job is not None else []
    written = write_outputs(result, tuning, sha256_json(tuning_doc), staging, figures=figures,
                            sources={"tuning": str(out / TUNING_NAME),
                                     "gate": os.fspath(gate_path) if gate_path else None}, sign_key=sign_key,
                            extra_figures=ident_figs, also_tried=also_tried)
    return written, result, tuning, notes, also_tried


def _failed_checks(result) -> str:
    """The first three failed checks of a validation, ``"<scenario> <criterion>; ..."``."""
    fails = result.verdict.failures
    return "; ".join(f"{c.scenario} {c.criterion}" for c in fails[:3]) + (" ..." if len(fails) > 3 else "")


def _as_identified(ident, attempt, first):
    """``run``'s second try on a defaulted payload box that failed the gate: the axis as identified.

    ``first`` is the first try's ``(tuning doc, tuning, validation result, notes)``; the second
    (:func:`commission.tune.box.as_identified_box`: the payload range cut to none, stated as the
    range of validity) replaces it only when it passes the gate; otherwise the first is kept, and
    what the second gave is returned as one sentence (``also_tried``, last of the five), which the
    report and the next steps say.  A stated payload range, or one already cut to none, is
    not retried: the first try stands (``also_tried`` None).
    """
    from commission.tune.box import as_identified_box

    pb = (first[1].identification.extra.get("bounds") or {}).get("payload_range")
    span = f"{pb[0]:.4g}..{pb[1]:.4g}" if isinstance(pb, list) and len(pb) == 2 else "the default range"
    cut = as_identified_box(ident, f"over the payloads {span} the gate failed ({_failed_checks(first[2])})")
    if cut is None:
        return (*first, None)
    try:
        second = attempt(cut[0])
    except SpecError as exc:
        return (*first, f"the axis as identified (no payload) was tried too and refused ({exc})")
    if second[2].passed:
        return (*second[:3], cut[1] + second[3], None)
    return (*first, f"the axis as identified (no payload) was tuned and validated too and failed the gate as well "
                    f"({_failed_checks(second[2])})")


__all__ = ["run_all", "RunOutcome", "IDENT_NAME", "TUNING_NAME"]
