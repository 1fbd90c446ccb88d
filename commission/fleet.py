"""``commission fleet MANIFEST --out-dir DIR``: commission many axes, one ``run`` each.

The manifest lists the axes (:func:`load_manifest`); each one is commissioned by
:func:`commission.pipeline.run_all` -- the same call as ``commission run`` -- into
``DIR/<name>/``, and the fleet is summarised in ``DIR/fleet.json`` and ``DIR/fleet.md``
(one row per axis, :func:`axis_row`) with a figure of the parameter spread (drawn by the CLI).

Design
------
* **One bad axis never stops the others.**  Every axis runs in its own task; any error
  of its run (a corrupt log, a spec that does not fit it, a failed stage) becomes that
  axis's error row, with the error's one-line message.  A bad *manifest* (its syntax, a
  missing column, a duplicate or unsafe name) is a :class:`commission.errors.SchemaError`
  before any axis runs (exit 2).
* **Exit code** (:func:`exit_code`): 0 when every axis passed its gate, 1 when any gate
  failed or any axis ended in an error.
* **Where the axes run**: on the executor (:mod:`commission.infra.executor`).  Locally the axes
  run one after another, each on every core (tune and validate are parallel inside); on a
  Dask cluster each axis is one task, and its run uses the worker's cores.  The rows are
  gathered in manifest order whatever the engine.
* **Resumable**: each row records the sha256 of the axis's inputs (:func:`inputs_sha256`:
  the log file(s), the spec, the gate, and the options that change the result) and of its
  validation.json.  A rerun into the same ``DIR`` keeps the row of an axis whose inputs hash
  the same and whose files are all in place (the validation.json hash matching), and runs
  every other axis again.
* **Outliers** (:func:`flag_outliers`): in a fleet of nominally identical axes, an axis
  whose identified mass or friction sits far from its siblings points at a mechanical fault.
  Robust statistics, so that the outlier does not hide itself: per parameter
  (:data:`OUTLIER_PARAMETERS`), the median over the axes that were identified and a scale
  ``s = max(1.4826 MAD, OUTLIER_REL_FLOOR |median|)``; the axis is flagged when
  ``|x - median| > OUTLIER_Z s`` for any of them.  1.4826 MAD estimates a standard deviation
  of normal data; the threshold 3.5 is Iglewicz and Hoaglin's for the modified z-score; the
  relative floor (5 %) keeps a fleet of near-identical axes, whose MAD is tiny, from flagging
  differences a machine builder would not call a fault.  Needs :data:`OUTLIER_MIN_AXES` axes.
"""

from __future__ import annotations

import csv
import datetime as _dt
import hashlib
import math
import os
import re
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Callable, Mapping, Sequence

import commission
from commission.errors import SchemaError, UsageError
from commission.infra.executor import Executor, LocalExecutor
from commission.formats.validation_json import check_validation
from commission.jsonio import read_json, sha256_file
from commission.validate.results import CONTROLLER_NAME, FLAGGED_NAME

FLEET_KIND = "fleet"
FLEET_SCHEMA_VERSION = 1
FLEET_JSON = "fleet.json"
FLEET_MD = "fleet.md"
FLEET_FIGURE = "fleet.png"
#: Manifest columns / keys of an axis.
AXIS_KEYS = ("name", "log", "spec", "gate")
#: Parameters compared across the fleet (ident.json's ``parameters``).
OUTLIER_PARAMETERS = ("M", "fc", "fs")
#: Modified z-score above which an axis is flagged (Iglewicz & Hoaglin).
OUTLIER_Z = 3.5
#: Least scale relative to the median (5 %): spread below it is not a fault.
OUTLIER_REL_FLOOR = 0.05
#: Fewest identified axes for the statistics.
OUTLIER_MIN_AXES = 3
#: Parameters listed per axis, with their units (commission.units.parameter_units).
ROW_PARAMETERS = ("M", "B", "fc", "fs", "offset")
_NAME = re.compile(r"^[A-Za-z0-9][A-Za-z0-9._-]{0,63}$")


