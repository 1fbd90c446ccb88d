"""The ExcitationLog type: immutable, copied, validated, hashed (commission.logs.model)."""

from __future__ import annotations

import numpy as np
import pytest
from log_writers import FS

from commission.errors import DataError
from commission.logs import ExcitationLog


def test_excitation_log_is_immutable_and_validated():
    t = np.arange(5) / FS
    q = np.zeros(5)
    log = ExcitationLog.from_arrays(t, q, np.ones(5), source="sim")
    q[0] = 99.0  # the caller's array is copied, not shared
    assert log.q[0] == 0.0
    with pytest.raises(ValueError):
        log.q[0] = 1.0
    with pytest.raises(AttributeError):
        log.u_unit = "N"  # type: ignore[misc]
    assert log.sample_rate == pytest.approx(FS)
    assert log.sha256 == ExcitationLog.from_arrays(t, np.zeros(5), np.ones(5)).sha256
    assert log.sha256 != ExcitationLog.from_arrays(t, np.zeros(5), np.full(5, 2.0)).sha256
    with pytest.raises(DataError, match=r"sim: channel 'u' has shape \(4,\) but channel 't' has shape \(5,\)"):
        ExcitationLog.from_arrays(t, q, np.ones(4), source="sim")
    with pytest.raises(DataError, match=r"sim: u_unit 'W' not supported"):
        ExcitationLog.from_arrays(t, q, np.ones(5), u_unit="W", source="sim")
