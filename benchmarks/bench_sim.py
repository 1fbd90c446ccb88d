"""Speed of the closed-loop simulator (targets from the project brief).

* one 10-s ARC run, Set 1, 2.5 kHz, 10 plant sub-steps: median over repeats, target <= 10 ms
  (issue 33; the project brief's first target was 50 ms), wall and CPU;
* a batch of 256 ARC runs on 256 different plants (Set-1 trajectory): target <= 10 s;
* CPU per run of a batch on one thread, each run alone and two runs' plants interleaved
  (``simulate_batch(interleave=...)``, :func:`commission.controllers.simulate.closed_loop_pair_kernel`),
  on the rigid plants and on a plant with a 500 Hz mode, and the ratio;
* speed-up against the same loop run as plain Python (every compiled kernel
  replaced by its ``.py_func``) on a shorter horizon, scaled to 10 s.

Run: ``/work/venv/bin/python benchmarks/bench_sim.py [--controller PID|ARC]``.
Prints figures; asserts nothing.
"""

from __future__ import annotations

import argparse
import contextlib
import os
import statistics
import time

import numpy as np
from numba.core.registry import CPUDispatcher

import commission.controllers.metrics as _metrics
import commission.controllers.pid as _pid
import commission.controllers.plant as _plant
import commission.controllers.simulate as _sim
from commission.controllers.plant import plant_vector
from commission.controllers.simulate import simulate, simulate_batch
from commission.controllers.trajectory import sinusoid
from commission.paper import TS, paper_controller, scenario

#: Issue 33: one 10-s scenario (Set 1, ARC, 10 plant sub-steps) in at most this time, ms (the
#: project brief's first target was 50 ms).
KERNEL_TARGET_MS = 10.0


@contextlib.contextmanager
def pure_python():
    """Swap every compiled kernel in the simulator's modules for its Python original."""
    import commission.controllers.arc as _arc

    saved = []
    for mod in (_sim, _plant, _pid, _metrics, _arc):
        for name, obj in list(vars(mod).items()):
            if isinstance(obj, CPUDispatcher):
                saved.append((mod, name, obj))
                setattr(mod, name, obj.py_func)
    try:
        yield
    finally:
        for mod, name, obj in saved:
            setattr(mod, name, obj)


def random_plants(rng: np.random.Generator, n: int) -> np.ndarray:
    """``n`` plants around the reference one (mass 0.02..0.12, friction and ripple +-30 %)."""
    rows = []
    for _ in range(n):
        fc = 0.1 * rng.uniform(0.7, 1.3)
        rows.append(plant_vector(M=rng.uniform(0.02, 0.12), B=0.273 * rng.uniform(0.7, 1.3), fc=fc,
                                 fs=fc * rng.uniform(1.0, 1.4), vs=0.01, xi=2.0,
                                 ripple_amp=0.01 * rng.uniform(0.5, 1.5), ripple_pitch=0.03))
    return np.stack(rows)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--controller", choices=("ARC", "PID"), default="ARC")
    ap.add_argument("--repeats", type=int, default=21)
    ap.add_argument("--batch", type=int, default=256)
    ap.add_argument("--python-horizon", type=float, default=0.4, help="s simulated in plain Python")
    args = ap.parse_args()

    sc = scenario("set1")
    kind, ctrl = paper_controller(args.controller, TS)
    print(f"controller {args.controller}; {sc.traj.n} samples, 10 sub-steps; {os.cpu_count()} CPUs")

    t0 = time.perf_counter()
    r = simulate(sc.plant_p, kind, ctrl, sc.traj)
    print(f"first call (includes loading/compiling kernels): {time.perf_counter() - t0:.2f} s; "
          f"diverged={r.diverged}")

    times, cpu = [], []
    for _ in range(args.repeats):
        t0, c0 = time.perf_counter(), time.process_time()
        simulate(sc.plant_p, kind, ctrl, sc.traj)
        times.append(time.perf_counter() - t0)
        cpu.append(time.process_time() - c0)
    med = statistics.median(times)
    print(f"single 10-s run: median {med * 1e3:.1f} ms wall over {args.repeats} (min {min(times) * 1e3:.1f} ms;"
          f" median CPU {statistics.median(cpu) * 1e3:.1f} ms)  target <= {KERNEL_TARGET_MS:.0f} ms (issue 33; "
          f"{'met' if med * 1e3 <= KERNEL_TARGET_MS else 'NOT met'} on wall, "
          f"{'met' if statistics.median(cpu) * 1e3 <= KERNEL_TARGET_MS else 'NOT met'} on CPU)")
    print(f"load average (1 min) {os.getloadavg()[0]:.1f} on {os.cpu_count()} CPUs")

    plants = random_plants(np.random.default_rng(2024), args.batch)
    simulate_batch(plants[:2], kind, ctrl, sc.traj)  # warm the batch entry point
    t0, c0 = time.perf_counter(), time.process_time()
    b = simulate_batch(plants, kind, ctrl, sc.traj)
    tb, cb = time.perf_counter() - t0, time.process_time() - c0
    print(f"batch of {args.batch} plants: {tb:.2f} s wall, {cb:.2f} s CPU ({b.diverged.sum()} diverged)"
          f"  target <= 10 s")

    modal = np.stack([plant_vector(M=0.027 * (1 + 0.01 * i), B=0.273, fc=0.1, fs=0.12, vs=0.01, ripple_amp=0.01,
                                   ripple_pitch=0.03, mode_hz=500.0, mode_damping=0.05, mode_ratio=0.5,
                                   mode_load_side=True) for i in range(32)])
    for label, rows in (("rigid", plants[:32]), ("500 Hz mode", modal)):
        per: dict[bool, list[float]] = {False: [], True: []}
        for _ in range(9):  # alone and paired alternated: a noisy machine's drift falls on both
            for inter in (False, True):
                c0 = time.process_time()
                simulate_batch(rows, kind, ctrl, sc.traj, workers=1, interleave=inter)
                per[inter].append((time.process_time() - c0) / rows.shape[0])
        alone, paired = statistics.median(per[False]), statistics.median(per[True])
        print(f"one thread, {rows.shape[0]} {label} plants, CPU per 10-s run: alone {alone * 1e3:.1f} ms "
              f"(min {min(per[False]) * 1e3:.1f}), interleaved in pairs {paired * 1e3:.1f} ms "
              f"(min {min(per[True]) * 1e3:.1f}); ratio of medians {alone / paired:.2f}, of minima "
              f"{min(per[False]) / min(per[True]):.2f} (9 each)  target <= {KERNEL_TARGET_MS:.0f} ms per run")

    short = sinusoid(args.python_horizon, TS)
    fast = [0.0] * 3
    for i in range(3):
        t0 = time.perf_counter()
        simulate(sc.plant_p, kind, ctrl, short)
        fast[i] = time.perf_counter() - t0
    slow = []
    with pure_python():
        for _ in range(3):
            t0 = time.perf_counter()
            rp = simulate(sc.plant_p, kind, ctrl, short)
            slow.append(time.perf_counter() - t0)
    rc = simulate(sc.plant_p, kind, ctrl, short)
    same = np.array_equal(rp.u, rc.u)
    scale = sc.traj.n / short.n
    py10 = statistics.median(slow) * scale
    print(f"plain Python: {statistics.median(slow):.2f} s for {args.python_horizon} s "
          f"-> {py10:.1f} s per 10-s run (scaled); compiled/python ratio 1:{py10 / med:.0f}; "
          f"identical output: {same}")


if __name__ == "__main__":
    main()
