"""The adversarial kit: bad, hostile and interrupted inputs to every command, counted.

Run from the repository root with the tool installed::

    python benchmarks/adversarial_kit.py [--base DIR] [--only SUBSTRING] [--jobs N]

It first makes (or reuses, ``--base``) one good set of artifacts from the sample
(``commission run sample_data/axis_excitation.h5``), then runs each case as a user
or an attacker would -- a ``commission`` process on a damaged log, an edited
``ident.json``/``tuning.json``/``controller.json`` (checksums recomputed, as anyone
can), a forged or stripped signature, a hostile unit string, a signal at a chosen
moment, a full disk (a 64 KiB tmpfs, when run as root), a symlinked output folder
-- and classifies what happened:

traceback
    a Python traceback or "internal error" on stderr instead of a named refusal;
exit0-on-bad
    a case that must be refused (exit 2) exited 0;
partial
    after a refusal or a signal, an output of the command, a staging folder
    (``.*.tmp-*``) or a lock file is left where nothing was before;
data-loss
    a file that was in the output location before a refused run was changed or removed;
injection
    a generated file holds a hostile string verbatim (escaped text is harmless), or the
    exported C does not compile with ``-Werror``, or its replay prints the marker;
hang
    no answer within the case's time limit.

It prints one line per case and the totals; exit status 1 when any case is in a
failure class.  Cases run in parallel (``--jobs``, default 2): each in its own folder.
"""

from __future__ import annotations

import argparse
import concurrent.futures as cf
import hashlib
import json
import os
import shutil
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import adversarial_cases
from adversarial_cases import (FAILURES, MARKER, ROOT, SAMPLE, Case, _two_exports, commission_cmd, export_cases,
                               identify_cases, python_api_cases, signal_cases, symlink_lock_case, tune_cases,
                               validate_cases)


def snapshot(p: Path) -> dict[str, str]:
    if not p.exists():
        return {}
    files = [p] if p.is_file() else [f for f in p.rglob("*") if f.is_file()]
    return {str(f): hashlib.sha256(f.read_bytes()).hexdigest() for f in files}


def leftovers(work: Path) -> list[str]:
    return [str(f.relative_to(work)) for f in work.rglob("*") if ".tmp-" in f.name or f.name.endswith(".lock")]


def injected(p: Path, payload: str | None) -> bool:
    """Whether an output file holds ``payload`` verbatim (JSON outputs: its JSON-escaped form)."""
    if not p.exists() or not payload:
        return False
    files = [p] if p.is_file() else [f for f in p.rglob("*") if f.is_file()]
    forms = {payload.encode(errors="surrogatepass"), json.dumps(payload)[1:-1].encode()}
    return any(form in f.read_bytes() for f in files for form in forms)


def compile_and_replay(out: Path) -> tuple[bool, str]:
    """(injected, note): build the export with -Werror and run the replay."""
    cc = shutil.which("cc") or shutil.which("gcc")
    if cc is None:
        return False, "no C compiler"
    srcs = [str(out / n) for n in ("test_main.c", "commission_arc.c", "commission_arc_params.c")]
    b = subprocess.run([cc, "-std=c99", "-O2", "-ffp-contract=off", "-Wall", "-Wextra", "-Werror", "-o",
                        str(out / "replay"), *srcs, "-lm"], capture_output=True, text=True)
    if b.returncode != 0:
        return MARKER in b.stderr, "does not compile: " + b.stderr.strip().splitlines()[0][:100]
    r = subprocess.run([str(out / "replay"), str(out / "test_vectors.csv")], capture_output=True, text=True,
                       timeout=120)
    return MARKER in r.stdout + r.stderr, f"replay exit {r.returncode}"