@dataclass(frozen=True)
class AxisEntry:
    """One axis of the manifest; paths resolved against the manifest's folder.

    Attributes
    ----------
    name : str
        Folder name under ``--out-dir`` (letters, digits, ``._-``; at most 64).
    log : str
        Excitation log file, or a folder of logs of that axis (as ``run`` takes them).
    spec, gate : str or None
        spec.toml and gate.toml (default: the manifest's ``[fleet]`` ones, else none).
    """

    name: str
    log: str
    spec: str | None = None
    gate: str | None = None


def load_manifest(path: str | os.PathLike[str]) -> tuple[AxisEntry, ...]:
    """Read a fleet manifest (TOML or CSV, by its suffix).

    TOML::

        [fleet]                 # optional defaults for every axis
        spec = "fast.toml"
        gate = "gate.toml"

        [[axis]]
        name = "x01"
        log = "logs/x01.h5"     # a file or a folder
        spec = "x01.toml"       # optional

    CSV: a header naming ``name`` and ``log`` and optionally ``spec`` and ``gate``; an empty
    cell is "not given".  Relative paths are relative to the manifest's folder.

    Raises
    ------
    InputFileError
        The manifest is missing.
    SchemaError
        Naming the axis (row) and the key: a missing name or log, an unknown key, a
        duplicate or unsafe name, no axis at all.
    """
    p = Path(path)
    if not p.is_file():
        from commission.errors import InputFileError

        raise InputFileError(f"{p}: no such manifest file")
    base = p.parent
    rows: list[dict[str, Any]] = []
    defaults: dict[str, Any] = {}
    if p.suffix.lower() == ".toml":
        try:
            import tomllib
        except ImportError:  # pragma: no cover - Python 3.10
            import tomli as tomllib  # type: ignore[no-redef]
        try:
            doc = tomllib.loads(p.read_text(encoding="utf-8"))
        except (tomllib.TOMLDecodeError, UnicodeDecodeError) as exc:
            raise SchemaError(f"{p}: not a TOML manifest ({exc})") from None
        for key in doc:
            if key not in ("fleet", "axis"):
                raise SchemaError(f"{p}: {key}: unknown table (known: fleet, axis)")
        defaults = doc.get("fleet", {})
        if not isinstance(defaults, dict):
            raise SchemaError(f"{p}: fleet: expected a table")
        for k in defaults:
            if k not in ("spec", "gate"):
                raise SchemaError(f"{p}: fleet.{k}: unknown key (known in [fleet]: spec, gate)")
        axes = doc.get("axis", [])
        if not isinstance(axes, list) or not all(isinstance(a, dict) for a in axes):
            raise SchemaError(f"{p}: axis: expected an array of tables ([[axis]])")
        rows = axes
        where = [f"axis[{i}]" for i in range(len(rows))]
    elif p.suffix.lower() == ".csv":
        with p.open(newline="", encoding="utf-8") as fh:
            reader = csv.DictReader(fh)
            header = [h.strip() for h in (reader.fieldnames or [])]
            for h in header:
                if h not in AXIS_KEYS:
                    raise SchemaError(f"{p}: column {h!r}: unknown (known: {', '.join(AXIS_KEYS)})")
            for need in ("name", "log"):
                if need not in header:
                    raise SchemaError(f"{p}: no {need!r} column (the header needs name and log)")
            rows = [{k.strip(): (v.strip() if isinstance(v, str) else v) for k, v in r.items() if k is not None
                     and v not in (None, "")} for r in reader]
        where = [f"row {i + 2}" for i in range(len(rows))]
    else:
        raise SchemaError(f"{p}: a fleet manifest is a .toml or a .csv file")
    if not rows:
        raise SchemaError(f"{p}: no axis listed")
    out: list[AxisEntry] = []
    seen: set[str] = set()
    for w, r in zip(where, rows):
        for k in r:
            if k not in AXIS_KEYS:
                raise SchemaError(f"{p}: {w}.{k}: unknown key (known: {', '.join(AXIS_KEYS)})")
        for k in ("name", "log"):
            if not isinstance(r.get(k), str) or not r[k]:
                raise SchemaError(f"{p}: {w}.{k}: missing (every axis needs a name and a log)")
        for k in ("spec", "gate"):
            if k in r and not isinstance(r[k], str):
                raise SchemaError(f"{p}: {w}.{k} = {r[k]!r}: expected a path")
        name = r["name"]
        if not _NAME.match(name) or name in ("fleet.json", "fleet.md", FLEET_FIGURE):
            raise SchemaError(f"{p}: {w}.name = {name!r}: a folder name of letters, digits and ._- (at most 64)")
        if name in seen:
            raise SchemaError(f"{p}: {w}.name = {name!r}: listed twice")
        seen.add(name)

        def res(v: str | None) -> str | None:
            return None if v is None else os.fspath(base / v) if not os.path.isabs(v) else v

        out.append(AxisEntry(name, res(r["log"]) or "", res(r.get("spec", defaults.get("spec"))),
                             res(r.get("gate", defaults.get("gate")))))
    return tuple(out)


