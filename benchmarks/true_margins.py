"""The emitted ARC's stability margins on each swept axis's TRUE plant (issue 30: "a margin for what is emitted").

Reads a ``benchmarks/sweep_random_axes.py`` workdir (``DIR/axisN/out/controller.json``); each axis's
true plant is redrawn from its seed (:func:`commission.synth.random_axis`, as the sweep draws it).  For
every emitted controller it prints the ARC's margins on the true sampled plant (modes and delay
included) with theta_hat at its initial estimate and at the true plant's theta, and the closed loop's
spectral radius with one more sample of delay, against validate's default floors (the radius as the
margin table reads it: the adaptation's neutral modes sit on the unit circle, so up to 1 +
``NEUTRAL_TOL`` is stable).  Reads; changes
nothing.  Run: ``python benchmarks/true_margins.py DIR``.
"""

from __future__ import annotations

import argparse
import glob
import os
import re

import numpy as np

from commission.controllers.arc import arc_pack
from commission.controllers.linear import sampled_plant
from commission.controllers.margins import NEUTRAL_TOL, closed_loop_radius, linearize_arc, loop_margins
from commission.robustness import MarginFloors
from commission.runtime import load_controller
from commission.synth import random_axis


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("workdir")
    args = ap.parse_args()
    floors = MarginFloors()
    print(f"floors: gain {floors.gain_db:g} dB, phase {floors.phase_deg:g} deg, modulus {floors.modulus:g}, "
          f"delay {floors.delay_samples:g} samples; +1 sample: spectral radius < 1 + {NEUTRAL_TOL:g} (the adaptation's "
          f"integrators sit on the unit circle)")
    worst = {"gm": np.inf, "pm": np.inf, "mm": np.inf, "dm": np.inf, "r1": 0.0}
    n = held = 0
    for path in sorted(glob.glob(os.path.join(args.workdir, "axis*", "out", "controller.json")),
                       key=lambda p: int(re.search(r"axis(\d+)", p).group(1))):
        seed = int(re.search(r"axis(\d+)", path).group(1))
        truth = random_axis(np.random.default_rng(seed))
        gains = load_controller(path).config.gains
        p = truth.plant()
        plant, plant1 = sampled_plant(p, truth.period), sampled_plant(p, truth.period, extra_delay=1.0)
        th_true = (1.0 / truth.M, truth.B / truth.M, -truth.offset / truth.M)
        rows = []
        for at, th in (("initial", tuple(gains.theta0)), ("true", th_true)):
            lin = linearize_arc(arc_pack(gains), th)
            m = loop_margins(lin, plant)
            r1 = closed_loop_radius(lin, plant1)
            rows.append((at, m, r1))
            worst["gm"] = min(worst["gm"], m.gain_margin_db)
            worst["pm"] = min(worst["pm"], m.phase_margin_deg)
            worst["mm"] = min(worst["mm"], m.modulus_margin)
            worst["dm"] = min(worst["dm"], m.delay_margin_samples)
            worst["r1"] = max(worst["r1"], r1)
        ok = all(m.stable and m.gain_margin_db >= floors.gain_db and m.phase_margin_deg >= floors.phase_deg
                 and m.modulus_margin >= floors.modulus and m.delay_margin_samples >= floors.delay_samples
                 and r1 < 1.0 + NEUTRAL_TOL for _a, m, r1 in rows)
        n += 1
        held += ok
        print(f"axis {seed}: " + "; ".join(
            f"theta_hat {a}: GM {m.gain_margin_db:.1f} dB, PM {m.phase_margin_deg:.0f} deg, MM {m.modulus_margin:.2f}, "
            f"DM {m.delay_margin_samples:.2f} samples, radius +1 {r1:.6f}" for a, m, r1 in rows)
            + ("" if ok else "  BELOW A FLOOR"))
    print(f"{held} of {n} emitted controllers keep every floor on their true plant at both estimates; worst: "
          f"GM {worst['gm']:.1f} dB, PM {worst['pm']:.0f} deg, MM {worst['mm']:.2f}, DM {worst['dm']:.2f} samples, "
          f"radius with +1 sample {worst['r1']:.6f}")


if __name__ == "__main__":
    main()
