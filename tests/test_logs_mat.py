"""The MATLAB readers, v5 and v7.3: shapes in MATLAB's order, corrupt files, the EMPS data (commission.logs.mat)."""

from __future__ import annotations

import h5py
import numpy as np
import pytest
import scipy.io
from log_writers import reference_arrays, write_mat73
from shared_paths import EMPS_DIR

from commission.errors import DataError, InputFileError
from commission.logs import load_log

EMPS = EMPS_DIR
EMPS_GAIN = 35.15065188248547
EMPS_MAP = {"q": "qm", "u": "vir"}
needs_emps = pytest.mark.skipif(not (EMPS / "DATA_EMPS.mat").exists(), reason="EMPS data not present")


def test_row_and_column_vectors_are_flattened(tmp_path):
    a = reference_arrays(50)
    path = tmp_path / "rows.mat"
    scipy.io.savemat(path, {"t": a["t"][None, :], "q": a["q"][:, None], "u": a["u"]}, oned_as="row")
    log = load_log(path)
    np.testing.assert_array_equal(log.t, a["t"])
    np.testing.assert_array_equal(log.q, a["q"])


def test_matlab_shapes_are_reported_in_matlab_order(tmp_path):
    a = reference_arrays(100)
    path = tmp_path / "m73.mat"
    write_mat73(path, {"t": a["t"], "q": a["q"]})
    with h5py.File(path, "a") as f:
        f["vir"] = np.zeros((3, 100))  # MATLAB sees 100×3
    with pytest.raises(DataError, match=r"m73\.mat: channel 'u' \('vir'\) has shape \(100, 3\)"):
        load_log(path, mapping={"u": "vir"})
    path5 = tmp_path / "m5.mat"
    scipy.io.savemat(path5, {"t": a["t"][:, None], "q": a["q"][:, None], "vir": np.zeros((100, 3))})
    with pytest.raises(DataError, match=r"m5\.mat: channel 'u' \('vir'\) has shape \(100, 3\)"):
        load_log(path5, mapping={"u": "vir"})


def test_corrupt_mat5_type_byte_is_an_error_not_a_crash(tmp_path):
    # scipy's compiled reader indexes a table with this byte unchecked (segfault);
    # the loader's structure walk must catch it first.
    a = reference_arrays(20)
    path = tmp_path / "corrupt.mat"
    scipy.io.savemat(path, {"t": a["t"][:, None], "q": a["q"][:, None], "u": a["u"][:, None]})
    data = bytearray(path.read_bytes())
    real_part_tag = 128 + 8 + 16 + 16 + 8  # header, matrix tag, flags, dims, name (small element)
    assert data[real_part_tag] == 9  # miDOUBLE
    data[real_part_tag] = 130
    path.write_bytes(bytes(data))
    with pytest.raises(InputFileError, match=r"corrupt\.mat: not a readable MATLAB file \(corrupt v5 structure: "
                                             r"unknown data type 130"):
        load_log(path)
    data[real_part_tag] = 9
    data[128 + 8 + 8 + 1] |= 0x08  # set the "complex" flag: scipy would read a missing imaginary part
    path.write_bytes(bytes(data))
    with pytest.raises(InputFileError, match=r"array of class 6 has 4 of its 5 parts"):
        load_log(path)


# --------------------------------------------------------------------------- #
# EMPS benchmark files (real data)
# --------------------------------------------------------------------------- #
@needs_emps
def test_emps_loads_with_mapping_and_gain():
    path = EMPS / "DATA_EMPS.mat"
    log = load_log(path, mapping=EMPS_MAP, input_gain=EMPS_GAIN)
    assert log.n == 24841
    assert log.t.shape == log.q.shape == log.u.shape == (24841,)
    assert log.t[0] == 0.0 and log.t[-1] == pytest.approx(24.84)
    assert log.sample_rate == pytest.approx(1000.0, rel=1e-4)
    # README: force gtau*vir spans -152.0 ... 145.5 N; qm spans -2.2e-5 ... 0.24638 m.
    assert round(log.u.min(), 1) == -152.0 and round(log.u.max(), 1) == 145.5
    assert log.q.min() == pytest.approx(-2.2e-5, rel=1e-3) and log.q.max() == pytest.approx(0.24638, rel=1e-4)
    assert log.q_ref is None
    assert log.sha256 == "6cf6814ae14618795da0101aae2bb97ff0c6351b0501b5492751b02b07facf7e"  # README
    with_ref = load_log(path, mapping=dict(EMPS_MAP, q_ref="qg"), input_gain=EMPS_GAIN)
    assert np.abs(with_ref.q_ref - with_ref.q).max() == pytest.approx(0.85e-3, abs=0.01e-3)  # README: 0.85 mm


@needs_emps
def test_emps_without_mapping_points_at_the_flag():
    with pytest.raises(DataError, match=r"DATA_EMPS\.mat: channel 'q' not found \(available: gtau, kp, kv, qg, qm, "
                                        r"t, vir\); use --map q=NAME"):
        load_log(EMPS / "DATA_EMPS.mat")
    with pytest.raises(DataError, match=r"channel 'u' \('gtau'\) has shape \(1, 1\) but channel 'q' \('qm'\) has shape \(24841, 1\)"):
        load_log(EMPS / "DATA_EMPS.mat", mapping={"q": "qm", "u": "gtau"})
