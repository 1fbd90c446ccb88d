"""Regenerate the bundled sample excitation log and its known truth.

Usage (from the repository root)::

    python sample_data/make_sample_data.py            # rewrites sample_data/
    python sample_data/make_sample_data.py --out DIR  # writes elsewhere

Deterministic: one seeded ``numpy.random.Generator`` drives the only random
part (encoder noise).  The CSV is written first at 12 significant digits and
the HDF5 is written from the CSV's values, so both files hold the same numbers.
``truth.json`` records the parameters (with units), the excitation plan, where
the ladder legs and the multisine are, and the sha256 of both log files.
"""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any

import numpy as np

from commission.jsonio import sha256_file, write_json_atomic
from commission.synth import AxisTruth, ExcitationPlan, simulate_excitation, write_log_csv, write_log_h5

SEED = 20010601
H5_NAME = "axis_excitation.h5"
CSV_NAME = "axis_excitation.csv"
TRUTH_NAME = "truth.json"

#: A single epoxy-core axis close to the paper's Y stage (section 4.1), in volts.
TRUTH = AxisTruth(
    M=0.032,  # V s^2/m (paper: 0.027 unloaded)
    B=0.25,  # V s/m
    fc=0.10,  # V
    fs=0.12,  # V
    vs=0.01,  # m/s
    xi=2.0,
    offset=0.01,  # V
    ripple_amp=0.01,  # V
    ripple_pitch=0.03,  # m
    lsb=0.5e-6,  # m
    sample_rate=2500.0,  # Hz
    u_unit="V",
    noise_std=0.1e-6,  # m, before quantization
    u_max=10.0,  # V
)

#: The default commissioning run (about 43 s).
PLAN = ExcitationPlan()


def build(out_dir: str | Path) -> dict[str, Any]:
    """Simulate the run and write the three files into ``out_dir``.

    Returns
    -------
    dict
        The content written to ``truth.json``.
    """
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    data = simulate_excitation(TRUTH, PLAN, np.random.default_rng(SEED))
    if np.max(np.abs(data["u"])) >= TRUTH.u_max:
        raise RuntimeError("the sample run hit the command rail; change PLAN or TRUTH")
    csv_path, h5_path = out / CSV_NAME, out / H5_NAME
    write_log_csv(csv_path, data)
    cols = np.loadtxt(csv_path, delimiter=",", skiprows=1)
    write_log_h5(h5_path, {name: cols[:, i] for i, name in enumerate(data)}, q_unit="m", u_unit=TRUTH.u_unit)
    ref = PLAN.reference(TRUTH.sample_rate)
    truth = {
        "kind": "synthetic_truth",
        "schema_version": 1,
        "generator": "sample_data/make_sample_data.py",
        "seed": SEED,
        "axis": TRUTH.to_dict(),
        "plan": PLAN.to_dict(),
        "log": {
            "samples": int(ref.t.size),
            "duration_s": float(ref.t[-1]),
            "sample_rate_hz": TRUTH.sample_rate,
            "legs": [{"start_s": leg.start, "stop_s": leg.stop, "velocity_m_per_s": leg.velocity}
                     for leg in ref.legs],
            "multisine": {"start_s": ref.multisine[0], "stop_s": ref.multisine[1]},
        },
        "files": {name: {"sha256": sha256_file(out / name), "bytes": (out / name).stat().st_size}
                  for name in (H5_NAME, CSV_NAME)},
    }
    write_json_atomic(out / TRUTH_NAME, truth)
    return truth


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", default=str(Path(__file__).resolve().parent),
                    help="output folder (default: this script's folder)")
    args = ap.parse_args(argv)
    truth = build(args.out)
    for name, info in truth["files"].items():
        print(f"{name}: {info['bytes']} bytes, sha256 {info['sha256']}")
    print(f"{TRUTH_NAME}: {truth['log']['samples']} samples, {truth['log']['duration_s']:.3f} s")


if __name__ == "__main__":
    main()
