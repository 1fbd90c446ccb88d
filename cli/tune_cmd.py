"""``commission tune IDENT --out TUNING [--spec SPEC] [--seed N]``: choose the ARC gains."""

from __future__ import annotations

import math
from pathlib import Path
from typing import Optional, Sequence

import typer
from rich.console import Console
from rich.markup import escape
from rich.table import Table

from commission.cli.errors import cli_errors
from commission.cli.main import app
from commission.cli.progress import StageProgress
from commission.infra.files import Outputs
from commission.formats.spec_toml import SPEC_KEYS
from commission.formats.table import Key, help_lines
from commission.spec import MAX_OMEGA_T, check_flags
from commission.tune import load_tune_inputs, pid_chatter, pid_pole_note, run_tune
from commission.tuning import Tuning
from commission.units import nominal, unit


def help_text(keys: Sequence[Key] = SPEC_KEYS) -> str:
    """The command's help: its key list is the spec table's rows (:func:`commission.formats.table.help_lines`)."""
    return f"""Tune the discrete output-feedback ARC (and the PID baseline) for an identified axis.

Reads ident.json, checks the spec (before any simulation), places the observer
poles, searches the free gains on the tuning scenarios, checks Theorem 1 and
the discrete feasibility over the theta box, and writes tuning.json.

\b
Spec TOML keys (section.key = default, then what it is; every key optional):
{escape(chr(10).join(help_lines(keys)))}

\b
Defaulted keys tune may change, each with a note: the envelope (trajectory.v_max, a_max) is scaled
below the paper's rate and lowered to what the drive can feed forward on the box's most demanding
plant; the theta3 box is narrowed instead when identify's defaulted load-force bound leaves no room;
the observer pole is a coordinate of the search; pid.pole is lowered when that PID chatters beyond
validate's c_u limit.  tune.budget is kept whatever a candidate costs to simulate (a starved
search certifies weak gains: docs/robustness.md).  Values you set are checked, not changed.
Ranges: docs/interface.md section 6.
A requested bandwidth w (rad/s) needs w / sample_rate <= {MAX_OMEGA_T:g}.
A bad spec (unknown key, negative rate, too low a sample rate) exits 2 naming the key.
"""


def _um(x: float) -> str:
    return f"{x * 1e6:.3g}" if math.isfinite(x) else "-"


def print_summary(t: Tuning, console: Console) -> None:
    """Chosen gains, the design checks, and ARC vs PID on every tuning scenario."""
    g = t.arc
    units = t.identification.units
    u, q, small = units.get("u", "u-unit"), unit("q", units), unit("small", units)
    gains = Table(title="Chosen gains")
    gains.add_column("gain")
    gains.add_column("value", justify="right")
    rows = [
        ("sample rate (Hz)", nominal(1 / g.Ts, "{:g}")),
        ("observer pole (rad/s): k1, k2", f"{t.observer.pole:g}: {g.k1:.4g}, {g.k2:.4g}"),
        ("g1, g2 (1/s)", f"{g.g1:.4g}, {g.g2:.4g}"),
        ("k1s_max, k2s_max (1/s)", f"{g.k1s_max:.4g}, {g.k2s_max:.4g}"),
        ("Gamma (theta_i's unit per unit of tau_i, per s)", ", ".join(f"{x:.3g}" for x in g.Gamma)),
        (f"theta_hat(0) ({unit('theta1', units)}, 1/s, {unit('a', units)})",
         ", ".join(f"{x:.4g}" for x in g.theta0)),
        (f"PID Kp ({u}/{q}), Ki ({u}/({q}·s)), Kd ({u}·s/{q})", f"{t.pid.Kp:.4g}, {t.pid.Ki:.4g}, {t.pid.Kd:.4g}"),
        ("Theorem 1 condition", f"{'holds' if t.theorem1.holds else 'FAILS'} (min ratio {t.theorem1.min_ratio:.3g})"),
        ("discrete feasibility (ARC)",
         f"{'holds' if t.feasibility['arc'].holds else 'FAILS'} (rho_max {t.feasibility['arc'].rho_max:.4f})"),
    ]
    se = t.search
    rows.append(("search", f"{se.n_evaluations} candidates, {se.n_feasible} met every constraint "
                           f"(margins, gate, feasibility)"))
    if se.chosen_level != 0:
        rows.append(("constraints", f"NOT MET by any candidate: the least violation ({se.chosen_violation:.3g}) chosen"))
    if se.holdout_plants:
        rows.append(("default gate, hold-out",
                     f"{min(se.holdout_failures)} failures on {se.holdout_plants} fresh plants + the tuning scenarios"))
    for r in rows:
        gains.add_row(*r)
    console.print(gains)
    sc = Table(title=f"ARC / PID on the tuning scenarios (errors in {small})")
    sc.add_column("scenario", no_wrap=True)
    for h in ("e_M", "e_F", "e_rms", "c_u"):
        sc.add_column(f"{h} ARC / PID", justify="right", no_wrap=True)
    for name, row in t.scores.items():
        a, p = row["arc"], row["pid"]
        sc.add_row(name, f"{_um(a.e_M)} / {_um(p.e_M)}", f"{_um(a.e_F)} / {_um(p.e_F)}",
                   f"{_um(a.e_rms)} / {_um(p.e_rms)}", f"{a.c_u:.2f} / {p.c_u:.2f}",
                   style="red" if a.diverged or (math.isfinite(p.e_rms) and a.e_rms > p.e_rms) else None)
    console.print(sc)


