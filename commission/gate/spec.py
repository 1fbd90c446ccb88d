"""What a ``gate.toml`` says: :class:`GateSpec`, read through the table of
:data:`commission.formats.gate_toml.GATE_KEYS`.

The table holds every key's type, default, range, unit and error line
(:func:`commission.formats.gate_toml.read_gate`); this module only turns the values it accepted
into a :class:`GateSpec`: error limits as :class:`ErrorLimit` (a number in metres, or
``"<number> <unit>"`` with unit ``m``, ``mm``, ``um`` (or ``µm``), ``nm``, ``lsb`` (encoder steps
of the tuning's quantization) or ``%travel`` (percent of the envelope's ``trajectory.travel``)),
the margin keys as one mapping.  ``None`` marks a key
left at its default; :func:`commission.gate.limits.resolve_gate` resolves the defaults for an axis.
"""

from __future__ import annotations

import dataclasses
import os
import re
from dataclasses import dataclass
from typing import Any, Mapping

from commission.infra.files import read_toml
from commission.formats.gate_toml import GATE, MARGIN_KEYS, read_gate
from commission.formats.table import Length


@dataclass(frozen=True)
class ErrorLimit:
    """An error limit as written: ``value`` in ``unit`` (``m``, ``lsb`` or ``%travel``).

    Attributes
    ----------
    value : float
        In metres for ``unit == "m"``, in encoder steps for ``"lsb"``, in
        percent of the travel for ``"%travel"``.
    unit : str
    text : str
        The TOML value as written (for reports).
    """

    value: float
    unit: str
    text: str

    def metres(self, lsb: float, travel: float) -> float:
        """The limit in metres for an encoder of ``lsb`` m and an envelope stroke ``travel`` m."""
        if self.unit == "lsb":
            return self.value * lsb
        if self.unit == "%travel":
            return self.value * 1e-2 * travel
        return self.value


@dataclass(frozen=True)
class GateSpec:
    """A parsed ``gate.toml``; ``None`` marks a key left at its default (:mod:`commission.gate.limits`).

    One attribute per key of :data:`commission.formats.gate_toml.GATE_KEYS`, whose row states its
    meaning, unit, range and default; the margin keys are gathered in ``margins``.

    Attributes
    ----------
    e_F, e_M, e_rms, arc_vs_pid_slack : ErrorLimit or None
        The lengths, as written.
    c_u, u_max, arc_vs_pid_e_rms, arc_vs_pid_median, arc_vs_pid_p90, arc_vs_pid_nominal : float or None
        The numbers (``arc_vs_pid_e_rms`` None: the scenario-by-scenario comparison is off).
    no_divergence : bool
    margins : mapping of str to float
        The margin keys given (:data:`~commission.formats.gate_toml.MARGIN_KEYS`); absent keys take
        the tuning spec's ``[margins]``.
    source : str
        File name (or ``"defaults"``).
    """

    e_F: ErrorLimit | None = None
    e_M: ErrorLimit | None = None
    e_rms: ErrorLimit | None = None
    c_u: float | None = None
    u_max: float | None = None
    no_divergence: bool = True
    arc_vs_pid_e_rms: float | None = None
    arc_vs_pid_slack: ErrorLimit | None = None
    source: str = "defaults"
    margins: Mapping[str, float] = dataclasses.field(default_factory=dict)
    arc_vs_pid_median: float | None = None
    arc_vs_pid_p90: float | None = None
    arc_vs_pid_nominal: float | None = None



def _error_limit(raw: Any) -> ErrorLimit:
    """A length the table accepted: metres, or a value in encoder steps or percent of the travel."""
    if isinstance(raw, str):
        m = re.match(Length.PATTERN, raw)
        assert m is not None  # the table's pattern accepted it
        val, unit = float(m.group(1)), m.group(2)
        if unit in Length.UNITS:
            return ErrorLimit(val * Length.UNITS[unit], "m", raw.strip())
        return ErrorLimit(val, unit, raw.strip())
    return ErrorLimit(float(raw), "m", repr(raw))


def gate_from_mapping(data: Mapping[str, Any], source: str = "gate.toml") -> GateSpec:
    """Validate a parsed gate TOML through its table (:func:`commission.formats.gate_toml.read_gate`).

    Parameters
    ----------
    data : mapping
        Parsed TOML: an optional ``[gate]`` table and nothing else.
    source : str
        File name, the first word of every error.

    Returns
    -------
    GateSpec

    Raises
    ------
    SpecError
        Naming the key (``gate.toml: gate.e_F = -1: ...``): an unknown section
        or key, a wrong type, a non-positive limit or an unknown unit.
    """
    given = read_gate(data, source)
    kw: dict[str, Any] = {"source": source}
    for key, raw in given.items():
        kind = GATE[key].type
        if key in MARGIN_KEYS:
            continue
        kw[key] = _error_limit(raw) if kind is Length else raw if kind is bool else float(raw)
    kw["margins"] = {k: float(given[k]) for k in MARGIN_KEYS if k in given}
    return GateSpec(**kw)


def load_gate(path: str | os.PathLike[str] | None) -> GateSpec:
    """Read and validate ``gate.toml``; ``None`` gives the defaults.

    Raises
    ------
    InputFileError
        The file is missing.
    SpecError
        The TOML does not parse, or a key is bad (:func:`gate_from_mapping`).
    """
    if path is None:
        return GateSpec()
    name = os.fspath(path)
    return gate_from_mapping(read_toml(name), name)
