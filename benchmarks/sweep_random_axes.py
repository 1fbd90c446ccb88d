"""Issue 30's yield: random axes -> ``commission run`` -> what it emits, judged on the TRUE axis.

For each seed, :func:`commission.synth.record_random_axis_log` draws an axis from the spread of
real machines (:func:`commission.synth.random_axis`: 0.3-300 kg, V or N, 1-20 kHz, 0-2
samples of delay, encoder noise to 1 count, 0-2 structural modes at 200 Hz-2 kHz) and
simulates its commissioning log; the product then runs its default pipeline on the log
(identify -> tune -> validate, :func:`commission.pipeline.run_all`, seed ``--tune-seed``), and
:func:`commission.true_axis.judge_axis` simulates what was emitted (or, when refused, the
tuned gains forced through) on the axis's TRUE plant in Case 1 and Case 2, as logged and with
one more sample of delay, against the fastest PID that keeps the margin floors on the true
plant (docs/robustness.md, "Yield on the true axis").

One line per axis -- rate, mass (kg, with the command unit and its gain), modes, delay,
noise, the tool's verdict, the count it falls in (works / FALSE-CERT / FALSE-REFUSAL /
refused-ok / no-candidate, which says whether a true-plant PID works there; CRASH for an
exception that is not an exit-2 refusal), the worst ARC/PID e_rms ratio over the four runs, the tool's
own PID yardstick judged on the true plant (:class:`commission.true_axis.ToolYardstick`: does the PID
the gate compared the ARC with keep the floors there, and how its e_rms compares with the true-plant
PID's) and the seconds it took (wall and this process's CPU) -- then the totals, the median ratio over
the emitted axes, and how many false refusals and false certifications had a tool yardstick that
misses the floors or a run on the true plant.

The counts compare each run on one draw of the encoder's noise, as one run on the machine would.
Each line also gives the ARC/PID ratio of the median e_rms over ``--noise-draws`` draws
(:func:`commission.true_axis.draws_ratio`, default 5) and the count that ratio gives, and the
totals say how many axes it moves: where a loop's error is a limit cycle of friction and
quantisation, one draw can decide the count.  It is a diagnosis; the counts reported are the
judged draw's.

Seeds 0-29 are the development set.  A held-out set is run once, on final code, by the lead, and
is no longer held out once a change has been made after seeing its failures: 100-129, 200-229,
300-329, 400-429, 500-529, 600-629 and 700-729 have been seen so (600-629 was run once before the
excite change of that session and once after it), 800-829 and 900-929 were each run once on code with
the same verdict, 1000-1029 once on the code of the ``<case>/stribeck`` scenario (session 15),
1100-1129 to 1900-1929 once each on the code of their session (docs/robustness.md), and the next
change of the verdict needs seeds nobody has run, 2000-2029.  Nothing is asserted: the tests run the judging function on known cases
(``tests/test_true_axis.py``).

Each axis is recorded as the tool tells users to record it (``--log excite``, the default):
:func:`commission.synth.record_random_axis_log` writes the limits.toml an engineer of that axis
would write, plans the run with ``commission excite`` (:func:`commission.excite.plan_run`) and
plays the plan on the TRUE axis; when excite refuses the limits, the legacy log is written and
the line says so.  ``--log legacy`` records the commissioning run of issue 30's generator
(ladder, moves, a low multisine; no broadband injection).  Each line states which log the axis
got, its duration and samples.

Run: ``python benchmarks/sweep_random_axes.py [--seeds 0-5] [--log excite|legacy] [--tune-seed 0]
[--workers N] [--workdir DIR] [--reuse-logs DIR] [--ripple-pitch-none] [--noise-draws N]`` (``--seeds`` takes ``A-B`` and/or comma lists; ``--workers``: axes in
parallel processes, each validating on one thread -- the machine's cores are shared, mind
them; ``--workdir`` keeps each axis's log and run outputs under ``DIR/axisN``; ``--reuse-logs DIR``
judges the logs a previous ``--workdir`` kept instead of recording new ones, so that a subset re-runs
on the same logs after a change of the tool).
"""

from __future__ import annotations

import argparse
import math
import pathlib
import statistics
import tempfile
import time

import numpy as np
from concurrent.futures import ProcessPoolExecutor

from commission.identification import IdentifyOptions
from commission.synth import LOG_KINDS, AxisTruth, random_axis, record_random_axis_log
from commission.true_axis import NOISE_DRAWS, Judgement, judge_axis


def parse_seeds(text: str) -> list[int]:
    """``"0-3,16"`` -> ``[0, 1, 2, 3, 16]``."""
    out: list[int] = []
    for part in text.split(","):
        lo, _, hi = part.partition("-")
        out.extend(range(int(lo), int(hi or lo) + 1))
    return out


