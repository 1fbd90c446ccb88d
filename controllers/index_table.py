"""The one table of the performance indexes: each index's name, label, unit and display scale.

Pure data (no numpy, no numba), so that the file formats (:mod:`commission.formats`) and the
report take their rows from it without importing simulation code; :mod:`.metrics` computes the
indexes and holds their record, :class:`~commission.controllers.metrics.Indexes`, whose field
order is this table's.
"""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class IndexRow:
    """One row of :data:`INDEX_TABLE`: how an index is named, labelled, scaled and unit-ed.

    Attributes
    ----------
    name : str
        Field of :class:`Indexes` and key in tuning.json / validation.json.
    label : str
        Label as the paper prints it (Unicode), without its unit.
    text : str
        The same label in plain ASCII, for terminals.
    unit : str
        ``"q"`` (the axis position unit: m or rad), ``"u"`` (the command's unit) or ``""``
        (dimensionless).
    scale : float
        Display scale: a ``"q"`` index is shown in micro-units (x 1e6), the rest as stored.
    fmt : str
        Display format of the scaled value.
    doc : str
        One-line meaning.
    """

    name: str
    label: str
    text: str
    unit: str
    scale: float
    fmt: str
    doc: str

    def heading(self, q_unit: str, u_unit: str, *, ascii: bool = False) -> str:
        """``label (unit)``: ``q_unit`` names the *scaled* position unit (e.g. ``um``), ``u_unit``
        the command's; a dimensionless index has no unit."""
        unit = {"q": q_unit, "u": u_unit}.get(self.unit, "")
        name = self.text if ascii else self.label
        return f"{name} ({unit})" if unit else name


#: The one table of the indexes: the six of Section 4.2, then the peak input.  Its order is the
#: field order of :class:`Indexes` and of the records in tuning.json and validation.json.
INDEX_TABLE: tuple[IndexRow, ...] = (
    IndexRow("e_M", "e_M", "e_M", "q", 1e6, "{:.3g}", "maximum |e| (transient)"),
    IndexRow("e_F", "e_F", "e_F", "q", 1e6, "{:.3g}", "maximum |e| over the final window (final accuracy)"),
    IndexRow("e_rms", "‖e‖rms", "||e||rms", "q", 1e6, "{:.3g}", "RMS tracking error"),
    IndexRow("u_rms", "‖u‖rms", "||u||rms", "u", 1.0, "{:.3g}", "RMS input"),
    IndexRow("du_rms", "‖Δu‖rms", "||du||rms", "u", 1.0, "{:.3g}", "RMS of the input increments (54)"),
    IndexRow("c_u", "c_u", "c_u", "", 1.0, "{:.2f}", "chattering du_rms / u_rms"),
    IndexRow("u_peak", "peak |u|", "peak |u|", "u", 1.0, "{:.3g}", "largest |u| over the recorded samples"),
)
#: Rows by name.
INDEX_ROWS: dict[str, IndexRow] = {r.name: r for r in INDEX_TABLE}
#: The six indexes of Section 4.2 (what :func:`indexes_kernel` returns, in its order).
INDEX_NAMES: tuple[str, ...] = tuple(r.name for r in INDEX_TABLE[:6])
#: The numbers of a run's record (the six indexes and ``u_peak``), as tuning.json stores them.
SCORE_NAMES: tuple[str, ...] = tuple(r.name for r in INDEX_TABLE)
