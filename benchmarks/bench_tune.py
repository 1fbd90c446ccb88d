"""Speed of ``commission tune`` with the default spec on the paper's axis.

Default budget: 144 candidate gain sets of the CMA-ES search, each first linearised (its
stability margins) and, when it meets them, simulated on the tuning scenarios (12 fixed +
the robustness ones + 16 box corners + 4 largest-force plants + 6 interior payloads); plus the
discrete-feasibility checks of the candidates that meet the gate, the PID baseline, the hold-out
selection and the robust feasibility report of the chosen gains.

Prints medians (s) over ``--repeat`` runs of

* ``tune()`` on all CPUs (the pipeline function, inputs already loaded);
* the search's share: one generation of 8 candidates on the tuning set, and one
  discrete-feasibility check, measured separately;
* the ``commission tune`` command end to end in a fresh process, once (imports,
  numba cache load, search, writing tuning.json);
* the same command on the slow worst case: the paper's axis at 4 kHz with a 0.2 m/s,
  4 m/s^2 envelope (Case 1 lasts 31 s), where one candidate simulates 3.4x the work
  (the default budget is kept: the run takes longer);
* the same command on random axis 16 (:func:`commission.synth.random_axis`, 5 kHz,
  0.55 um encoder; its log simulated and identified first, not timed).

The identification is the CONTRACT §2 example document (the paper's axis, box (53)).

Usage::

    python benchmarks/bench_tune.py [--repeat 3]
"""

from __future__ import annotations

import argparse
import dataclasses
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from commission.artifacts import Identification
from commission.controllers.arc import arc_pack
from commission.controllers.design import KIND_ARC, discrete_feasibility
from commission.jsonio import write_json_atomic
from commission.scenarios import case1_trajectory, case2_trajectory, tuning_scenarios
from commission.spec import default_spec
from commission.identification import identify_log
from commission.synth import ExcitationPlan, random_axis, simulate_excitation, write_log_h5
from commission.tune import Evaluator, base_arc_gains, tune
from commission.tuning import Tuning

CONTRACT_EXAMPLE = {
    "kind": "identification", "schema_version": 1, "units": {"u": "V", "q": "m"},
    "parameters": {"M": {"value": 0.027, "std": 0.0001}, "B": {"value": 0.27, "std": 0.002},
                   "fc": {"value": 0.10, "std": 0.001}, "fs": {"value": 0.12, "std": 0.002},
                   "vs": {"value": 0.01, "std": 0.001}, "xi": {"value": 2.0, "std": 0.1},
                   "offset": {"value": 0.0, "std": 0.001}},
    "fit": {"relative_error": 0.04, "condition_number": 26.0, "validation_relative_error": 0.06},
    "theta": {"nominal": [37.0, 10.1, 0.0], "min": [8.3, 2.4, -50.0], "max": [50.0, 17.5, 50.0]},
    "delta_d": 0.5, "friction_compensation": {"level": 0.1, "slope": 900.0},
}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=3)
    args = ap.parse_args()
    ident = Identification.from_dict(CONTRACT_EXAMPLE)
    spec = default_spec()
    print(f"cpus: {os.cpu_count()}  budget: {spec.budget}  sample rate: {spec.sample_rate:g} Hz")

    # warm the numba caches (not timed)
    tune(ident, dataclasses.replace(spec, budget=2), rng=np.random.default_rng(0), seed=0, ident_sha256="0" * 64)

    ev = Evaluator(tuning_scenarios(ident, spec, rng=np.random.default_rng(0)), spec)
    base = base_arc_gains(ident, spec)
    trajs = [case1_trajectory(spec).render(spec.period), case2_trajectory(spec).render(spec.period)]
    gen, feas = [], []
    for _ in range(args.repeat):
        t0 = time.perf_counter()
        ev.scores(KIND_ARC, [arc_pack(base)] * 8)
        gen.append(time.perf_counter() - t0)
        t0 = time.perf_counter()
        discrete_feasibility(KIND_ARC, arc_pack(base), ident.theta.min, ident.theta.max, trajs)
        feas.append(time.perf_counter() - t0)
    print(f"one generation (8 candidates x {len(ev.scenarios)} scenarios): median {statistics.median(gen):.2f} s")
    print(f"one discrete-feasibility check: median {statistics.median(feas):.2f} s")

    wall, cpu = [], []
    for r in range(args.repeat):
        c0, t0 = time.process_time(), time.perf_counter()
        t = tune(ident, spec, rng=np.random.default_rng(r), seed=r, ident_sha256="0" * 64)
        wall.append(time.perf_counter() - t0)
        cpu.append(time.process_time() - c0)
        print(f"  run {r}: {wall[-1]:.1f} s wall, {cpu[-1]:.1f} s CPU, cost {t.search.cost_best:.3f}, "
              f"feasible {t.feasibility['arc'].holds}")
    print(f"tune(): median {statistics.median(wall):.1f} s wall (CPU/wall {statistics.median(cpu) / statistics.median(wall):.2f})")

    with tempfile.TemporaryDirectory() as d:
        write_json_atomic(Path(d) / "ident.json", CONTRACT_EXAMPLE)
        exe = Path(sys.executable).with_name("commission")
        t0 = time.perf_counter()
        subprocess.run([str(exe), "tune", str(Path(d) / "ident.json"), "--out", str(Path(d) / "tuning.json")],
                       check=True, capture_output=True)
        print(f"commission tune (fresh process, end to end): {time.perf_counter() - t0:.1f} s  (target <= 120 s)")
        (Path(d) / "slow.toml").write_text("[controller]\nsample_rate = 4000.0\n"
                                           "[trajectory]\nv_max = 0.2\na_max = 4.0\n")
        t0 = time.perf_counter()
        subprocess.run([str(exe), "tune", str(Path(d) / "ident.json"), "--out", str(Path(d) / "slow.json"),
                            "--spec", str(Path(d) / "slow.toml")], check=True, capture_output=True, text=True)
        wall_slow = time.perf_counter() - t0
        se = Tuning.load(str(Path(d) / "slow.json")).search
        print(f"commission tune, 4 kHz and 0.2 m/s (fresh process): {wall_slow:.1f} s  (target <= 120 s); "
              f"{se.n_evaluations} candidates")
        truth = random_axis(np.random.default_rng(16))
        write_log_h5(Path(d) / "a16.h5", simulate_excitation(truth, ExcitationPlan(), np.random.default_rng(1016)))
        write_json_atomic(Path(d) / "a16.json", identify_log(str(Path(d) / "a16.h5")).ident.to_dict())
        t0 = time.perf_counter()
        subprocess.run([str(exe), "tune", str(Path(d) / "a16.json"), "--out", str(Path(d) / "a16_tuning.json")],
                       check=False, capture_output=True)
        wall16 = time.perf_counter() - t0
        se = Tuning.load(str(Path(d) / "a16_tuning.json")).search
        print(f"commission tune, random axis 16 (fresh process): {wall16:.1f} s  (target <= 120 s); "
              f"{se.n_evaluations} candidates, {se.n_feasible} met every constraint")


if __name__ == "__main__":
    main()
