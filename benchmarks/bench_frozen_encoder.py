"""Frozen and implausible encoder readings on the sample's controller (issue 29, item 6 and must-show 4).

The controller is the one ``commission run sample_data/axis_excitation.h5``
emits (controller.json, runtime guards included); the plant is the
*identified* plant of its tuning.json (:func:`commission.scenarios.identified_plant`,
the model validate simulates; not ``sample_data/truth.json``), run with the
validated encoder step, its input delay and ``plant_substeps`` sub-steps per sample,
like ``validate``'s simulator (:func:`closed_loop`; pinned to
:func:`commission.controllers.simulate.simulate` by ``tests/test_bench_frozen_encoder.py``).
The desired motion is Case 2 (moves of the whole stroke at v_max, a_max).  Each case
corrupts the measurement the compiled step receives (the same ``arc_step`` the runtime
and the exported C run):

* ``frozen 20 ms @ 1 m/s``: the encoder repeats its last reading for 20 ms
  during the first move's cruise at v_max (must-show 4);
* ``frozen 20 ms @ start``: frozen from 2 ms before the first move starts
  (the axis at rest: the prediction says "still", so only the command at
  the rail can tell);
* ``frozen 20 ms @ accel``: frozen half way through the first acceleration;
* one-sample glitches in the cruise: 0.3 mm, +-0.79 mm, 1 mm, and a glitch of
  0.9 x the innovation bound the step held that sample to (accepted by design);
* a sweep of one-sample glitches from 2 um to 1 mm, both signs: the most
  samples at the rail any of them costs.

For each case the figures are: samples at the rail (|u| >= u_max) from the
event on, samples from the event's first sample to the one whose step latched
the fault and returned 0 (``-``: none), the readings rejected before it, the
fault's reason, and the true plant at the fault -- position error q - q_d and speed
-- and after it, with the drive at the safe command 0 until the axis stops:
the peak of |q - q_d(t_fault)| (the motion is aborted at the fault: how far
the axis ends up from where it was meant to be then) and the peak speed.
``ideal e`` is that peak had the drive been disabled at the event's first
sample (the command 0 from there on, the commands already issued still arriving
after the input delay: the least any detector can do).  The same cases run once more with the
controller's runtime section as it was before issue 29 (the innovation and
frozen-encoder guards off), for comparison.

Run: ``python benchmarks/bench_frozen_encoder.py [RUN_DIR]`` with RUN_DIR a
``commission run`` output folder (controller.json, tuning.json); without it the
sample is run once into a temporary folder (about a minute).  Prints figures;
asserts nothing.
"""

from __future__ import annotations

import dataclasses
import math
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

from commission.controller_config import ControllerConfig
from commission.controllers import arc as A
from commission.controllers.plant import NX, P_DELAY, V_MOTOR, plant_output, plant_start
from commission.controllers.simulate import _segment as hold_segment
from commission.scenarios import case2_trajectory, identified_plant, plant_substeps
from commission.tuning import Tuning

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests"))  # the reading faults the runtime guards' tests pin, as pytest finds them
from sensor_faults import frozen  # noqa: E402
SAMPLE = ROOT / "sample_data" / "axis_excitation.h5"
FREEZE = 0.02  # s
AFTER = 0.6  # s simulated after the event (the axis coasts to rest well within it)


def _quantize(x: float, q: float) -> float:
    return q * math.floor(x / q + 0.5) if q > 0 else x


def delay_schedule(plant: np.ndarray, Ts: float) -> tuple[int, float]:
    """The plant's input delay ``P_DELAY`` as ``(n_d, f)``, ``tau = P_DELAY / Ts = n_d + f`` samples.

    The same split, with the same rounding guards, as
    :func:`commission.controllers.simulate.closed_loop_kernel` (validate's simulator without its
    extra computation delay): the plant receives ``c_{k-n_d-1}`` over the first ``f Ts`` of sample
    ``k`` and ``c_{k-n_d}`` over the rest (commands before the start are 0).  The kernel keeps the
    split inside its compiled loop, which this harness cannot call per sample, so it is restated
    here; ``tests/test_bench_frozen_encoder.py`` pins the two loops to each other on delayed plants.
    """
    tau = float(plant[P_DELAY]) / Ts
    n_d = int(math.floor(tau + 1e-9))
    f = tau - n_d
    return n_d, (0.0 if f < 1e-9 else f)