def _files_of(path: str) -> list[str]:
    if os.path.isdir(path):
        return sorted(os.path.join(path, f) for f in os.listdir(path) if os.path.isfile(os.path.join(path, f)))
    return [path]


def inputs_sha256(entry: AxisEntry, options: Mapping[str, Any]) -> str | None:
    """sha256 over the axis's input files and the options that change its result (None: a file is missing)."""
    h = hashlib.sha256()
    try:
        for role, p in (("log", entry.log), ("spec", entry.spec), ("gate", entry.gate)):
            h.update(role.encode() + b"\0")
            if p is None:
                continue
            for f in _files_of(p):
                h.update(os.path.basename(f).encode() + b"\0" + bytes.fromhex(sha256_file(f)))
    except OSError:
        return None
    h.update(repr(sorted(options.items())).encode())
    h.update(commission.__version__.encode())
    return h.hexdigest()


@dataclass(frozen=True)
class FleetOptions:
    """What every axis is run with (picklable: sent to a Dask worker once).

    Attributes
    ----------
    out_dir : str
    seed, n_monte_carlo : int
        As ``run``'s ``--seed`` and ``--monte-carlo``.
    workers : int or None
        Threads of each axis's run (default: the machine's CPUs).
    figures, ident_figures : callable or None
        The CLI's figure writers (``run``'s).
    """

    out_dir: str
    seed: int
    n_monte_carlo: int
    workers: int | None = None
    figures: Callable[..., Any] | None = None
    ident_figures: Callable[..., Any] | None = None

    def hashed(self) -> dict[str, Any]:
        return {"seed": self.seed, "monte_carlo": self.n_monte_carlo}


def _units_of(ident: Mapping[str, Any]) -> dict[str, str]:
    from commission.units import parameter_units

    return dict(parameter_units(ident.get("units", {})))


def _certified_range(out: Path) -> dict[str, Any] | None:
    """The payload range a passed axis's controller.json claims (its ``validity``),
    ``{"payload_range": [lo, hi], "unit"}``, or None: the whole box (the payload the user stated, or the
    default one)."""
    v = read_json(out / CONTROLLER_NAME).get("validity")
    if not isinstance(v, Mapping):
        return None
    return {"payload_range": [float(x) for x in v["payload_range"]], "unit": str(v.get("unit", ""))}


