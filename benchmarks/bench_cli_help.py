"""Time ``commission --help`` and ``commission -h`` end to end (issue 23, must-show 4).

Target: under 0.5 s wall (median) on 2 cores.  The help answers without
importing numpy, scipy, numba, h5py or matplotlib: the command modules load
only when a command runs (``commission.cli.main.LazyGroup``).  Each run is a
fresh process of the installed console script, as a user types it.  Also
prints, for comparison, the help of one command (which imports that command's
module) and whether the numerics stayed unloaded for ``--help``.

Run: ``python benchmarks/bench_cli_help.py [--runs 7]``
"""

from __future__ import annotations

import argparse
import shutil
import statistics
import subprocess
import sys
import time
from pathlib import Path

TARGET_S = 0.5


def _script() -> list[str]:
    found = Path(sys.executable).parent / "commission"
    if found.is_file():
        return [str(found)]
    which = shutil.which("commission")
    if which is None:
        raise SystemExit("commission is not installed (pip install -e .)")
    return [which]


def _median(argv: list[str], runs: int) -> float:
    times = []
    for _ in range(runs):
        t0 = time.perf_counter()
        subprocess.run(argv, check=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        times.append(time.perf_counter() - t0)
    return statistics.median(times)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", type=int, default=7)
    args = ap.parse_args()
    script = _script()
    subprocess.run([*script, "--help"], check=True, stdout=subprocess.DEVNULL)  # warm the file cache
    for flag in ("--help", "-h"):
        m = _median([*script, flag], args.runs)
        print(f"commission {flag:7s} median {m:.3f} s over {args.runs} runs "
              f"({'within' if m < TARGET_S else 'ABOVE'} the {TARGET_S} s target)")
    m = _median([*script, "validate", "--help"], max(3, args.runs // 2))
    print(f"commission validate --help median {m:.3f} s (imports the validate command's module)")
    probe = ("import sys; sys.argv = ['commission', '--help']; from commission.cli.main import run; run(); "
             "heavy = [m for m in ('numpy', 'scipy', 'numba', 'h5py', 'matplotlib') if m in sys.modules]; "
             "sys.stderr.write(f'numerics loaded by --help: {heavy or \"none\"}\\n')")
    r = subprocess.run([sys.executable, "-c", probe], stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    print(r.stderr.strip())


if __name__ == "__main__":
    main()