def run_case(case: Case, scratch: Path) -> tuple[str, list[str], str]:
    work = Path(tempfile.mkdtemp(prefix="kit-", dir=scratch))
    mounted = False
    try:
        if case.needs_root and os.geteuid() != 0:
            return case.name, [], "skipped (needs root for a tmpfs)"
        if case.expect == "special":
            return case.name, *_run_two_exports(case, work)
        argv = case.setup(work)
        mounted = (work / "disk").is_dir() and case.needs_root
        out = work / case.out
        before = snapshot(out)
        before_names = set(before)
        env = {**os.environ, **case.env}
        t0 = time.monotonic()
        p = subprocess.Popen([*commission_cmd(), *argv], cwd=work, env=env, stdout=subprocess.PIPE,
                             stderr=subprocess.PIPE, text=True, errors="replace")
        if case.interrupt_after is not None:
            time.sleep(case.interrupt_after)
            if p.poll() is None:
                p.send_signal(signal.SIGINT)
        try:
            stdout, stderr = p.communicate(timeout=case.timeout)
        except subprocess.TimeoutExpired:
            p.kill()
            p.communicate()
            return case.name, ["hang"], f"no answer in {case.timeout:.0f} s"
        rc = p.returncode
        classes = []
        if "Traceback" in stderr or "internal error" in stderr:
            classes.append("traceback")
        after = snapshot(out)
        if case.expect == "refuse" and rc == 0:
            classes.append("exit0-on-bad")
        if rc not in (0,):
            if set(after) - before_names or leftovers(work):
                classes.append("partial")
            if any(before[f] != after.get(f) for f in before):
                classes.append("data-loss")
        elif case.interrupt_after is not None and leftovers(work):
            classes.append("partial")
        if case.interrupt_after is not None and rc == 0 and case.out == "out" and argv[0] == "export":
            if len(after) != 6:
                classes.append("partial")
        if injected(out, case.payload):
            classes.append("injection")
        note = (stderr.strip().splitlines() or [""])[-1][:110]
        if rc == 0 and case.compile_c and (out / "test_main.c").is_file():
            inj, cnote = compile_and_replay(out)
            if inj:
                classes.append("injection")
            note = cnote
        if case.expect == "ok" and rc != 0:
            note = "expected success: " + note
            classes.append("refused-good")
        return case.name, classes, f"exit {rc} ({time.monotonic() - t0:.1f} s): {note}"
    finally:
        if mounted:
            subprocess.run(["umount", str(work / "disk")], check=False)
        shutil.rmtree(work, ignore_errors=True)


def _run_two_exports(case: Case, work: Path) -> tuple[list[str], str]:
    _two_exports(work)
    procs = [subprocess.Popen([*commission_cmd(), "export", str(work / "controller.json"), "--out-dir", str(d)],
                              cwd=work, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
             for d in (work / "real", work / "link")]
    res = [(p.wait(timeout=180), p.communicate()[1]) for p in procs]
    classes = []
    if any("Traceback" in e for _, e in res):
        classes.append("traceback")
    rcs = sorted(r for r, _ in res)
    if rcs != [0, 2]:
        classes.append("data-loss" if rcs == [0, 0] else "partial")
    if leftovers(work):
        classes.append("partial")
    return classes, f"exit codes {rcs}"


def run_python_case(name: str, code: str, scratch: Path) -> tuple[str, list[str], str]:
    work = Path(tempfile.mkdtemp(prefix="kit-", dir=scratch))
    try:
        shutil.copy(adversarial_cases.BASE / "controller.json", work / "controller.json")
        prog = ("import sys\nfrom commission.runtime import load_controller\nfrom commission.errors import "
                "CommissionError\nP = sys.argv[1]\ntry:\n    " + code + "\nexcept CommissionError as e:\n"
                "    print('refused:', type(e).__name__, str(e)[:90]); sys.exit(2)\nprint('accepted'); sys.exit(0)\n")
        r = subprocess.run([sys.executable, "-c", prog, str(work / "controller.json")], capture_output=True,
                           text=True, timeout=120)
        classes = []
        if "Traceback" in r.stderr:
            classes.append("traceback")
        if r.returncode == 0:
            classes.append("exit0-on-bad")
        return name, classes, (r.stdout.strip() or r.stderr.strip().splitlines()[-1])[:110]
    finally:
        shutil.rmtree(work, ignore_errors=True)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--base", type=Path, help="folder with ident.json, tuning.json, controller.json of the sample "
                                              "(default: made now with commission run)")
    ap.add_argument("--only", default="", help="run only the cases whose name contains this")
    ap.add_argument("--jobs", type=int, default=2)
    args = ap.parse_args()
    scratch = Path(tempfile.mkdtemp(prefix="commission-kit-"))
    try:
        if args.base is None:
            args.base = scratch / "base"
            print(f"making the base artifacts: commission run {SAMPLE.relative_to(ROOT)} ...", flush=True)
            subprocess.run([*commission_cmd(), "-q", "run", str(SAMPLE), "--out-dir", str(args.base)], check=True)
        adversarial_cases.BASE = args.base.resolve()
        cases = [*identify_cases(), *tune_cases(), *validate_cases(), *export_cases(), *signal_cases(),
                 symlink_lock_case()]
        cases = [c for c in cases if args.only in c.name]
        results = []
        with cf.ThreadPoolExecutor(max(1, args.jobs)) as ex:
            futs = [ex.submit(run_case, c, scratch) for c in cases]
            futs += [ex.submit(run_python_case, n, code, scratch) for n, code in python_api_cases()
                     if args.only in n]
            for f in cf.as_completed(futs):
                name, classes, note = f.result()
                results.append((name, classes, note))
                print(f"{'FAIL ' + ','.join(classes) if classes else 'ok':<28} {name:<58} {note}", flush=True)
        print()
        print(f"{len(results)} cases")
        failed = 0
        for cls in (*FAILURES, "refused-good"):
            n = sum(cls in c for _, c, _ in results)
            failed += n
            print(f"  {cls:<14} {n}")
        return 1 if failed else 0
    finally:
        shutil.rmtree(scratch, ignore_errors=True)


if __name__ == "__main__":
    sys.exit(main())