def axis_row(entry: AxisEntry, out: Path, elapsed: float, inputs: str | None,
             also_tried: str | None = None) -> dict[str, Any]:
    """The fleet row of an axis whose run finished: verdict, parameters with units, margins, e_rms, what
    the certificate covers (a narrowed payload range), and for a failed gate whether the ARC was written
    flagged (safe, not better than the PID) and ``run``'s failed second try (``also_tried``)."""
    ident = read_json(out / "ident.json")
    val = check_validation(read_json(out / "validation.json"), str(out / "validation.json"))
    passed = bool(val.get("passed"))
    units = _units_of(ident)
    params = {}
    for k in ROW_PARAMETERS:
        v = (ident.get("parameters", {}).get(k) or {}).get("value")
        params[k] = {"value": v, "unit": units.get(k, "")}
    nominal = {r["name"]: r for r in val.get("runs", []) if "nominal" in r.get("tags", [])}
    e_rms = {}
    for name, r in sorted(nominal.items()):
        a, p = r["arc"].get("e_rms"), r["pid"].get("e_rms")
        e_rms[name] = {"arc": a, "pid": p, "ratio": (a / p) if isinstance(a, float) and isinstance(p, float) and p > 0
                       else None, "unit": ident.get("units", {}).get("q", "m")}
    worst = (val.get("margins") or {}).get("worst") or {}
    return {"name": entry.name, "status": "passed" if passed else "failed", "error": None,
            "validity": _certified_range(out) if passed else None,
            "not_better": (not passed) and (out / FLAGGED_NAME).is_file(), "also_tried": also_tried,
            "log": entry.log, "spec": entry.spec, "gate": entry.gate, "inputs_sha256": inputs,
            "validation_sha256": sha256_file(out / "validation.json"), "elapsed_s": elapsed,
            "parameters": params, "margins": {"arc": worst.get("arc"), "pid": worst.get("pid")}, "e_rms": e_rms,
            "failures": len(val.get("failures", [])), "outlier": None, "resumed": False}


def error_row(entry: AxisEntry, exc: BaseException, elapsed: float, inputs: str | None) -> dict[str, Any]:
    msg = str(exc).splitlines()[0] if str(exc) else ""
    return {"name": entry.name, "status": "error", "error": f"{type(exc).__name__}: {msg}", "log": entry.log,
            "spec": entry.spec, "gate": entry.gate, "inputs_sha256": inputs, "validation_sha256": None,
            "elapsed_s": elapsed, "parameters": None, "margins": None, "e_rms": None, "failures": None,
            "outlier": None, "resumed": False, "validity": None, "not_better": False, "also_tried": None}


def commission_axis(opts: FleetOptions, entry: AxisEntry) -> dict[str, Any]:
    """One executor task: ``run`` the axis into ``out_dir/<name>``; its row (an error row on any error)."""
    from commission.pipeline import run_all

    out = Path(opts.out_dir) / entry.name
    inputs = inputs_sha256(entry, opts.hashed())
    t0 = time.perf_counter()
    try:
        # A local executor inside the task: a fleet on Dask must not nest another cluster (COMMISSION_SCHEDULER).
        ro = run_all(entry.log, out, spec_path=entry.spec, gate_path=entry.gate, force=True, seed=opts.seed,
                     n_monte_carlo=opts.n_monte_carlo, workers=opts.workers, figures=opts.figures,
                     ident_figures=opts.ident_figures, executor=LocalExecutor(opts.workers))
        return axis_row(entry, out, time.perf_counter() - t0, inputs, also_tried=ro.also_tried)
    except Exception as exc:  # one bad axis never stops the others: its own row
        return error_row(entry, exc, time.perf_counter() - t0, inputs)


def _complete(row: Mapping[str, Any], out: Path) -> bool:
    if row.get("status") not in ("passed", "failed"):
        return False
    names = ["ident.json", "tuning.json", "validation.json", "report.md"]
    if row["status"] == "passed":
        names.append("controller.json")
    if not all((out / n).is_file() for n in names):
        return False
    return sha256_file(out / "validation.json") == row.get("validation_sha256")


def previous_rows(out_dir: Path) -> dict[str, dict[str, Any]]:
    """The rows of an earlier fleet.json in ``out_dir`` (empty when there is none or it does not load)."""
    p = out_dir / FLEET_JSON
    if not p.is_file():
        return {}
    try:
        doc = read_json(p)
    except Exception:
        return {}
    if not isinstance(doc, dict) or doc.get("kind") != FLEET_KIND:
        return {}
    return {r["name"]: r for r in doc.get("axes", []) if isinstance(r, dict) and isinstance(r.get("name"), str)}


