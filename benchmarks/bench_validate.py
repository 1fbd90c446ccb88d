"""Speed of ``commission validate``: the default matrix (12 fixed scenarios + 64 Monte-Carlo
plants) with both the ARC and the PID baseline, i.e. 152 closed-loop runs of 8-10 s at 2.5 kHz.

Target: <= 30 s on a 2-core machine for the whole command.  Prints medians (s) of

* ``validate()``: the simulations alone, on all CPUs and on one thread (the ratio is the
  parallel speed-up);
* ``write_outputs()``: validation.json, the five figures and report.md;
* the ``commission validate`` command end to end (a fresh process: imports, the numba
  cache load, simulations, figures), once.

On a shared machine the 1-thread/N-thread ratio understates the speed-up; the
CPU-time/wall-time ratio of the threaded run shows how many cores were kept busy.

Usage::

    python benchmarks/bench_validate.py [--repeat 3]

A short tuning of the paper's axis (CONTRACT §2 example, search budget 8) is made
first; it is not timed.
"""

from __future__ import annotations

import argparse
import os
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from commission.paper import reference_identification
from commission.spec import spec_from_mapping
from commission.tune import tune
from commission.validate import DEFAULT_MONTE_CARLO, validate, write_outputs



def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=3)
    args = ap.parse_args()
    tmp = Path(tempfile.mkdtemp(prefix="bench_validate_"))
    try:
        t = tune(reference_identification(delta_d=0.5), spec_from_mapping({"tune": {"budget": 8}}),
                 rng=np.random.default_rng(0), seed=0, ident_sha256="0" * 64)
        tpath = tmp / "tuning.json"
        t.save(str(tpath))
        validate(t, n_monte_carlo=2)  # compile / load the numba cache outside the timing
        load = os.getloadavg()[0] if hasattr(os, "getloadavg") else float("nan")
        n_runs = 2 * (12 + DEFAULT_MONTE_CARLO)
        cpus = os.cpu_count() or 1

        cpu_ratio: list[float] = []

        def timed(fn, repeat):
            out = []
            for _ in range(repeat):
                t0, c0 = time.perf_counter(), time.process_time()
                res = fn()
                out.append(time.perf_counter() - t0)
                cpu_ratio.append((time.process_time() - c0) / out[-1])
            return statistics.median(out), res

        par, result = timed(lambda: validate(t, seed=0), args.repeat)
        busy = statistics.median(cpu_ratio)
        ser, _ = timed(lambda: validate(t, seed=0, workers=1), max(1, args.repeat // 2))
        from commission.cli.plots_validate import validation_plots

        def outputs():
            d = tmp / f"out{time.perf_counter_ns()}"
            return write_outputs(result, t, "0" * 64, d, figures=validation_plots)

        wr, _ = timed(outputs, args.repeat)
        out_dir = tmp / "cli"
        t0 = time.perf_counter()
        proc = subprocess.run([sys.executable, "-c", "from commission.cli.main import main; main()", "validate", str(tpath), "--out-dir",
                               str(out_dir)], capture_output=True, text=True)
        cli = time.perf_counter() - t0
        print(f"1-min load average before the run: {load:.2f} on {cpus} CPUs (other processes compete for the cores)")
        print(f"default matrix: {n_runs} closed-loop runs (12 fixed + {DEFAULT_MONTE_CARLO} Monte-Carlo scenarios "
              f"x ARC, PID), {cpus} CPUs")
        print(f"validate() simulations, {cpus} threads: median {par:6.2f} s ({par / n_runs * 1e3:.1f} ms per run; "
              f"CPU time / wall time {busy:.2f}, about the number of cores kept busy)")
        print(f"validate() simulations, 1 thread:  median {ser:6.2f} s (speed-up {ser / par:.2f}x)")
        print(f"validation.json + 5 figures + report.md: median {wr:6.2f} s")
        print(f"`commission validate` end to end (fresh process, exit {proc.returncode}): {cli:6.2f} s "
              f"(target <= 30 s on 2 cores)")
    finally:
        shutil.rmtree(tmp, ignore_errors=True)


if __name__ == "__main__":
    main()