def closed_loop(g: A.ArcGains, plant: np.ndarray, traj, quant: float, sensor, k_end: int,
                off_from: int | None = None) -> dict:
    """The validated loop with ``sensor(k, y)`` between the encoder and the step.

    As validate's simulator: the plant starts at rest at ``q_d(0)``, the encoder rounds its output
    to ``quant``, the command (clipped to ``u_max``) is held over the sample and reaches the plant
    ``P_DELAY`` late (:func:`delay_schedule`), each part of the sample sub-stepped by the
    simulator's own hold (:func:`commission.controllers.simulate._segment`, which
    ``commission.synth`` shares too) with ``plant_substeps`` sub-steps per sample.  From sample
    ``off_from`` on the step is not called and the command is 0 (the drive disabled there; the
    commands issued before still reach the plant).  ``u`` is the command issued at each sample,
    ``u_held`` the one the plant holds at the end of it (``SimResult.u``), ``v`` the motor-side speed.
    """
    p = A.arc_pack(g)
    s = A.arc_new_state(p)
    st = np.empty(NX)
    plant_start(plant, st, traj.qd[0])
    Ts = traj.Ts
    sub = plant_substeps(1.0 / Ts)
    n_d, f = delay_schedule(plant, Ts)
    A.arc_reset(p, s, _quantize(plant_output(plant, st), quant))
    out = {k: np.zeros(k_end) for k in ("y", "q", "v", "u", "u_held", "fault", "rejected", "bound")}
    u_hist = out["u"]
    for k in range(k_end):
        x = plant_output(plant, st)
        y = sensor(k, _quantize(x, quant))
        if off_from is not None and k >= off_from:
            u = 0.0
        else:
            u = A.arc_step(p, s, y, traj.qd[k], traj.dqd[k], traj.ddqd[k])
            u = min(max(u, -g.u_max), g.u_max)
        out["y"][k], out["q"][k], out["v"][k], u_hist[k] = y, x, st[V_MOTOR], u
        out["fault"][k], out["rejected"][k], out["bound"][k] = s[A.S_FAULT], s[A.S_REJECTED], s[A.S_BOUND]
        c_early = u_hist[k - n_d - 1] if k >= n_d + 1 else 0.0
        c_late = u_hist[k - n_d] if k >= n_d else 0.0
        hold_segment(plant, st, c_early, g.u_max, 0.0, f * Ts, sub, Ts)
        out["u_held"][k] = hold_segment(plant, st, c_late, g.u_max, 0.0, (1.0 - f) * Ts, sub, Ts)
    return out


def _stop(r: dict, k: int, n_d: int) -> int:
    """The first sample from ``k + n_d + 1`` (the last command issued before ``k`` has acted) at which
    the motor side stands still; the last sample if it never does."""
    v = r["v"]
    k1 = min(k + n_d + 1, v.shape[0] - 1)
    still = np.nonzero(v[k1:] == 0.0)[0]
    return k1 + int(still[0]) if still.size else v.shape[0] - 1


def figures(r: dict, traj, k0: int, u_max: float, n_d: int) -> dict:
    """Rail samples, samples to fault, and the true excursion for an event starting at sample ``k0``
    (``n_d``: the whole samples of the plant's input delay, :func:`delay_schedule`)."""
    n = r["u"].shape[0]
    rail = int(np.sum(np.abs(r["u"][k0:]) >= u_max))
    faulted = np.nonzero(r["fault"][k0:] != 0)[0]
    kf = k0 + int(faulted[0]) if faulted.size else None
    out = dict(rail=rail, to_fault=None if kf is None else kf - k0,
               reason=A.FAULT_REASONS[int(r["fault"][-1])],
               rejected=int(np.sum(r["rejected"][k0:n if kf is None else kf] != 0)),
               e_f=math.nan, v_f=math.nan, v_peak=math.nan, e_peak=math.nan)
    if kf is not None:
        q, v = r["q"], r["v"]
        stop = _stop(r, kf, n_d)
        out.update(e_f=q[kf] - traj.qd[kf], v_f=v[kf], v_peak=float(np.max(np.abs(v[kf:stop + 1]))),
                   e_peak=float(np.max(np.abs(q[kf:stop + 1] - traj.qd[kf]))))
    return out


def ideal_excursion(g: A.ArcGains, plant: np.ndarray, traj, quant: float, sensor, k0: int, k_end: int) -> float:
    """Peak |q - q_d(k0)| until the axis stops had the drive been disabled at sample ``k0``: the same
    loop with the command 0 from ``k0`` on (the commands issued before still arrive ``P_DELAY`` late)."""
    r = closed_loop(g, plant, traj, quant, sensor, k_end, off_from=k0)
    stop = _stop(r, k0, delay_schedule(plant, traj.Ts)[0])
    return float(np.max(np.abs(r["q"][k0:stop + 1] - traj.qd[k0])))


