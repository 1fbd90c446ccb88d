"""The ``commission validate`` command's entry (:func:`run_validate`: tuning.json in, files out)
and the files it writes (:func:`write_outputs`: validation.json, report.md, the figures and
controller.json only when the gate passed).
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path
from typing import Callable, Mapping, Sequence

from commission.infra.executor import Executor, make_executor, resolve_scheduler
from commission.infra.files import Outputs
from commission.gate import load_gate, resolve_gate, safe_not_better
from commission.jsonio import read_json, sha256_file, write_json_atomic, write_text_atomic
from commission.report import report_markdown
from commission.scenarios import check_run_length
from commission.spec import check_flags
from commission.tuning import Tuning
from commission.validate.results import (CONTROLLER_NAME, DEFAULT_MONTE_CARLO, FIGURE_NAMES, FLAGGED_NAME, Progress,
                                         REPORT_NAME, USER_FIGURE_NAME, VALIDATION_NAME, ValidationResult)
from commission.validate.stage import validate
from commission.validate.controller_file import controller_config
from commission.validate.provenance import check_provenance


@dataclass(frozen=True)
class ValidateOutcome:
    """What :func:`run_validate` wrote.

    Attributes
    ----------
    result : ValidationResult
        Everything validate computed: every scenario's run, the traces and the gate's verdict.
    tuning : Tuning
        The tuning.json that was validated, as loaded.
    written : tuple of Path
        Every file written, in order.
    controller : Path or None
        controller.json when the gate passed.
    """

    result: ValidationResult
    tuning: Tuning
    written: tuple[Path, ...]
    controller: Path | None


FigureWriter = Callable[[ValidationResult, Path], Sequence[Path]]

def output_names() -> tuple[str, ...]:
    """Every file ``validate`` may write into its output folder."""
    return (REPORT_NAME, VALIDATION_NAME, CONTROLLER_NAME, FLAGGED_NAME, *FIGURE_NAMES, USER_FIGURE_NAME)


def run_validate(tuning_path: str | os.PathLike[str], out_dir: str | os.PathLike[str], *,
                 gate_path: str | os.PathLike[str] | None = None, force: bool = False, seed: int = 0,
                 n_monte_carlo: int = DEFAULT_MONTE_CARLO, progress: Progress | None = None,
                 workers: int | None = None, figures: FigureWriter | None = None,
                 sign_key: bytes | None = None, scheduler: str | None = None,
                 executor: Executor | None = None) -> ValidateOutcome:
    """File-level pipeline of ``commission validate`` (module docstring).

    Every input check runs before any simulation (the flags' ranges, the gate,
    tuning.json and its provenance, the trajectories' length, the output
    folder, which is then locked), and the files are moved into place together
    when the simulations are done (:class:`commission.infra.files.Outputs`).

    Parameters
    ----------
    tuning_path : path
        tuning.json.
    out_dir : path
        Folder for report.md, validation.json, the figures and controller.json.
    gate_path : path, optional
        gate.toml (default: the documented defaults).
    force : bool
        Overwrite existing outputs.
    seed, n_monte_carlo, progress, workers
        As in :func:`validate`.
    figures : callable(result, out_dir) -> paths, optional
        Draws the figures (the CLI passes its matplotlib writer); report.md links what it returns.
    sign_key : bytes, optional
        Signs controller.json with HMAC-SHA256 (:mod:`commission.controller_config`).
    scheduler : str, optional
        ``--scheduler``: a Dask scheduler address; else ``COMMISSION_SCHEDULER``; else local
        threads (:func:`commission.infra.executor.resolve_scheduler`).  Connected to after the input
        checks and before any simulation.
    executor : commission.infra.executor.Executor, optional
        An open executor instead (a library caller's; not closed here).

    Raises
    ------
    InputFileError, SchemaError, SpecError, UsageError
        Bad input (exit 2); nothing is written.  An unreachable scheduler is a
        :class:`commission.infra.executor.SchedulerError` (a UsageError) naming its address.
    """
    check_flags(seed=seed, monte_carlo=n_monte_carlo, workers=workers)
    gate = load_gate(gate_path)
    tpath = os.fspath(tuning_path)
    tuning = Tuning.from_dict(read_json(tpath), source=tpath)
    check_run_length(tuning.spec, tpath, "$.spec.")
    check_provenance(tuning, tpath)
    # Resolve now so that a gate that cannot apply to this tuning fails before any simulation.
    resolve_gate(gate, lsb=tuning.quantization, travel=tuning.spec.travel, u_max=tuning.spec.u_max,
                 targets=tuning.spec.targets)
    outputs = Outputs(force=force, inputs=(tpath, gate_path))
    out = outputs.add_dir(out_dir, output_names(), "--out-dir")
    tuning_sha = sha256_file(tpath)
    own = executor is None
    ex = make_executor(resolve_scheduler(scheduler), workers) if own else executor
    try:
        with outputs:  # locked and proved writable before the simulations; moved into place at the end
            result = validate(tuning, gate, seed=seed, n_monte_carlo=n_monte_carlo, progress=progress,
                              workers=workers, executor=ex)
            staged = write_outputs(result, tuning, tuning_sha, outputs.staging(out), figures=figures,
                                   sources={"tuning": tpath, "gate": os.fspath(gate_path) if gate_path else None},
                                   sign_key=sign_key)
    finally:
        if own:
            ex.close()
    written = [outputs.final(p) for p in staged]
    ctrl = out / CONTROLLER_NAME
    return ValidateOutcome(result, tuning, tuple(written), ctrl if result.passed else None)


def write_outputs(result: ValidationResult, tuning: Tuning, tuning_sha256: str, out: Path, *,
                  figures: FigureWriter | None = None, sources: Mapping[str, str | None] | None = None,
                  sign_key: bytes | None = None, extra_figures: Sequence[Path] = (),
                  also_tried: str | None = None) -> list[Path]:
    """Write validation.json, the figures, report.md and (gate and floors passed) controller.json into ``out``.

    ``out`` is the staging folder of :class:`commission.infra.files.Outputs` in the commands;
    ``extra_figures`` are figures already written there (``run``'s identification
    figures), which the report links; ``also_tried`` is ``run``'s failed second try on the axis
    as identified (:attr:`commission.pipeline.RunOutcome.also_tried`), which the report states.
    """
    out.mkdir(parents=True, exist_ok=True)
    written: list[Path] = []
    write_json_atomic(out / VALIDATION_NAME, result.to_dict())
    written.append(out / VALIDATION_NAME)
    figs = [*extra_figures, *(figures(result, out) if figures is not None else [])]
    written.extend(figs)
    text = report_markdown(result, tuning, figures=[p.name for p in figs], sources=sources or {},
                           tuning_sha256=tuning_sha256, also_tried=also_tried)
    write_text_atomic(out / REPORT_NAME, text)
    written.append(out / REPORT_NAME)
    ctrl = out / CONTROLLER_NAME
    if result.passed:
        write_json_atomic(ctrl, controller_config(result, tuning, tuning_sha256).to_dict(sign_key=sign_key))
        written.append(ctrl)
    elif ctrl.exists():
        ctrl.unlink()  # never leave a deployable file next to a failing report
    flagged = out / FLAGGED_NAME
    if safe_not_better(result.verdict):
        write_json_atomic(flagged, controller_config(result, tuning, tuning_sha256, flagged=True)
                          .to_dict(sign_key=sign_key))
        written.append(flagged)
    elif flagged.exists():
        flagged.unlink()
    return written