def flag_outliers(rows: Sequence[dict[str, Any]]) -> dict[str, Any]:
    """Set each row's ``outlier`` (module docstring); returns the fleet's statistics per parameter."""
    import numpy as np

    stats: dict[str, Any] = {}
    ok = [r for r in rows if r.get("parameters")]
    for k in OUTLIER_PARAMETERS:
        vals = [(r, r["parameters"].get(k, {}).get("value")) for r in ok]
        vals = [(r, float(v)) for r, v in vals if isinstance(v, (int, float)) and math.isfinite(v)]
        if len(vals) < OUTLIER_MIN_AXES:
            stats[k] = None
            continue
        x = np.array([v for _r, v in vals])
        med = float(np.median(x))
        mad = float(np.median(np.abs(x - med)))
        scale = max(1.4826 * mad, OUTLIER_REL_FLOOR * abs(med))
        stats[k] = {"median": med, "mad": mad, "scale": scale, "unit": vals[0][0]["parameters"][k]["unit"]}
        for r, v in vals:
            z = abs(v - med) / scale if scale > 0 else 0.0
            o = r["outlier"] or {"flagged": False, "z": {}, "parameters": []}
            o["z"][k] = z
            if z > OUTLIER_Z:
                o["flagged"] = True
                o["parameters"].append(k)
            r["outlier"] = o
    return stats


def exit_code(rows: Sequence[Mapping[str, Any]]) -> int:
    """0 when every axis passed; 1 when a gate failed or an axis ended in an error."""
    return 0 if rows and all(r["status"] == "passed" for r in rows) else 1


def fleet_document(manifest: str, rows: list[dict[str, Any]], stats: Mapping[str, Any],
                   executor: Mapping[str, Any], elapsed: float) -> dict[str, Any]:
    return {
        "kind": FLEET_KIND, "schema_version": FLEET_SCHEMA_VERSION, "tool_version": commission.__version__,
        "created_utc": _dt.datetime.now(_dt.timezone.utc).strftime("%Y-%m-%dT%H:%M:%SZ"),
        "manifest": manifest, "manifest_sha256": sha256_file(manifest), "elapsed_s": elapsed,
        "executor": dict(executor),
        "outlier_rule": {"parameters": list(OUTLIER_PARAMETERS), "z": OUTLIER_Z, "rel_floor": OUTLIER_REL_FLOOR,
                         "scale": "max(1.4826 MAD, rel_floor |median|)", "min_axes": OUTLIER_MIN_AXES},
        "statistics": dict(stats),
        "summary": {"axes": len(rows), "passed": sum(r["status"] == "passed" for r in rows),
                    "failed": sum(r["status"] == "failed" for r in rows),
                    "errors": sum(r["status"] == "error" for r in rows),
                    "outliers": [r["name"] for r in rows if (r.get("outlier") or {}).get("flagged")],
                    "resumed": [r["name"] for r in rows if r.get("resumed")],
                    "exit_code": exit_code(rows)},
        "axes": rows,
    }


def _fmt(x: Any, spec: str = ".4g") -> str:
    return "—" if not isinstance(x, (int, float)) or not math.isfinite(x) else format(x, spec)


def verdict_text(row: Mapping[str, Any]) -> str:
    """An axis's verdict in a few words, for fleet.md and the console: PASSED with the payload range it is
    certified for when narrowed, FAILED with "safe, not better" when the ARC was written flagged, ERROR."""
    status = str(row["status"]).upper()
    v = row.get("validity")
    if row["status"] == "passed" and v:
        lo, hi = v["payload_range"]
        unit = v.get("unit", "")
        return (f"{status} as identified (no payload)" if hi <= 0 else
                f"{status} for payloads {_fmt(lo)} to {_fmt(hi)} {unit} only")
    if row["status"] == "failed" and row.get("not_better"):
        return f"{status}: safe, not better than the PID ({FLAGGED_NAME})"
    return status


