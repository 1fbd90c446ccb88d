"""What to do after ``validate`` (and ``run``): the next step, always said.

On a pass, the export command for the target and a first, reduced-speed test on the
machine with the signals to watch.  On a failure, the two or three changes that would
make the gate pass, with values:

* a criterion that ``gate.toml`` may set (e_F, e_M, e_rms, c_u, the ARC-vs-PID factor and quantiles)
  and that failed on runs that did not diverge: the limit this controller meets, the
  worst value measured on the same scenarios rounded up with a 5 % allowance.
  Validation is deterministic for a given ``--seed`` and ``--monte-carlo``, so
  validating again with that ``gate.toml`` passes those checks; whether the looser
  limit is acceptable for the machine is the engineer's call, and the text says so;
* a floor that no ``gate.toml`` lowers (divergence, the command reaching u_max, the
  stability margins): what to change in the identification or the tuning spec, with
  the values that bound it (the envelope's acceleration scaled by the command's
  headroom, a narrower payload box).  These cannot be promised to pass: they change
  the controller, which is then validated anew.

The texts are built here once and printed by the CLI and written into ``report.md``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Sequence

#: Criteria a gate.toml sets, with how their suggested limit is written.
ADJUSTABLE = ("e_F", "e_M", "e_rms", "c_u", "arc_vs_pid_e_rms", "arc_vs_pid_median", "arc_vs_pid_p90",
              "arc_vs_pid_nominal")
#: Allowance over the worst measured value for a suggested limit.
ALLOWANCE = 1.05
#: Fraction of the validated envelope's speed and acceleration for the first test on the machine.
FIRST_TEST_FRACTION = 0.25


@dataclass(frozen=True)
class NextSteps:
    """The next step after a validation.

    Built once (:func:`next_steps`) and rendered twice: :meth:`text` for the console,
    :meth:`markdown` for report.md, so that both say the same.

    Attributes
    ----------
    lines : tuple of str
        Plain sentences (commands in backticks), most useful first.
    gate_toml : str
        On a failure that loosening the gate would cure: the ``[gate]`` table that
        passes with this controller ("" otherwise).
    preface : str
        A sentence said before the steps ("" for none): what ``run`` already tried.
    """

    lines: tuple[str, ...]
    gate_toml: str = ""
    preface: str = ""

    def text(self) -> str:
        """The console form: a heading, the preface, and one numbered line each."""
        head = "next:" + (f" {self.preface}" if self.preface else "")
        body = [f"  {i}. {line}" for i, line in enumerate(self.lines, 1)]
        table = [f"       {t}" for t in self.gate_toml.splitlines()]
        return "\n".join([head, *body[:1], *table, *body[1:]])

    def markdown(self) -> list[str]:
        """The report's section."""
        from commission.report.text import md_text

        out = ["## Next steps", ""]
        if self.preface:  # names scenarios and, for a refused try, the spec's own words: escaped
            out += [md_text(self.preface), ""]
        out += [f"{i}. {line}" for i, line in enumerate(self.lines, 1)]
        if self.gate_toml:
            out += ["", "```toml", self.gate_toml.rstrip("\n"), "```"]
        out.append("")
        return out


def _round_up(x: float, digits: int = 2) -> float:
    """``x`` rounded up to ``digits`` significant digits (x > 0)."""
    if x <= 0 or not math.isfinite(x):
        return x
    e = math.floor(math.log10(x)) - (digits - 1)
    q = 10.0 ** e
    return math.ceil(x / q - 1e-9) * q


def _length_literal(metres: float, lsb: float, q_unit: str) -> str:
    """A gate length as gate.toml takes it: micrometres on a linear axis, encoder steps otherwise."""
    if q_unit == "m":
        return f'"{_round_up(metres * 1e6):.6g} um"'
    return f'"{_round_up(metres / lsb):.6g} lsb"'


def _length_text(metres: float, q_unit: str) -> str:
    return f"{metres * 1e6:.3g} um" if q_unit == "m" else f"{metres:.3g} {q_unit}"


def _worst(checks: Sequence[Any]) -> Any:
    return max(checks, key=lambda c: c.value)