def describe(truth: AxisTruth) -> str:
    """Rate, mass, command, modes, delay and noise of an axis, with units."""
    unit = "V" if truth.u_unit == "V" else "N"
    cmd = f"{truth.input_gain:.3g} N/V" if unit == "V" else "force cmd"
    modes = []
    for f, z, load in ((truth.mode_hz, truth.mode_damping, truth.mode_load_side),
                       (truth.mode2_hz, truth.mode2_damping, truth.mode2_load_side)):
        if f > 0:
            modes.append(f"{f:.0f} Hz z{z:.2f} {'load' if load else 'motor'}")
    return (f"{truth.sample_rate / 1e3:g} kHz, {truth.mass_kg:.3g} kg (M {truth.M:.3g} {unit} s^2/m, {cmd}), "
            f"modes [{'; '.join(modes) or 'rigid'}], delay {truth.delay * truth.sample_rate:.2f} samples, "
            f"noise {truth.noise_std / truth.lsb:.2f} counts of {truth.lsb * 1e6:.2g} um")


def category(j: Judgement) -> str:
    """The count an axis falls in."""
    if j.works:
        return "works"
    if j.false_certification:
        return "FALSE-CERT"
    if j.false_refusal:
        return "FALSE-REFUSAL"
    if j.candidate:
        return "refused-ok"
    return "no-candidate" + (" (a true-plant PID works)" if j.pid.gains is not None else "")


def draws_category(j: Judgement) -> str:
    """The count an axis with a candidate and a true-plant PID falls in when the comparison is
    :attr:`Judgement.draws_ratio` below 1 (the runs' c_u, divergence and faults still the judged
    draw's); ``"-"`` where it was not computed."""
    if math.isnan(j.draws_ratio):
        return "-"
    wins = all(r.ok for r in j.arc_runs) and j.draws_ratio < 1.0
    if j.emitted:
        return "works" if wins else "FALSE-CERT"
    return "FALSE-REFUSAL" if wins else "refused-ok"