def fleet_markdown(doc: Mapping[str, Any], figure: str | None) -> str:
    """fleet.md: one row per axis (verdict, parameters with units, margins, e_rms vs PID, time)."""
    from commission.report import md_code, md_text
    s = doc["summary"]
    lines = [f"# Fleet: {s['axes']} axes", "",
             f"{s['passed']} passed, {s['failed']} failed the gate, {s['errors']} errors; "
             f"outliers: {', '.join(s['outliers']) or 'none'}; exit code {s['exit_code']}.", ""]
    rows = doc["axes"]
    units = next((r["parameters"] for r in rows if r.get("parameters")), None)
    heads = [f"{k} ({units[k]['unit']})" if units else k for k in ROW_PARAMETERS]
    lines.append("| axis | verdict | " + " | ".join(heads) + " | ARC gain margin (dB) | ARC phase margin (deg) | "
                 "e_rms ARC/PID case1 | e_rms ARC/PID case2 | outlier | time (s) |")
    lines.append("|" + "---|" * (len(heads) + 8))
    for r in rows:
        if r["status"] == "error":
            lines.append(f"| {r['name']} | ERROR | " + " | ".join("—" for _ in heads) + " | — | — | — | — | — | "
                         f"{_fmt(r['elapsed_s'], '.1f')} |")
            continue
        p = r["parameters"]
        m = (r.get("margins") or {}).get("arc") or {}
        er = r.get("e_rms") or {}
        ratio = [_fmt((er.get(f"{c}/nominal") or {}).get("ratio"), ".3f") for c in ("case1", "case2")]
        o = r.get("outlier") or {}
        flag = ("**yes**: " + ", ".join(o.get("parameters", []))) if o.get("flagged") else "no"
        # The unit of a narrowed range is read back from the files (and from fleet.json on a resume): escaped.
        lines.append(f"| {r['name']} | {md_text(verdict_text(r))}{' (resumed)' if r.get('resumed') else ''} | "
                     + " | ".join(_fmt(p[k]["value"]) for k in ROW_PARAMETERS)
                     + f" | {_fmt(m.get('gain_margin_db'), '.1f')} | {_fmt(m.get('phase_margin_deg'), '.1f')} | "
                     f"{ratio[0]} | {ratio[1]} | {flag} | {_fmt(r['elapsed_s'], '.1f')} |")
    tried = [r for r in rows if r.get("also_tried")]
    if tried:
        lines += ["", "## Second tries", ""]
        # run's own sentence (it quotes the failed checks, whose scenario names come from the files): escaped.
        lines += [f"- **{r['name']}**: {md_text(r['also_tried'])}" for r in tried]
    errs = [r for r in rows if r["status"] == "error"]
    if errs:
        lines += ["", "## Errors", ""]
        # The log's path and the error's text come from the manifest and the files: escaped, as report.md does.
        lines += [f"- **{r['name']}** ({md_code(r['log'])}): {md_text(r['error'])}" for r in errs]
    lines += ["", "## Outliers", "",
              f"An axis is flagged when its identified {', '.join(OUTLIER_PARAMETERS)} sits more than {OUTLIER_Z} "
              f"robust scales from the fleet's median (scale = max(1.4826 MAD, {OUTLIER_REL_FLOOR:.0%} of the "
              f"median)); in a fleet of identical axes that is a mechanical fault worth a look.", ""]
    for k, st in doc["statistics"].items():
        if st:
            lines.append(f"- {k}: median {_fmt(st['median'])} {st['unit']}, scale {_fmt(st['scale'])} {st['unit']}")
    if figure:
        lines += ["", f"![{figure}]({figure})"]
    lines += ["", "Each axis's own report: `<name>/report.md`; its files are those of `commission run`."]
    return "\n".join(lines) + "\n"


FleetProgress = Callable[[dict[str, Any], int, int], None]


