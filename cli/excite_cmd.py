"""``commission excite --spec limits.toml --out-dir DIR``: plan the excitation run within the machine's limits."""

from __future__ import annotations

from pathlib import Path
from typing import Sequence

import typer
from rich.console import Console
from rich.markup import escape

from commission.cli.errors import cli_errors
from commission.cli.main import app
from commission.excite import band_lines, load_excite_spec, plan_run, write_plan_csv, write_plan_h5
from commission.infra.files import Outputs
from commission.formats.limits_toml import LIMITS_KEYS
from commission.formats.table import Key, sections
from commission.jsonio import write_json_atomic

def spec_help(keys: Sequence[Key] = LIMITS_KEYS) -> str:
    """``--spec``'s help from limits.toml's table: the required keys, then every other key by section."""
    required = [k.path for k in keys if k.required]
    optional = {s: [k.name for k in ks if not k.required] for s, ks in sections(keys).items()}
    rest = "; ".join(f"[{s}] {', '.join(names)}" for s, names in optional.items() if names)
    return (f"limits.toml: required {', '.join(required)}; optional {escape(rest)} "
            "(drive: bandwidth_hz, or kp and kd; units, defaults and ranges: docs/interface.md section 10).")


#: Files of ``--out-dir``.
PLAN_NAMES = ("plan.csv", "plan.h5", "plan.json", "plan.png")


@app.command("excite")
@cli_errors
def excite(
    spec: Path = typer.Option(..., "--spec", help=spec_help()),
    out_dir: Path = typer.Option(..., "--out-dir", help="Folder for plan.csv, plan.h5, plan.json, plan.png."),
    force: bool = typer.Option(False, "--force", help="Overwrite existing plan files in --out-dir."),
) -> None:
    """Plan one excitation run (friction ladder, moves, broadband injection) within the machine's limits,
    pre-simulate it and write it; refuse (exit 2, nothing written) a plan that would break a limit."""
    outputs = Outputs(force=force, inputs=(spec,))
    outputs.add_dir(out_dir, PLAN_NAMES, "--out-dir")
    console = Console(stderr=False)
    with outputs:
        s = load_excite_spec(spec)
        with console.status("designing the plan ...", spinner="dots") as status:
            plan = plan_run(s, progress=lambda msg: status.update(msg))
        stage = outputs.staging(out_dir)
        write_plan_csv(stage / "plan.csv", plan)
        write_plan_h5(stage / "plan.h5", plan)
        write_json_atomic(stage / "plan.json", plan.to_dict())
        from commission.cli.plots_excite import plan_plot

        plan_plot(plan, stage / "plan.png")
    q, u = s.q_unit, s.u_unit
    pk = plan.peaks
    console.print(f"plan: {plan.duration:.2f} s ({plan.duration / 60:.2f} min), {plan.t.size} samples at "
                  f"{s.sample_rate:g} Hz, {len(plan.segments)} segments")
    for line in band_lines(plan):
        console.print(line, markup=False, soft_wrap=True)
    for g in plan.segments:
        extra = "".join(f", {k} {g.info[k]:.4g} {un}" for k, un in (("speed", f"{q}/s"), ("amplitude", u),
                                                                   ("acceleration", f"{q}/s^2")) if k in g.info)
        console.print(f"  {g.t_start:8.2f} - {g.t_end:8.2f} s  {g.name}{extra}")
    console.print("pre-simulation peaks (conservative models) against the limits:")
    console.print(f"  |u| {pk['u']:.4g} {u} <= u_max {s.u_max:g} {u}")
    console.print(f"  |q - start| {max(-pk['q_min'], pk['q_max']):.4g} {q} <= travel/2 {s.travel / 2:g} {q}")
    console.print(f"  |v| {pk['v']:.4g} {q}/s <= v_max {s.v_max:g} {q}/s")
    console.print(f"  |a| {pk['a']:.4g} {q}/s^2 <= a_max {s.a_max:g} {q}/s^2")
    if plan.motion_scale < 1.0:
        console.print(f"note: the moves' top speed and acceleration were lowered to {plan.motion_scale:.3g} of their "
                      "design to stay within the limits")
    if plan.injection_scale < 1.0:
        console.print(f"note: the injection was lowered to {plan.injection_scale:.3g} of its design amplitude "
                      "to stay within the limits")
    for name in PLAN_NAMES:
        console.print(f"wrote {out_dir / name}")
    console.print(f"next: play plan.csv on the drive (u_inject added to the holding loop's command), record t, q, u "
                  f"(CONTRACT §1), then: commission identify LOG --plan {out_dir / 'plan.json'}")
