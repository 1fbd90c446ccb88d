"""Where ``commission run`` spends its time on the sample: wall and CPU seconds per stage (issue 33).

``bench_quickstart.py`` times the whole command; this script splits one run into what a plan
to make it faster needs to know:

* **imports**: the modules ``commission run`` loads (the CLI, scipy, numba, matplotlib, pycma);
* **identify**: :func:`commission.identification.identify_log` (the fit, the ripple search,
  the frequency response);
* **tune**: the PID yardstick, the payload box and the gain search
  (:func:`commission.tune.tune_from`);
* **validate**: the simulations of validate's scenarios and Monte-Carlo plants;
* **outputs**: the verdict's linear checks, the report, the figures and the files
  (:func:`commission.validate.write_outputs`).

Each run is a fresh process that calls :func:`commission.pipeline.run_all` exactly as
``commission run`` does (the same figure writers), with a progress callback that marks where
each stage ends; a run whose first try fails the gate and tries again (the axis as identified)
adds its second tune and validate to the same rows.  CPU is the process's own
(``time.process_time``, every thread) plus the forked figure processes' (``RUSAGE_CHILDREN``),
charged to the stage in which they ended.  One untimed run first writes the numba cache and
the bytecode.  Printed: the median over ``--runs`` of each stage's wall and CPU seconds and
its share of the total CPU, and the search's candidate count from tuning.json.

Run from the repository root with the package installed:
``python benchmarks/bench_run_stages.py [--runs 3]``.  Prints figures; asserts nothing.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
SAMPLE = ROOT / "sample_data" / "axis_excitation.h5"
STAGES = ("imports", "identify", "tune", "validate", "outputs")

#: The child: times one ``run_all`` and prints one JSON line of per-stage (wall, CPU) seconds.
CHILD = r"""
import json, resource, sys, time
def clock():
    ch = resource.getrusage(resource.RUSAGE_CHILDREN)
    return time.perf_counter(), time.process_time() + ch.ru_utime + ch.ru_stime
t0 = clock()
from commission.cli.plots import identification_plots
from commission.cli.plots_validate import validation_plots
from commission.pipeline import run_all
marks = [("imports", clock())]
cur = ["identify"]
def progress(stage, done, total):
    # a stage ends where the next one reports first; identify and validate at their last step
    if stage != cur[0]:
        marks.append((cur[0], clock()))
        cur[0] = stage
    if stage in ("identify", "validate") and done == total and cur[0] == stage:
        marks.append((stage, clock()))
        cur[0] = "tune" if stage == "identify" else "outputs"
run_all(sys.argv[1], sys.argv[2], progress=progress, figures=validation_plots, ident_figures=identification_plots)
marks.append((cur[0], clock()))
out = {s: [0.0, 0.0] for s in %(stages)r}
prev = t0
for name, now in marks:
    out[name][0] += now[0] - prev[0]
    out[name][1] += now[1] - prev[1]
    prev = now
print(json.dumps(out))
""" % {"stages": STAGES}


def one(out_dir: Path) -> dict[str, list[float]]:
    env = {k: v for k, v in os.environ.items() if k != "PYTHONDONTWRITEBYTECODE"}
    r = subprocess.run([sys.executable, "-c", CHILD, str(SAMPLE), str(out_dir)], cwd=ROOT, env=env,
                       capture_output=True, text=True)
    if r.returncode != 0:
        raise SystemExit(f"the timed run failed (exit {r.returncode}):\n{r.stderr[-2000:]}")
    return json.loads(r.stdout.strip().splitlines()[-1])


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", type=int, default=3)
    args = ap.parse_args()
    load0 = os.getloadavg()[0]
    with tempfile.TemporaryDirectory() as tmp:
        one(Path(tmp) / "warm")  # the numba cache and the bytecode
        res = [one(Path(tmp) / f"r{i}") for i in range(args.runs)]
        search = json.loads((Path(tmp) / "r0" / "tuning.json").read_text())["search"]
    med = {s: (statistics.median(r[s][0] for r in res), statistics.median(r[s][1] for r in res)) for s in STAGES}
    total_cpu = sum(c for _, c in med.values())
    total_wall = sum(w for w, _ in med.values())
    print(f"commission run {SAMPLE.relative_to(ROOT)}, median of {args.runs} fresh processes "
          f"(load average {load0:.2f} at the start, {os.getloadavg()[0]:.2f} at the end, {os.cpu_count()} cores)")
    print(f"{'stage':10s} {'wall s':>8s} {'CPU s':>8s} {'CPU share':>10s}")
    for s in STAGES:
        w, c = med[s]
        print(f"{s:10s} {w:8.1f} {c:8.1f} {100 * c / total_cpu:9.0f}%")
    print(f"{'total':10s} {total_wall:8.1f} {total_cpu:8.1f}")
    print(f"search: {search.get('n_evaluations')} candidates in {search.get('generations')} generations "
          f"(budget {search.get('budget')})")


if __name__ == "__main__":
    main()
