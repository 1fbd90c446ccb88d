"""maxon EPOS Studio recorder files as a :class:`_Raw` (the parsing is :mod:`commission.logs.epos`)."""

from __future__ import annotations

from typing import Mapping

from commission.errors import UsageError
from commission.logs.raw import _Raw
from commission.logs.epos import read_epos_arrays


def _read_epos(data: bytes, label: str, mapping: Mapping[str, str]) -> _Raw:
    if mapping:
        raise UsageError(f"{label}: --map does not apply to an EPOS recorder file (its channels are fixed)")
    arrays = read_epos_arrays(data, label)
    vectors = {ch: (arrays[ch], arrays[ch].shape, src)  # type: ignore[union-attr]
               for ch, src in (("t", "time"), ("q", "integrated velocity"), ("u", "torque"))}
    return _Raw(vectors, q_unit="rad", u_unit=arrays["u_unit"], q_from_velocity=True)