@app.command("tune", help=help_text())
@cli_errors
def tune_command(
    ident: Path = typer.Argument(..., help="ident.json written by `commission identify`."),
    out: Path = typer.Option(..., "--out", help="Where to write tuning.json."),
    spec: Optional[Path] = typer.Option(None, "--spec", help="Spec TOML (see above; default: the paper's setting)."),
    seed: int = typer.Option(0, "--seed", help="Seed of the gain search (results are deterministic for a seed)."),
    workers: Optional[int] = typer.Option(None, "--workers", help="Simulation threads, 1-256 (default: one per CPU)."),
    force: bool = typer.Option(False, "--force", help="Overwrite an existing --out file."),
) -> None:
    out_console = Console()
    err = Console(stderr=True)
    check_flags(workers=workers)
    inputs = load_tune_inputs(ident, spec_path=spec, seed=seed)  # every check before any simulation
    outputs = Outputs(force=force, inputs=(ident, spec))
    outputs.add_file(out, "--out")
    for note in inputs.notes:
        err.print(f"note: {note}", highlight=False)
    with outputs, StageProgress(err) as bar:  # locked and proved writable before the search
        t = run_tune(ident, outputs.path(out), progress=bar.callback("tuning"), workers=workers, inputs=inputs)
    print_summary(t, out_console)
    out_console.print(f"wrote {out}", highlight=False)
    pid_note = pid_pole_note(t)
    if pid_note is not None:
        err.print(f"note: {pid_note}", highlight=False)
    se = t.search
    if se.chosen_level != 0:
        err.print(f"warning: no candidate of the search met every constraint (stability margins, validate's "
                  f"default gate with room, discrete feasibility); these gains miss them by "
                  f"{se.chosen_violation:.3g} and `commission validate` will likely refuse them: a narrower "
                  f"envelope or payload box, or a larger tune.budget", highlight=False)
    left = min(se.holdout_failures, default=0)
    if left:
        err.print(f"warning: these gains still fail {left} check(s) of validate's default gate on tune's "
                  f"hold-out plants; `commission validate` will likely refuse them", highlight=False)
        chatter = pid_chatter(t)
        if chatter is not None:
            err.print(f"warning: the PID baseline itself exceeds the gate's c_u <= {chatter.limit:g} on "
                      f"{chatter.count} tuning scenario(s) (worst {chatter.worst:.2f}, {chatter.scenario}): "
                      f"at {t.spec.sample_rate:g} Hz an encoder step of {t.quantization * 1e6:.3g} "
                      f"{unit('small', t.identification.units)} chatters "
                      f"any loop that tracks within it; a finer encoder or a gate.toml c_u states what this "
                      f"axis can do", highlight=False)
