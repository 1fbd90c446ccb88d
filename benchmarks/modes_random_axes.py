"""Identification of the structural modes of random axes: true against identified, one line per axis.

For each seed, :func:`commission.synth.record_random_axis_log` records the axis's log as the tool
tells users to (its own ``commission excite`` plan played on the TRUE axis), ``identify`` runs on it
with its defaults, and the line gives the friction's share of the rail, the true modes (frequency,
damping, encoder side) and input delay, the identified ones, the band the log backs and which log
was recorded.  This is what the verdict rests on before any tuning: a mode read with the wrong
damping or at the wrong frequency moves the PID yardstick and the ARC's margins
(docs/robustness.md, "The injection's cruise").  Nothing is asserted.

Run: ``python benchmarks/modes_random_axes.py --seeds 500-529``.
"""

from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

import numpy as np

from commission.identification import identify_log
from commission.synth import random_axis, record_random_axis_log


def parse_seeds(text: str) -> list[int]:
    out: list[int] = []
    for part in text.split(","):
        a, _, b = part.partition("-")
        out += range(int(a), int(b) + 1) if b else [int(a)]
    return out


def _modes_text(modes: list[tuple[float, float, bool]]) -> str:
    return " ".join(f"{f:.0f} Hz/z{z:.3f}/{'load' if load else 'motor'}" for f, z, load in modes) or "rigid"


def line(seed: int) -> str:
    """One axis: its truth, what identify read from its excite log, and the time it took."""
    t = random_axis(np.random.default_rng(seed))
    t0 = time.perf_counter()
    with tempfile.TemporaryDirectory() as d:
        path = Path(d) / "log.h5"
        rec = record_random_axis_log(seed, path)
        fr = identify_log(str(path), u_unit=t.u_unit).ident.to_dict()["frequency_response"]
    m = fr.get("model") or {}
    true = [(t.mode_hz, t.mode_damping, t.mode_load_side)][:t.n_modes]
    if t.n_modes >= 2:
        true.append((t.mode2_hz, t.mode2_damping, t.mode2_load_side))
    found = [(m[f"{k}_hz"], m[f"{k}_damping"], bool(m[f"{k}_load_side"])) for k in ("mode", "mode2") if m.get(f"{k}_hz")]
    delay = f"{m['delay_s'] * t.sample_rate:.2f}" if m.get("delay_s") is not None else "-"
    return (f"axis {seed}: {t.sample_rate / 1e3:g} kHz, friction {max(t.fc, t.fs) / t.u_max:.2f} of the rail | true "
            f"{_modes_text(true)}, delay {t.delay * t.sample_rate:.2f} samples | identified {_modes_text(found)}, delay "
            f"{delay} | band {fr.get('band_hz')} Hz, evidence {fr.get('evidence_band_hz')} Hz | log {rec.log} | "
            f"{time.perf_counter() - t0:.0f} s")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", default="0-29")
    for seed in parse_seeds(ap.parse_args().seeds):
        print(line(seed), flush=True)


if __name__ == "__main__":
    main()