def main(argv: list[str]) -> None:
    if argv:
        run_dir = Path(argv[0])
    else:
        run_dir = Path(tempfile.mkdtemp(prefix="bench-frozen-")) / "run"
        print(f"running: commission run {SAMPLE.name} --out-dir {run_dir}", flush=True)
        subprocess.run([sys.executable, "-c", "from commission.cli.main import main; main()", "run", str(SAMPLE),
                        "--out-dir", str(run_dir)], check=True, capture_output=True)
    cfg = ControllerConfig.load(str(run_dir / "controller.json"))
    tuning = Tuning.load(str(run_dir / "tuning.json"))
    g = cfg.gains
    plant = identified_plant(tuning.identification, tuning.spec)
    quant = tuning.quantization
    traj = case2_trajectory(tuning.spec).render(g.Ts, 0.0)
    Ts, v_max = g.Ts, tuning.spec.v_max
    k_move = int(np.argmax(np.abs(traj.dqd) > 0.0))
    k_cruise = int(np.argmax(np.abs(traj.dqd) >= 0.999 * v_max)) + 50
    k_accel = k_move + int(np.argmax(np.abs(traj.dqd[k_move:]) >= 0.5 * v_max))
    k_end = k_cruise + int(round((FREEZE + AFTER) / Ts))
    nf = int(round(FREEZE / Ts))
    n_d, frac = delay_schedule(plant, Ts)
    print(f"controller: {run_dir / 'controller.json'} (Ts = {Ts * 1e3:.3f} ms, u_max = {g.u_max:g}); plant: the "
          f"identified plant of tuning.json (input delay {plant[P_DELAY] * 1e3:.4f} ms = {n_d + frac:.4f} samples); "
          f"encoder step {quant * 1e6:g} um; Case 2 at v_max = {v_max:g} m/s")
    print("runtime guards: " + ", ".join(f"{n} = {getattr(g, n):.6g}" for n in A.RUNTIME_GUARDS))
    clean = closed_loop(g, plant, traj, quant, lambda k, y: y, k_end)
    b = float(clean["bound"][k_cruise])
    print(f"innovation bound at the cruise sample: {b * 1e6:.2f} um")

    def glitch(k0, amp):
        return lambda k, y: y + amp if k == k0 else y

    cases = [("frozen 20 ms @ 1 m/s", frozen(k_cruise, nf), k_cruise),
             ("frozen 20 ms @ start", frozen(k_move - 5, nf), k_move - 5),
             ("frozen 20 ms @ accel", frozen(k_accel, nf), k_accel),
             ("glitch +0.3 mm", glitch(k_cruise, 0.3e-3), k_cruise),
             ("glitch +0.79 mm", glitch(k_cruise, 0.79e-3), k_cruise),
             ("glitch -0.79 mm", glitch(k_cruise, -0.79e-3), k_cruise),
             ("glitch +1 mm", glitch(k_cruise, 1e-3), k_cruise),
             (f"glitch +0.9 bound ({0.9 * b * 1e6:.1f} um)", glitch(k_cruise, 0.9 * b), k_cruise),
             (f"glitch -0.9 bound ({0.9 * b * 1e6:.1f} um)", glitch(k_cruise, -0.9 * b), k_cruise)]
    old = dataclasses.replace(g, accel_max=math.inf, y_err=0.0, n_frozen_max=math.inf)
    for label, gains in (("with the guards of this version", g), ("without the innovation and frozen guards "
                                                                   "(runtime section before issue 29)", old)):
        print(f"\n{label}")
        print(f"{'case':34s} {'rail':>4s} {'to fault':>8s} {'rejected':>8s} {'e at fault':>11s} {'v at fault':>10s} "
              f"{'e peak':>8s} {'v peak':>7s} {'ideal e':>8s}  reason")
        for name, sensor, k0 in cases:
            r = closed_loop(gains, plant, traj, quant, sensor, k_end)
            f = figures(r, traj, k0, g.u_max, n_d)
            ideal = (ideal_excursion(gains, plant, traj, quant, sensor, k0, k_end) if name.startswith("frozen")
                     else math.nan)
            tf = "-" if f["to_fault"] is None else str(f["to_fault"])
            if f["to_fault"] is None:
                print(f"{name:34s} {f['rail']:4d} {tf:>8s} {f['rejected']:8d} {'-':>11s} {'-':>10s} {'-':>8s} {'-':>7s} "
                      f"{'-':>8s}  {f['reason']}")
                continue
            print(f"{name:34s} {f['rail']:4d} {tf:>8s} {f['rejected']:8d} {f['e_f'] * 1e3:8.3f} mm {f['v_f']:6.3f} m/s "
                  f"{f['e_peak'] * 1e3:5.1f} mm {f['v_peak']:7.3f} {ideal * 1e3:5.1f} mm  {f['reason']}")
        worst, smallest = (0, 0.0), math.inf
        for amp in np.geomspace(2e-6, 1e-3, 40):
            for sign in (1.0, -1.0):
                r = closed_loop(gains, plant, traj, quant, glitch(k_cruise, sign * amp), k_cruise + 200)
                rail = int(np.sum(np.abs(r["u"][k_cruise:]) >= g.u_max))
                if rail > worst[0]:
                    worst = (rail, sign * amp)
                if rail:
                    smallest = min(smallest, amp)
        print(f"glitch sweep 2 um - 1 mm (80 glitches): most samples at the rail {worst[0]}"
              + (f" (glitch {worst[1] * 1e6:+.1f} um); the smallest that reaches it {smallest * 1e6:.1f} um"
                 if worst[0] else ""))


if __name__ == "__main__":
    main(sys.argv[1:])