def run_fleet(manifest: str | os.PathLike[str], out_dir: str | os.PathLike[str], *, seed: int = 0,
              n_monte_carlo: int | None = None, workers: int | None = None, executor: Executor | None = None,
              figures: Callable[..., Any] | None = None, ident_figures: Callable[..., Any] | None = None,
              fleet_figure: Callable[[Mapping[str, Any], Path], Path | None] | None = None,
              force: bool = False, progress: FleetProgress | None = None) -> tuple[dict[str, Any], list[Path]]:
    """Commission every axis of ``manifest`` into ``out_dir`` (module docstring).

    Parameters
    ----------
    manifest : path
        TOML or CSV (:func:`load_manifest`).
    out_dir : path
        ``<name>/`` per axis, ``fleet.json``, ``fleet.md`` and ``fleet.png``.
    seed, n_monte_carlo, workers
        As ``run``'s (``workers``: threads of each axis's run).
    executor : Executor, optional
        Where the axes run (default: local, one axis after another).
    figures, ident_figures : callable, optional
        ``run``'s figure writers.
    fleet_figure : callable(doc, out_dir) -> path, optional
        Draws the fleet figure.
    force : bool
        Write into an ``out_dir`` that holds files but no fleet.json.
    progress : callable(row, done, total), optional
        Called as each axis is done.

    Returns
    -------
    (dict, list of Path)
        fleet.json's content and the summary files written.

    Raises
    ------
    SchemaError, InputFileError, UsageError
        A bad manifest or output folder (exit 2); no axis has run.
    """
    from commission.infra.files import Outputs
    from commission.jsonio import write_json_atomic, write_text_atomic
    from commission.validate import DEFAULT_MONTE_CARLO
    from commission.spec import check_flags

    n_mc = DEFAULT_MONTE_CARLO if n_monte_carlo is None else int(n_monte_carlo)
    check_flags(seed=seed, monte_carlo=n_mc, workers=workers)
    entries = load_manifest(manifest)
    out = Path(out_dir)
    if out.exists() and not out.is_dir():
        raise UsageError(f"--out-dir {out}: exists and is not a folder")
    if out.is_dir() and any(out.iterdir()) and not (out / FLEET_JSON).is_file() and not force:
        raise UsageError(f"--out-dir {out}: holds files but no {FLEET_JSON}; give an empty folder or pass --force")
    for e in entries:
        if os.path.abspath(e.log) == os.path.abspath(out / e.name):
            raise UsageError(f"{manifest}: axis {e.name}: its log is its own output folder")
    summary = Outputs(force=True, inputs=(os.fspath(manifest),))
    summary.add_dir(out, (FLEET_JSON, FLEET_MD, FLEET_FIGURE), "--out-dir")
    opts = FleetOptions(out_dir=os.fspath(out), seed=int(seed), n_monte_carlo=n_mc, workers=workers,
                        figures=figures, ident_figures=ident_figures)
    prev = previous_rows(out)
    todo: list[AxisEntry] = []
    rows: dict[str, dict[str, Any]] = {}
    for e in entries:
        old = prev.get(e.name)
        if (old is not None and old.get("inputs_sha256") is not None
                and old.get("inputs_sha256") == inputs_sha256(e, opts.hashed()) and _complete(old, out / e.name)):
            rows[e.name] = {**old, "resumed": True, "outlier": None}
        else:
            todo.append(e)
    ex = executor if executor is not None else LocalExecutor(1)
    t0 = time.perf_counter()
    done = 0
    for name in rows:
        done += 1
        if progress is not None:
            progress(rows[name], done, len(entries))
    out.mkdir(parents=True, exist_ok=True)
    for row in ex.map(commission_axis, opts, todo):
        rows[row["name"]] = row
        done += 1
        if progress is not None:
            progress(row, done, len(entries))
    ordered = [rows[e.name] for e in entries]
    stats = flag_outliers(ordered)
    doc = fleet_document(os.fspath(manifest), ordered, stats, ex.describe(), time.perf_counter() - t0)
    with summary:
        stage = summary.staging(out)
        fig = fleet_figure(doc, stage) if fleet_figure is not None else None
        write_json_atomic(stage / FLEET_JSON, doc)
        write_text_atomic(stage / FLEET_MD, fleet_markdown(doc, fig.name if fig is not None else None))
    written = [summary.final(stage / FLEET_JSON), summary.final(stage / FLEET_MD)]
    if fig is not None:
        written.append(summary.final(fig))
    return doc, written


__all__ = ["AxisEntry", "FleetOptions", "load_manifest", "run_fleet", "commission_axis", "flag_outliers", "verdict_text",
           "exit_code", "fleet_markdown", "inputs_sha256", "OUTLIER_Z", "OUTLIER_REL_FLOOR", "OUTLIER_PARAMETERS"]