def gate_changes(verdict: Any, q_unit: str = "m") -> tuple[list[str], str]:
    """(sentences, gate.toml text) for the failed criteria that gate.toml may loosen.

    A criterion with a failure on a diverged run is left out: no limit cures a divergence.
    """
    limits = verdict.limits
    sentences: list[str] = []
    toml: list[str] = []
    for key in ADJUSTABLE:
        checks = [c for c in verdict.checks if c.criterion == key]
        failed = [c for c in checks if not c.passed]
        if not failed or any(not math.isfinite(c.value) for c in checks):
            continue
        w = _worst(checks)
        target = w.value * ALLOWANCE
        if key in ("e_F", "e_M", "e_rms"):
            lit = _length_literal(target, limits.lsb, q_unit)
            shown = _length_text(w.value, q_unit)
        else:
            lit = f"{_round_up(target, 3):.6g}"
            shown = f"{w.value:.3g}"
        toml.append(f"{key} = {lit}")
        sentences.append(f"`{key} = {lit}` (worst {shown} on {w.scenario}; {len(failed)} of {len(checks)} "
                         "checks failed)")
    text = ("[gate]\n" + "\n".join(toml) + "\n") if toml else ""
    return sentences, text


def floor_changes(verdict: Any, tuning: Any, q_unit: str = "m", u_unit: str = "u",
                  payload_tried: bool = False) -> list[str]:
    """Sentences for failed floors (divergence, command at u_max, margins): what to change in the tuning.

    ``payload_tried``: ``run`` already tried the axis as identified (no payload), so a narrower
    payload box is not offered.
    """
    out: list[str] = []
    spec = tuning.spec
    by = {}
    for c in verdict.failures:
        by.setdefault(c.criterion, []).append(c)
    if "u_peak" in by:
        w = _worst(by["u_peak"])
        # The command at the envelope's peak acceleration is about M a: scale a_max by the headroom.
        a_new = _round_up(spec.a_max * 0.8 * spec.u_max / max(w.value, spec.u_max), 2)
        # With the machine's moves the envelope is theirs: slow the moves (or the reference cases).
        where = (f"`[trajectory] a_max = {a_new:g}` ({q_unit}/s^2; now {spec.a_max:g})" if spec.profile is None else
                 f"slower machine moves (a_max <= {a_new:g} {q_unit}/s^2 in the profile; now {spec.a_max:g}) or "
                 f"`[trajectory] reference_a_max` for Case 1 and Case 2 (now {spec.case_a_max:.3g})")
        out.append(f"the command reached u_max = {spec.u_max:g} {u_unit} on {len(by['u_peak'])} scenarios "
                   f"(worst {w.scenario}): tune again with a gentler envelope, {where} in spec.toml"
                   + ("" if payload_tried else ", or a narrower payload box (`commission identify --payload-max ...`)"
                      " if the heaviest load is not needed"))
    if "divergence" in by:
        names = sorted({c.scenario for c in by["divergence"]})
        shown = ", ".join(names[:3]) + (f" and {len(names) - 3} more" if len(names) > 3 else "")
        out.append(f"{len(names)} scenarios diverged ({shown}): tune again with a larger search "
                   f"(`[tune] budget = {min(10000, 2 * spec.budget)}` in spec.toml, now {spec.budget})"
                   + ("" if payload_tried else " or a narrower payload box")
                   + "; no gate setting deploys a diverging controller")
    if "margins" in by:
        w = by["margins"][0]
        out.append(f"stability margins below the floors ({w.scenario}: {w.detail}): tune again "
                   f"(`[tune] budget = {min(10000, 2 * spec.budget)}`), and if the identified mode or delay "
                   "is uncertain, record a log with a broadband segment so that the model is backed up to "
                   "the loop's crossover")
    return out