def sweep_axis(seed: int, workdir: str, tune_seed: int, log: str = "excite",
               logs_from: str | None = None, no_ripple: bool = False,
               noise_draws: int = NOISE_DRAWS) -> tuple[int, str, str, float, bool, str, str, str]:
    """Judge random axis ``seed`` recorded with ``log``; ``(seed, line, category, ratio, emitted, log written,
    tool yardstick, draws category)``, the tool yardstick ``"ok"``, ``"floors"`` (misses them on the true
    plant), ``"runs"`` (a run diverges, chatters or faults) or ``"-"`` (none: refused before tuning); the
    draws category :func:`draws_category`'s.

    ``logs_from``: a previous sweep's ``--workdir``; its ``axisN/log.h5`` is judged again (the truth
    re-drawn with :func:`commission.synth.random_axis`) instead of recording a new log.
    ``no_ripple``: ``run --ripple-pitch none`` (no ripple search) instead of ``run`` without flags.
    """
    d = pathlib.Path(workdir) / f"axis{seed}"
    d.mkdir(parents=True, exist_ok=True)
    t0, c0 = time.perf_counter(), time.process_time()
    if logs_from is not None:
        log_path = pathlib.Path(logs_from) / f"axis{seed}" / "log.h5"
        truth = random_axis(np.random.default_rng(seed))  # as record_random_axis_log draws it
        how = f"log reused from {log_path}"
    else:
        log_path = d / "log.h5"
        rec = record_random_axis_log(seed, log_path, log=log)
        truth = rec.truth
        how = (f"log {rec.log}" + (f" (asked {rec.requested})" if rec.log != rec.requested else "")
               + f" {rec.duration_s:.1f} s, {rec.samples} samples" + (f" [{rec.note[:160]}]" if rec.note else ""))
    t_rec = time.perf_counter() - t0
    try:
        j = judge_axis(truth, log_path, out_dir=d / "out", seed=tune_seed, workers=1,
                       identify=IdentifyOptions(find_ripple=False) if no_ripple else None, noise_draws=noise_draws)
    except Exception as exc:  # a crash of the tool (not an exit-2 refusal): recorded, the sweep goes on
        dt = time.perf_counter() - t0
        return seed, f"axis {seed:3d}: {describe(truth)} | {how} | CRASH {type(exc).__name__}: {exc} | {dt:.0f} s", \
            "CRASH", math.nan, False, log if logs_from is None else "reused", "-", "-"
    dt, cpu = time.perf_counter() - t0, time.process_time() - c0
    cat = category(j)
    pid = f"PID {j.pid.pole:.0f} rad/s" if j.pid.gains is not None else "no PID keeps the floors"
    def run_text(r) -> str:
        if r.diverged:
            return "DIV"
        stop = "" if math.isnan(r.stopped) else f"/FAULT@{r.stopped:.3g}s"
        return f"{r.e_rms * 1e6:.3g}um/cu{r.c_u:.2f}{stop}"

    runs = " ".join(f"{r.case}{'+1' if r.extra_delay else ''}:{run_text(r)}" for r in j.arc_runs)
    tool, tool_text = "-", ""
    if j.tool_pid is not None:
        tool = "ok" if j.tool_pid.ok else ("floors" if j.tool_pid.violations else "runs")
        tool_text = f" | {j.tool_pid.describe(j.pid)}"
    dcat = draws_category(j)
    draws_text = "" if dcat == "-" else f" | over {noise_draws} noise draws: ARC/PID {j.draws_ratio:.2f} ({dcat})"
    line = (f"axis {seed:3d}: {describe(truth)} | {how} | {j.verdict[:120]} | {cat} | ARC/PID {j.ratio:.2f} ({pid}) "
            f"| {runs}{tool_text}{draws_text} | {dt:.0f} s wall ({t_rec:.0f} s recording), {cpu:.0f} s CPU")
    return seed, line, cat, j.ratio, j.emitted, log if logs_from is None else "reused", tool, dcat


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", default="0-29")
    ap.add_argument("--tune-seed", type=int, default=0)
    ap.add_argument("--workers", type=int, default=1, help="axes in parallel processes (default 1)")
    ap.add_argument("--workdir", type=pathlib.Path, default=None)
    ap.add_argument("--log", choices=LOG_KINDS, default="excite",
                    help="how each axis is recorded: excite (the plan of commission excite from the axis's "
                         "limits, played on the true axis; default) or legacy (ladder, moves, low multisine)")
    ap.add_argument("--reuse-logs", type=pathlib.Path, default=None, metavar="DIR",
                    help="judge the logs a previous sweep kept (DIR/axisN/log.h5, its --workdir) instead of "
                         "recording new ones; --workdir must then be another folder")
    ap.add_argument("--ripple-pitch-none", dest="no_ripple", action="store_true",
                    help="run each axis with --ripple-pitch none (no ripple search; the default searches)")
    ap.add_argument("--noise-draws", type=int, default=NOISE_DRAWS,
                    help=f"encoder-noise draws of each line's noise-averaged ratio (default {NOISE_DRAWS}; 1: none)")
    args = ap.parse_args()
    if args.reuse_logs is not None and args.workdir is not None and args.workdir.resolve() == args.reuse_logs.resolve():
        ap.error("--workdir must differ from --reuse-logs (the run outputs would overwrite the kept ones)")
    logs_from = None if args.reuse_logs is None else str(args.reuse_logs)
    seeds = parse_seeds(args.seeds)
    results = []
    t0 = time.perf_counter()
    with tempfile.TemporaryDirectory() as tmp:
        workdir = str(args.workdir or tmp)
        if args.workers > 1:
            with ProcessPoolExecutor(max_workers=args.workers) as ex:
                futs = [ex.submit(sweep_axis, s, workdir, args.tune_seed, args.log, logs_from, args.no_ripple,
                                  args.noise_draws) for s in seeds]
                for f in futs:
                    results.append(f.result())
                    print(results[-1][1], flush=True)
        else:
            for s in seeds:
                results.append(sweep_axis(s, workdir, args.tune_seed, args.log, logs_from, args.no_ripple,
                                          args.noise_draws))
                print(results[-1][1], flush=True)
    n = len(results)
    cats = [r[2] for r in results]
    emitted = [r for r in results if r[4]]
    ratios = [r[3] for r in emitted if not math.isnan(r[3])]
    print(f"{cats.count('works')} of {n} work; {cats.count('FALSE-CERT')} false certifications; "
          f"{cats.count('FALSE-REFUSAL')} false refusals; {cats.count('refused-ok')} refused rightly; "
          f"{sum(c.startswith('no-candidate') for c in cats)} refused before tuning (no candidate to judge; "
          f"{sum(c.endswith('works)') for c in cats)} of them on an axis where a true-plant PID works); "
          f"{len(emitted)} emitted" + (f"; {cats.count('CRASH')} CRASHED" if "CRASH" in cats else ""))
    print(f"median ARC/PID e_rms ratio over the {len(ratios)} emitted axes (worst of the four runs each): "
          f"{statistics.median(ratios):.2f}" if ratios else "median ARC/PID e_rms ratio: no axis emitted")
    for name, label in (("FALSE-REFUSAL", "false refusals"), ("FALSE-CERT", "false certifications")):
        tools = [r[6] for r in results if r[2] == name]
        if tools:
            print(f"of the {len(tools)} {label}, the tool's PID yardstick on the true plant: "
                  f"{tools.count('floors')} miss the floors, {tools.count('runs')} keep them but a run diverges, "
                  f"chatters or faults, {tools.count('ok')} run")
    judged = [r for r in results if r[7] != "-"]
    if judged:
        dc = [r[7] for r in judged]
        moved = [f"{r[0]} ({r[2]} -> {r[7]})" for r in judged if r[7] != r[2]]
        print(f"over {args.noise_draws} noise draws (median e_rms per run), of the {len(judged)} axes with a candidate "
              f"and a true-plant PID: {dc.count('works')} work, {dc.count('FALSE-CERT')} false certifications, "
              f"{dc.count('FALSE-REFUSAL')} false refusals, {dc.count('refused-ok')} refused rightly; "
              f"moved from the judged draw's count: {', '.join(moved) if moved else 'none'}")
    print(f"{time.perf_counter() - t0:.0f} s wall for {n} axes ({args.workers} worker(s)); logs: --log {args.log}, "
          f"{sum(r[5] == 'excite' for r in results)} excite-planned, {sum(r[5] == 'legacy' for r in results)} legacy")


if __name__ == "__main__":
    main()
