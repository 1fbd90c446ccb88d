"""What the evidence bound would say if the unseen mode were placed no higher than Nyquist.

The default bound (:mod:`commission.evidence`) places the lowest unseen mode a decade above the
band the log backs.  On a broadband log that decade usually lies above the loop's Nyquist
frequency, and the bound then weighs nothing between the band's top and Nyquist
(:attr:`commission.evidence.Evidence.assumed_mode_free_hz`).  This script re-reads the stored
``tuning.json`` of a ``sweep_random_axes.py --workdir DIR`` run and prints, per axis, the peak
``|W T|`` of the tuned ARC (worst of its two linearisations) and of the tool's PID yardstick under
the default weight and under the weight with ``f_m = min(10 x top, Nyquist)``, with whether
``controller.json`` was emitted.  Together with the sweep's own lines (works / false
certification / false refusal on the true axis) it says what such a rule would catch and what
it would refuse.  Nothing is re-tuned: it is the bound on the gains the tool chose.

Run: ``python benchmarks/evidence_nyquist.py DIR [DIR ...]``.  Prints figures; asserts nothing.
"""

from __future__ import annotations

import argparse
import dataclasses
import pathlib
import re

from commission.errors import CommissionError
from commission.evidence import EvidenceBound
from commission.tuning import Tuning


def axis_dirs(root: pathlib.Path) -> list[pathlib.Path]:
    """``root/axisN`` folders in seed order."""
    found = [d for d in root.glob("axis*") if re.fullmatch(r"axis\d+", d.name)]
    return sorted(found, key=lambda d: int(d.name[4:]))


def peaks(bound: EvidenceBound, tuning: Tuning) -> tuple[float, float]:
    """``(ARC's worst peak |W T|, PID's peak)`` under ``bound``'s weight."""
    return max(r.peak for r in bound.arc_rows(tuning.arc)), bound.pid_row(tuning.pid).peak


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("workdirs", nargs="+", type=pathlib.Path)
    args = ap.parse_args()
    print("axis      rate Hz  top Hz  top/Nyq  f_m Hz  emitted  ARC |WT| default -> f_m<=Nyq   PID default -> f_m<=Nyq")
    for root in args.workdirs:
        for d in axis_dirs(root):
            try:
                t = Tuning.load(str(d / "out" / "tuning.json"))
            except (OSError, CommissionError, ValueError) as exc:
                print(f"{d.name:9s} no tuning.json read ({type(exc).__name__})")
                continue
            b = EvidenceBound(t.identification, t.spec)
            ev = b.evidence
            if not ev.applies:
                print(f"{d.name:9s} no backed band")
                continue
            arc0, pid0 = peaks(b, t)
            nyq = 0.5 * t.spec.sample_rate
            # the cap stated the way a user states the first mode (spec [evidence] first_mode_hz)
            capped = (EvidenceBound(t.identification, dataclasses.replace(t.spec, evidence_first_mode_hz=nyq))
                      if ev.mode_hz > nyq else b)
            arc1, pid1 = peaks(capped, t)
            emitted = (d / "out" / "controller.json").exists()
            print(f"{d.name:9s} {2 * nyq:7.0f} {ev.top_hz:7.1f} {ev.top_hz / nyq:8.2f} {ev.mode_hz:7.0f}  "
                  f"{'yes' if emitted else 'no':7s}  {arc0:8.3f} -> {arc1:8.3f}{' EXCEEDS' if arc1 >= 1 else '':8s}"
                  f"  {pid0:8.3f} -> {pid1:8.3f}{' EXCEEDS' if pid1 >= 1 else ''}")


if __name__ == "__main__":
    main()