def next_steps(result: Any, tuning: Any, *, out_dir: str = ".", tuning_path: str = "tuning.json",
               signed: bool = False, also_tried: str | None = None) -> NextSteps:
    """The next step after ``validate`` (module docstring).

    Parameters
    ----------
    result : ValidationResult
    tuning : Tuning
        The tuning validated (its spec gives the envelope and u_max).
    out_dir : str
        Where validate wrote (for the export command).
    tuning_path : str
        The tuning.json validated (for ``export --tuning``).
    signed : bool
        controller.json was signed (the export command then names the key).
    also_tried : str, optional
        ``run``'s second try on the axis as identified, failed too
        (:attr:`commission.pipeline.RunOutcome.also_tried`): said before the steps
        (:attr:`NextSteps.preface`), which then do not offer a narrower payload box.
    """
    q = result.units.get("q", "m")
    u = result.units.get("u", "u")
    spec = tuning.spec
    verdict = result.verdict
    if verdict.passed:
        key = " --sign-key site.key" if signed else ""
        f = FIRST_TEST_FRACTION
        lines = (
            f"export for the drive: `commission export {out_dir}/controller.json --target c "
            f"--out-dir {out_dir}/deploy --tuning {tuning_path}{key}` (or `--target st`); build it and run "
            "`./replay test_vectors.csv` on the target: it must report 0 difference",
            f"first test on the machine, at {f:.0%} of the validated envelope: moves within the travel "
            f"{spec.travel:g} {q} at v <= {f * spec.v_max:.3g} {q}/s and a <= {f * spec.a_max:.3g} {q}/s^2, the "
            f"drive limited to u_max = {spec.u_max:g} {u}; log y, q_d, u and the fault flag every sample; "
            "stop (disable the drive) on a fault, a command that reaches u_max, or a tracking error "
            f"above the gate's e_M = {_length_text(verdict.limits.e_M, q)}; then raise the speed in steps "
            "to the envelope",
            "keep report.md and controller.json together: the report is the evidence the controller rests on",
        )
        ev = evidence_step(result, tuning)
        return NextSteps(lines + ((ev,) if ev else ()))
    sentences, toml = gate_changes(verdict, q)
    floors = floor_changes(verdict, tuning, q, u, payload_tried=bool(also_tried))
    lines: list[str] = []
    if toml:
        lines.append("if the machine allows the looser limits, set these keys in the gate.toml and validate "
                     "again (same --seed and --monte-carlo; this controller then passes them): "
                     + ", ".join(sentences))
    lines.extend(floors)
    if toml:
        lines.append("or keep the gate and ask more of the controller: tune again with a larger search"
                     + ("" if also_tried else " or a narrower payload box") + ", then validate again")
    ev = evidence_step(result, tuning)
    if ev and any(c.scenario.startswith(("evidence/", "measured/")) for c in verdict.failures):
        lines.insert(0, ev)  # the missing evidence is what refused it
    elif ev:
        lines = lines[:3] + [ev]
    # no payload box is narrower than none: said before the steps, which then do not offer one
    preface = (f"{also_tried[:1].upper()}{also_tried[1:]}; these outputs are the default payload range's try, and a "
               "narrower payload box is not the remedy." if also_tried else "")
    return NextSteps(tuple(lines[:4]), toml, preface)


# --------------------------------------------------------------------------- identify's side: missing evidence

#: A drive's analog command range, V: the assumed ``u_max`` of a log whose u is volts times ``--input-gain``.
ANALOG_COMMAND_RANGE_V = 10.0
from commission.excite import SKETCH_BANDWIDTH_HZ  # noqa: E402  (the sketch's builder owns it)


@dataclass(frozen=True)
class ExciteAdvice:
    """What the log lacks and the ``commission excite`` run that would supply it.

    identify stores :meth:`to_dict` in ident.json, and the CLI prints :meth:`text` from there,
    so that the advice is the one recorded.

    Attributes
    ----------
    missing : tuple of str
        The missing evidence, one sentence each.
    command : str
        ``commission excite --spec limits.toml --out-dir DIR``.
    limits_toml : str
        A ``limits.toml`` for the machine, from what the log shows (commented).
    """

    missing: tuple[str, ...]
    command: str
    limits_toml: str

    def text(self) -> str:
        """The console form."""
        out = ["missing evidence:"] + [f"  - {m}" for m in self.missing]
        out += [f"to supply it, plan an excitation run: {self.command}", "  with limits.toml (a sketch from this log; "
                "check every value against the machine):"]
        out += [f"    {line}" for line in self.limits_toml.rstrip("\n").splitlines()]
        return "\n".join(out)

    def to_dict(self) -> dict[str, Any]:
        return {"missing": list(self.missing), "excite_command": self.command, "limits_toml": self.limits_toml}


