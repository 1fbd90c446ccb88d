"""Monte-Carlo throughput of ``validate`` on the executors (issue 33, must show 2).

Prints, as medians of ``--repeat`` runs of ``validate(tuning, n_monte_carlo=N)``:

* plants/s on the local executor with 1 and 2 threads, and on a ``dask.distributed``
  LocalCluster of 2 worker processes (1 thread each), with the ratios to 1 thread.  A
  "plant" is one scenario simulated with the ARC and the PID baseline; the count includes
  validate's fixed scenarios (one task each) beside the N Monte-Carlo plants (chunks of
  :data:`commission.validate.MC_CHUNK`).
* the per-task cost (1-thread wall time / tasks) and the scheduler's overhead per task
  (a map of no-op tasks on the LocalCluster, wall time / tasks);
* a paper estimate of the wall time of ``validate --monte-carlo 10000`` on M machines of
  C cores: ``tasks x cost / (M C) + tasks x overhead`` (the scheduler handles tasks one
  after another; its per-task overhead does not shrink with more machines), plus the
  cluster's start, which is not counted.

Usage::

    python benchmarks/bench_scaling.py [--n 64] [--repeat 3]

The LocalCluster needs the optional extra (``pip install ".[dask]"``).  On a shared
machine the ratios understate the speed-up; the load average is printed beside them.
"""

from __future__ import annotations

import argparse
import math
import os
import statistics
import time

import numpy as np

from commission.infra.executor import DaskExecutor, LocalExecutor
from commission.paper import reference_identification
from commission.spec import spec_from_mapping
from commission.tune import tune
from commission.validate import MC_CHUNK, validate


def _noop(_shared, x):
    return x


def _time_validate(t, n, ex, repeat):
    walls = []
    res = None
    for _ in range(repeat):
        t0 = time.perf_counter()
        res = validate(t, n_monte_carlo=n, executor=ex)
        walls.append(time.perf_counter() - t0)
    return statistics.median(walls), res


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n", type=int, default=64, help="Monte-Carlo plants per validation")
    ap.add_argument("--repeat", type=int, default=3)
    args = ap.parse_args()
    t = tune(reference_identification(delta_d=0.5), spec_from_mapping({"tune": {"budget": 8}}),
             rng=np.random.default_rng(0), seed=0, ident_sha256="0" * 64)
    validate(t, n_monte_carlo=2, workers=1)  # load the numba cache outside the timing
    plants = len(validate(t, n_monte_carlo=args.n, workers=1).runs)
    n_fixed = plants - args.n
    tasks = n_fixed + math.ceil(args.n / MC_CHUNK)
    print(f"validate, reference axis: {plants} plants ({n_fixed} fixed + {args.n} Monte-Carlo) in {tasks} tasks, "
          f"ARC and PID each; median of {args.repeat}; load average {os.getloadavg()[0]:.1f} on "
          f"{os.cpu_count()} CPUs")
    rows = []
    w1, r1 = _time_validate(t, args.n, LocalExecutor(1), args.repeat)
    rows.append(("local, 1 thread", w1, r1))
    w2, r2 = _time_validate(t, args.n, LocalExecutor(2), args.repeat)
    rows.append(("local, 2 threads", w2, r2))
    overhead = warm = math.nan
    try:
        import distributed
    except ImportError:
        distributed = None
        print("dask/distributed not installed: the LocalCluster rows are left out (pip install \".[dask]\")")
    if distributed is not None:
        with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                                      dashboard_address=None) as cluster, distributed.Client(cluster) as client:
            ex = DaskExecutor(client=client)
            t0 = time.perf_counter()
            validate(t, n_monte_carlo=2, executor=ex)  # workers import commission and load the kernels
            warm = time.perf_counter() - t0
            wd, rd = _time_validate(t, args.n, ex, args.repeat)
            rows.append(("LocalCluster, 2 processes", wd, rd))
            n_noop = 400
            ovs = []
            for _ in range(args.repeat):
                t0 = time.perf_counter()
                list(ex.map(_noop, None, list(range(n_noop))))
                ovs.append((time.perf_counter() - t0) / n_noop)
            overhead = statistics.median(ovs)
    same = all(r.to_dict() | {"elapsed_s": 0, "executor": 0} == r1.to_dict() | {"elapsed_s": 0, "executor": 0}
               for _n, _w, r in rows)
    print(f"{'executor':<28}{'wall s':>9}{'plants/s':>11}{'vs 1 thread':>13}")
    for name, w, _r in rows:
        print(f"{name:<28}{w:>9.2f}{plants / w:>11.1f}{w1 / w:>12.2f}x")
    print(f"validation.json identical on every executor (times and executor aside): {same}")
    if distributed is not None:
        print(f"LocalCluster warm-up (first validation: each worker imports commission and loads the numba "
              f"kernels from the on-disk cache, once): {warm:.1f} s, not in the medians")
    cost = w1 / plants  # one plant (ARC + PID), 1 thread
    print(f"per-plant cost (1 thread): {cost * 1e3:.0f} ms (a Monte-Carlo task: {MC_CHUNK} plants, "
          f"{MC_CHUNK * cost:.2f} s); scheduler overhead per task (no-op map on the LocalCluster): "
          + (f"{overhead * 1e3:.1f} ms" if math.isfinite(overhead) else "not measured"))
    if math.isfinite(overhead):
        n_big, cores = 10000, 2
        big_plants = n_fixed + n_big
        big_tasks = n_fixed + math.ceil(n_big / MC_CHUNK)
        print(f"paper estimate, validate --monte-carlo {n_big} ({big_tasks} tasks), {cores} cores per machine: "
              f"plants x cost / (machines x cores) + tasks x overhead")
        print(f"{'machines':>10}{'wall s':>10}{'speed-up':>10}")
        base = big_plants * cost / cores + big_tasks * overhead
        for m in (1, 2, 4, 8, 16, 64):
            wall = big_plants * cost / (cores * m) + big_tasks * overhead
            print(f"{m:>10}{wall:>10.1f}{base / wall:>9.1f}x")
        print(f"bound: the scheduler's {big_tasks * overhead:.1f} s caps the speed-up over one machine at "
              f"{base / (big_tasks * overhead):.0f}x; larger chunks (MC_CHUNK) raise the cap")


if __name__ == "__main__":
    main()
