"""``gate.toml``, the validation gate of ``commission validate`` and ``run``: its one table of keys.

Every key of ``[gate]`` is one :class:`~commission.formats.table.Key` row of :data:`GATE_KEYS`,
with its default (or the rule of a derived default), accepted range, unit and one-line doc.
:func:`commission.gate.gate_from_mapping` validates through :data:`GateToml` (:func:`read_gate`)
and :func:`commission.gate.resolve_gate` takes its defaults from the rows (:class:`ErrorDefault`,
:class:`SpecMargin`); the ``--gate`` help of ``validate`` and ``run`` (:func:`gate_help`),
docs/interface.md §6 and docs/schemas/gate.schema.json are generated from them
(``python -m commission.formats``) and a test compares all three with the rows.

The error lines of a refused value are the ones this file has always given
(``gate.toml: gate.e_F = -1.0: must be a positive finite length in m``): :func:`error_line`
derives them from the row's type and range.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass
from typing import Any, Mapping

from pydantic import ValidationError

from commission.errors import SpecError
from commission.formats.table import Key, Length, build_model, help_lines

#: Version of docs/schemas/gate.schema.json.
SCHEMA_VERSION = 1
#: The factor tune aims at in the scenario-by-scenario ARC-vs-PID comparison when gate.toml leaves it off.
ARC_VS_PID_AIM = 1.0
#: The rms of uniform quantization noise in encoder steps, 1/sqrt(12): the default ARC-vs-PID slack.
QUANTIZATION_RMS_LSB = 1.0 / math.sqrt(12.0)


@dataclass(frozen=True)
class ErrorDefault:
    """A defaulted error limit: max(``lsb`` encoder steps, ``travel`` x the envelope's stroke[, ``factor`` x target]).

    ``target`` names the spec's ``[targets]`` key the limit is also at least ``factor`` times
    (None: none).  Where the PID yardstick sets a level, the limit also follows it
    (:func:`commission.gate.scenario_error_limit`).
    """

    lsb: float
    travel: float
    target: str | None = None
    factor: float = 4.0

    def formula(self, with_target: bool = True) -> str:
        """``max(30 LSB, 0.01 % travel[, 4 x targets.e_f])`` (the basis validation.json records)."""
        tgt = f", {self.factor:g} x targets.{self.target}" if self.target and with_target else ""
        return f"max({self.lsb:g} LSB, {self.travel * 100:g} % travel{tgt})"

    def text(self) -> str:
        return self.formula() + ", or the PID yardstick's value on a scenario where larger"


@dataclass(frozen=True)
class SpecMargin:
    """A margin floor whose default is the tuning spec's ``[margins] key`` (a floor gate.toml cannot lower)."""

    key: str

    def text(self) -> str:
        return f"the tuning spec's margins.{self.key} (a floor: a lower value here does not lower it)"


_POS = dict(range=(0.0, math.inf), open=(True, False))  # > 0, finite

GATE_KEYS: tuple[Key, ...] = (
    Key("gate", "e_F", Length, None, unit="m", rule=ErrorDefault(30.0, 1e-4, "e_f"), **_POS,
        doc="final accuracy: max |e| over the last 2 s (a number in m, or \"20 um\", \"30 lsb\", \"0.01 %travel\")"),
    Key("gate", "e_M", Length, None, unit="m", rule=ErrorDefault(200.0, 2e-3), **_POS,
        doc="transient: max |e| over the whole run (a length, as e_F)"),
    Key("gate", "e_rms", Length, None, unit="m", rule=ErrorDefault(15.0, 5e-5, "e_rms"), **_POS,
        doc="average: rms of e (a length, as e_F)"),
    Key("gate", "c_u", float, 1.0, unit="", **_POS, doc="chattering: ||du||_rms / ||u||_rms"),
    Key("gate", "u_max", float, None, unit="u-unit", rule="the tuning spec's controller.u_max", **_POS,
        doc="peak |u|; a command that reaches it fails (the controller relied on clipping)"),
    Key("gate", "no_divergence", bool, True, None, "",
        "no scenario may abort (non-finite, |q - q_d| > travel, |u| > 1e6); a floor whatever this says"),
    Key("gate", "arc_vs_pid_e_rms", float, None, unit="",
        rule=f"off (tune aims at {ARC_VS_PID_AIM:g}; the quantiles judge)", **_POS,
        doc="when given: ARC e_rms <= this factor x PID e_rms + arc_vs_pid_slack on every scenario"),
    Key("gate", "arc_vs_pid_slack", Length, None, unit="m", range=(0.0, math.inf),
        rule=f"LSB / sqrt(12) = {QUANTIZATION_RMS_LSB:.4g} lsb (the quantization noise rms)",
        doc="slack of the ARC-vs-PID comparisons (a length, as e_F; 0: strict)"),
    Key("gate", "arc_vs_pid_median", float, 1.0, unit="", **_POS,
        doc="median of the per-scenario factor f (ARC e_rms = f x PID e_rms + slack), fixed and Monte-Carlo apart"),
    Key("gate", "arc_vs_pid_p90", float, 1.2, unit="", **_POS, doc="90th percentile of that factor, per group"),
    Key("gate", "arc_vs_pid_nominal", float, 1.0, unit="", **_POS,
        doc="per case, ARC e_rms / PID e_rms summed over <case>/nominal, <case>/delay+1 and (a Coulomb-only fit) "
            "<case>/stribeck must be below it (no slack: a tie is not a win)"),
    Key("gate", "gain_margin_db", float, None, unit="dB", rule=SpecMargin("gain_db"), **_POS,
        doc="gain margin of the ARC on the identified plant (mode and delay included)"),
    Key("gate", "phase_margin_deg", float, None, unit="deg", rule=SpecMargin("phase_deg"), **_POS,
        doc="phase margin of the ARC on the identified plant"),
    Key("gate", "delay_margin_samples", float, None, unit="samples", rule=SpecMargin("delay_samples"), **_POS,
        doc="delay margin of the ARC, beyond the identified delay"),
    Key("gate", "modulus_margin", float, None, unit="", rule=SpecMargin("modulus"), **_POS,
        doc="modulus margin of the ARC: min |1 + L|"),
)

#: Key name -> its row.
GATE: dict[str, Key] = {k.name: k for k in GATE_KEYS}
#: The error-limit keys (lengths with an :class:`ErrorDefault`), in table order.
ERROR_KEYS: tuple[str, ...] = tuple(k.name for k in GATE_KEYS if isinstance(k.rule, ErrorDefault))
#: The margin keys of gate.toml -> the tuning spec's ``[margins]`` keys (= :class:`commission.robustness.MarginFloors`
#: attributes) they default to.
MARGIN_KEYS: dict[str, str] = {k.name: k.rule.key for k in GATE_KEYS if isinstance(k.rule, SpecMargin)}

#: The strict model of gate.toml (pydantic, built from :data:`GATE_KEYS`).
GateToml = build_model("GateToml", GATE_KEYS, "gate.toml: the validation gate of `commission validate`; "
                                              "every key optional.")

_LENGTH_HINT = '"20 um", "30 lsb", "0.01 %travel"'


def gate_help() -> str:
    """The ``--gate`` part of ``validate --help`` and ``run --help``: one line per key of the table."""
    return ("\b\nGate TOML (--gate): one table [gate]; every key optional (key = default, then what it is):\n"
            + "\n".join(help_lines(GATE_KEYS)) + "\n")


def error_line(k: Key, raw: Any, source: str) -> str:
    """The one error line of a refused value of ``k`` (the lines gate.toml has always given)."""
    path = f"{source}: gate.{k.name} = {raw!r}"
    if k.type is bool:
        return f"{path}: expected true or false"
    if k.type is Length:
        sign = "non-negative" if not k.open[0] else "positive"
        if isinstance(raw, bool):
            return f"{path}: expected a length (metres, or a string like {_LENGTH_HINT})"
        if isinstance(raw, (int, float)):
            return f"{path}: must be a {sign} finite length in m"
        if isinstance(raw, str):
            if not re.match(Length.PATTERN, raw):
                return f"{path}: expected \"<number> <unit>\" with unit m, mm, um, nm, lsb or %travel"
            return f"{path}: must be {sign}"
        return f"{path}: expected a number (m) or a string like \"20 um\""
    unit = f" in {k.unit}" if k.unit else ""
    return f"{path}: expected a positive finite number{unit}"


def read_gate(data: Mapping[str, Any], source: str) -> dict[str, Any]:
    """The keys a parsed gate.toml gives, validated through :data:`GateToml`; raises :class:`SpecError`.

    The first error named is an unknown section, then a ``[gate]`` that is not a table, then an
    unknown key (in the file's order), then the first refused value in table order.
    """
    if not isinstance(data, Mapping):
        raise SpecError(f"{source}: expected a table, got {type(data).__name__}")
    for section in data:
        if section != "gate":
            raise SpecError(f"{source}: {section}: unknown section (expected only [gate])")
    table = data.get("gate", {})
    if not isinstance(table, Mapping):
        raise SpecError(f"{source}: gate: expected a table, got {table!r}")
    for key in table:
        if key not in GATE:
            raise SpecError(f"{source}: gate.{key}: unknown key (known: {', '.join(GATE)})")
    try:
        GateToml.model_validate({"gate": dict(table)})
    except ValidationError as exc:
        bad = {str(e["loc"][1]) for e in exc.errors() if len(e["loc"]) > 1}
        k = next(k for k in GATE_KEYS if k.name in bad)
        raise SpecError(error_line(k, table[k.name], source)) from None
    return {k.name: table[k.name] for k in GATE_KEYS if k.name in table}
