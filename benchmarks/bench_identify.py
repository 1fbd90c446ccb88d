"""Time ``fit_axis`` on a 1,000,000-sample simulated excitation log.

Target: at most 5 s (median) on 2 cores for the default path (friction ladder
present, ``friction="stribeck"``, with a ripple pitch).  Also prints the Coulomb
fit and, for information, the whole-log Stribeck fallback (``use_steady=False``),
the frequency response of that log (no broadband content) and of a short log
with a broadband injection and a mode (``identify/frf/``), and what reading an HDF5 log in the isolated child process costs against reading
it in this process (the same 10^6-sample log written to a temporary .h5).

Run: ``python benchmarks/bench_identify.py [--runs 3]``
"""

from __future__ import annotations

import argparse
import importlib.util
import pathlib
import statistics
import tempfile
import time

import h5py
import numpy as np

from commission.logs import hdf5 as logs
from commission.identify import fit_axis, frequency_response
from commission.synth import AxisTruth, ExcitationPlan, simulate_excitation

TARGET_S = 5.0
ROOT = pathlib.Path(__file__).resolve().parents[1]


def _generator():
    """The small closed-loop log generator of the recovery tests."""
    path = ROOT / "tests" / "test_identify_recovery.py"
    spec = importlib.util.spec_from_file_location("_identify_recovery", path)
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def _median_time(fn, runs: int) -> tuple[float, object]:
    times, out = [], None
    for _ in range(runs):
        t0 = time.perf_counter()
        out = fn()
        times.append(time.perf_counter() - t0)
    return statistics.median(times), out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", type=int, default=3)
    args = ap.parse_args()

    gen = _generator()
    truth = dict(M=0.027, B=0.273, fc=0.10, fs=0.12, vs=0.01, xi=2.0, offset=0.01, ripple_amp=0.01,
                 ripple_pitch=0.03)
    # 10 kHz, 0.1 um encoder: ~20 s of friction ladder + 80 s of multisine, just over 10^6 samples
    t, q, u = gen.simulate(truth, 10_000.0, rng=np.random.default_rng(0), lsb=1e-7, noise=0.001, multisine_s=80.0)
    print(f"log: {t.size:,} samples at 10 kHz ({t[-1]:.1f} s)")

    med, fit = _median_time(lambda: fit_axis(t, q, u, friction="stribeck", ripple_pitch=0.03), args.runs)
    err = {k: fit.value(k) / truth[k] - 1 for k in ("M", "B", "fc", "fs", "vs")}
    print(f"fit_axis stribeck (method {fit.method}): median {med:.2f} s over {args.runs} runs "
          f"(target <= {TARGET_S:.0f} s: {'PASS' if med <= TARGET_S else 'FAIL'}); "
          + ", ".join(f"{k} {100 * e:+.2f} %" for k, e in err.items()))
    med, fit = _median_time(lambda: fit_axis(t, q, u, friction="coulomb", ripple_pitch=0.03), args.runs)
    print(f"fit_axis coulomb  (method {fit.method}): median {med:.2f} s")
    med, fit = _median_time(lambda: fit_axis(t, q, u, friction="stribeck", ripple_pitch=0.03, use_steady=False), 1)
    print(f"fit_axis stribeck whole-log fallback (use_steady=False): {med:.2f} s (1 run, information only)")

    med, fr = _median_time(lambda: frequency_response(t, q, u, fit.value("M"), fit.value("B")), args.runs)
    print(f"frequency_response (no broadband content, whole log): median {med:.2f} s; band {fr.band_hz}")
    plan = ExcitationPlan(n_speeds=5, ms_duration=6.0, leg_max_time=0.8, injection_s=3.0)
    axis = AxisTruth(M=0.027, B=0.273, fc=0.10, fs=0.12, vs=0.01, xi=2.0, lsb=1e-6, sample_rate=2500.0,
                     mode_hz=479.0, mode_damping=0.07, mode_ratio=0.3, mode_load_side=True)
    d = simulate_excitation(axis, plan, np.random.default_rng(3))
    med, fr = _median_time(lambda: frequency_response(d["t"], d["q"], d["u"], axis.M, axis.B), args.runs)
    print(f"frequency_response (3 s of PRBS at 2.5 kHz, mode fit): median {med:.2f} s; "
          f"mode {fr.fit.mode_hz:.1f} Hz (truth 479)")

    with tempfile.TemporaryDirectory() as tmp:
        path = pathlib.Path(tmp) / "log.h5"
        with h5py.File(path, "w") as f:
            for k, v in (("t", t), ("q", q), ("u", u)):
                f.create_dataset(k, data=v)
        data = path.read_bytes()
        read = {name: _median_time(lambda fn=getattr(logs, name): fn(data, "log.h5", "HDF5", {}, True, matlab=False),
                                   max(args.runs, 5))[0] for name in ("_read_hdf5_here", "_read_hdf5")}
    print(f"HDF5 read of {len(data) / 1e6:.0f} MB: in process {1e3 * read['_read_hdf5_here']:.0f} ms, "
          f"isolated child {1e3 * read['_read_hdf5']:.0f} ms (median; ratio "
          f"{read['_read_hdf5'] / read['_read_hdf5_here']:.2f})")


if __name__ == "__main__":
    main()
