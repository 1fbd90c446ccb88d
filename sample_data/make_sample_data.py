"""Regenerate the bundled sample: a plan of ``commission excite``, recorded on a known-truth axis.

Usage (from the repository root)::

    python sample_data/make_sample_data.py            # rewrites sample_data/
    python sample_data/make_sample_data.py --out DIR  # writes elsewhere

The sample is the recommended practice, end to end:

1. ``sample_data/limits.toml`` states the machine's limits for the reference axis (CONTRACT §5);
2. :func:`commission.excite.plan_run` plans the run from it (friction ladder, moves, broadband
   injection), exactly as ``commission excite --spec sample_data/limits.toml`` does, and the plan is
   written as ``plan.json`` (the file ``commission identify --plan`` reads);
3. :func:`commission.excite.simulate_plan` plays the plan through the drive's holding loop on a
   simulated axis that the rigid model does not describe: a non-collocated structural mode (the
   encoder reads the load), half a sample of input delay, a quantizing encoder with a little noise.

Deterministic: one seeded ``numpy.random.Generator`` drives the only random part (encoder noise).
The CSV is written first at 12 significant digits and the HDF5 is written from the CSV's values, so
both files hold the same numbers.  ``truth.json`` records the true parameters (with units), the
plan's segments, and the sha256 of the log files and of ``plan.json``.
"""

from __future__ import annotations

import argparse
import shutil
from pathlib import Path
from typing import Any

import numpy as np

from commission.excite import load_excite_spec, plan_run, simulate_plan
from commission.jsonio import sha256_file, write_json_atomic
from commission.synth import AxisTruth, write_log_csv, write_log_h5

SEED = 20010601
HERE = Path(__file__).resolve().parent
SPEC_NAME = "limits.toml"
PLAN_NAME = "plan.json"
H5_NAME = "axis_excitation.h5"
CSV_NAME = "axis_excitation.csv"
TRUTH_NAME = "truth.json"

#: The reference axis of CONTRACT §5 (the paper's Y stage, in volts) as a two-mass axis: a
#: non-collocated 500 Hz mode (30 % of the mass behind the compliance, encoder on the load),
#: half a sample of input delay, a 1 um encoder with 0.1 um rms noise before quantization.
TRUTH = AxisTruth(
    M=0.027,  # V s^2/m
    B=0.273,  # V s/m
    fc=0.10,  # V
    fs=0.12,  # V
    vs=0.01,  # m/s
    xi=2.0,
    offset=0.01,  # V
    ripple_amp=0.01,  # V
    ripple_pitch=0.03,  # m
    lsb=1e-6,  # m
    sample_rate=2500.0,  # Hz
    u_unit="V",
    noise_std=0.1e-6,  # m, before quantization
    u_max=10.0,  # V
    mode_hz=500.0,  # Hz
    mode_damping=0.05,
    mode_ratio=0.3,
    mode_load_side=True,
    delay=0.5 / 2500.0,  # s (half a sample)
)


def build(out_dir: str | Path) -> dict[str, Any]:
    """Plan the run, record it on :data:`TRUTH` and write the sample's files into ``out_dir``.

    Returns
    -------
    dict
        The content written to ``truth.json``.
    """
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    spec_path = HERE / SPEC_NAME
    if out.resolve() != HERE:
        shutil.copyfile(spec_path, out / SPEC_NAME)
    plan = plan_run(load_excite_spec(spec_path))
    write_json_atomic(out / PLAN_NAME, plan.to_dict())
    data = simulate_plan(plan, TRUTH, np.random.default_rng(SEED))
    if np.max(np.abs(data["u"])) >= TRUTH.u_max:
        raise RuntimeError("the sample run hit the command rail; change limits.toml or TRUTH")
    csv_path, h5_path = out / CSV_NAME, out / H5_NAME
    write_log_csv(csv_path, data)
    cols = np.loadtxt(csv_path, delimiter=",", skiprows=1)
    write_log_h5(h5_path, {name: cols[:, i] for i, name in enumerate(data)}, q_unit="m", u_unit=TRUTH.u_unit)
    T = 1.0 / TRUTH.sample_rate
    q = cols[:, 1]
    truth = {
        "kind": "synthetic_truth",
        "schema_version": 1,
        "generator": "sample_data/make_sample_data.py",
        "seed": SEED,
        "axis": TRUTH.to_dict(),
        "spec": {"file": SPEC_NAME, "sha256": sha256_file(spec_path)},
        "log": {
            "samples": int(cols.shape[0]),
            "duration_s": float(cols[-1, 0] + T),
            "sample_rate_hz": TRUTH.sample_rate,
            "segments": [{"name": s.name, "purpose": s.purpose, "start_s": s.t_start, "stop_s": s.t_end}
                         for s in plan.segments],
            "peaks": {"u": {"unit": TRUTH.u_unit, "value": float(np.max(np.abs(cols[:, 2])))},
                      "q": {"unit": "m", "value": float(np.max(np.abs(q)))},
                      "v": {"unit": "m/s", "value": float(np.max(np.abs(np.diff(q))) / T)}},
        },
        "files": {name: {"sha256": sha256_file(out / name), "bytes": (out / name).stat().st_size}
                  for name in (H5_NAME, CSV_NAME, PLAN_NAME)},
    }
    write_json_atomic(out / TRUTH_NAME, truth)
    return truth


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", default=str(HERE), help="output folder (default: this script's folder)")
    args = ap.parse_args(argv)
    truth = build(args.out)
    for name, info in truth["files"].items():
        print(f"{name}: {info['bytes']} bytes, sha256 {info['sha256']}")
    print(f"{TRUTH_NAME}: {truth['log']['samples']} samples, {truth['log']['duration_s']:.3f} s")


if __name__ == "__main__":
    main()