def excite_advice(frequency_response: dict[str, Any] | None, *, travel: float, v_peak: float, a_peak: float,
                  u_peak: float, u_max: float | None, u_max_source: str, sample_rate: float,
                  M: float | None, B: float | None, fc: float | None, q_unit: str, u_unit: str,
                  out_dir: str = "excite_plan") -> ExciteAdvice | None:
    """The evidence a log lacks for the certificate and the ``excite`` run that supplies it (None: nothing lacks).

    A log without a broadband segment backs the rigid model only up to the band its
    reference excites (``frequency_response.band_hz``); tuned loops cross over well above
    it, and modes and delay are not measured at all.  ``commission excite`` plans one run
    with a broadband injection within the machine's limits: the sketch takes them from
    the log (its span, peak speed and acceleration: what the machine is known to allow)
    and the drive's command limit ``u_max`` (given, or assumed, ``u_max_source`` says which),
    and the identified M, B and fc as ``[axis]`` guesses.

    Parameters
    ----------
    frequency_response : dict or None
        ident.json's ``frequency_response`` section.
    travel : float
        Span of the log's position, m (rad).
    v_peak, a_peak : float
        Peak speed (m/s) and acceleration (m/s^2) the log reached.
    u_peak : float
        Peak |u| of the log, u-unit.
    u_max : float or None
        The drive's command limit, u-unit (None: the log's peak is all that is known).
    u_max_source : str
        Where ``u_max`` comes from, for the sketch's comment.
    sample_rate : float
        Hz.
    M, B, fc : float or None
        Identified mass, viscous and Coulomb level (u-unit s^2/m, u-unit s/m, u-unit).
    q_unit, u_unit : str
    out_dir : str
        The ``--out-dir`` of the printed command.
    """
    fr = frequency_response or {}
    if fr and fr.get("source") == "broadband":
        return None
    band = fr.get("band_hz") if fr else None
    top = f"{band[1]:.3g} Hz" if band else "no frequency at all (no band of coherent data)"
    missing = [f"no broadband segment in the log: the model is backed only to {top}; structural modes, the input "
               "delay and the response above are not measured, and a loop tuned on it crosses over where the data "
               "say nothing"]
    if not fr:
        missing = ["no frequency response (M is not identified): nothing is known of the plant's dynamics"]
    from commission.excite import limits_toml_sketch

    umax = u_max if u_max is not None else u_peak
    toml = limits_toml_sketch(
        travel=travel, v_max=v_peak, a_max=a_peak, u_max=umax, sample_rate=sample_rate, M=M, B=B, fc=fc,
        q_unit=q_unit, u_unit=u_unit,
        notes={"travel": "the span this log used (more if the machine allows)", "v_max": "the log's peak speed",
               "a_max": "the log's peak acceleration", "u_max": u_max_source, "sample_rate": "the log's rate",
               "mass": "identified", "friction": "identified Coulomb level", "viscous": "identified"})
    return ExciteAdvice(tuple(missing), f"commission excite --spec limits.toml --out-dir {out_dir}", toml)


def evidence_step(result: Any, tuning: Any) -> str | None:
    """What to record to raise the evidence (:func:`commission.evidence.raise_evidence_line`).

    Said unless the log already holds a broadband segment whose backed band reaches past the
    loop's crossover times the uncertainty weight's factor (nothing more to record then), or the
    validation recorded no evidence (an older result).
    """
    from commission.evidence import raise_evidence_line

    ev = getattr(result, "evidence", None)
    if ev is None:
        return None
    rows = getattr(result, "evidence_rows", ())
    if ev.source == "broadband" and all(r.holds for r in rows):
        return None
    return raise_evidence_line(ev, tuning.spec, tuning.identification)


__all__ = ["NextSteps", "evidence_step", "next_steps", "gate_changes", "floor_changes", "ExciteAdvice",
           "excite_advice", "SKETCH_BANDWIDTH_HZ"]
