"""The HDF5 reader: unit attributes, nested datasets, and the isolated child read (commission.logs.hdf5)."""

from __future__ import annotations

import os
import time

import h5py
import numpy as np
import pytest
from log_writers import reference_arrays, write_h5, write_mat73

import commission.logs.hdf5 as hdf5_mod
from commission.errors import DataError, InputFileError, UsageError
from commission.logs import load_log


@pytest.mark.parametrize("unit, per_metre", [("mm", 1e3), ("um", 1e6)])
@pytest.mark.parametrize("ext", ["h5", "hdf5", "v73.mat"])
def test_q_unit_attribute_converts_to_metres(tmp_path, unit, per_metre, ext):
    a = reference_arrays()
    stored = dict(a, q=a["q"] * per_metre, q_ref=a["q_ref"] * per_metre)
    path = tmp_path / f"log.{ext}"
    writer = write_mat73 if ext.endswith(".mat") else write_h5
    writer(path, stored, attrs={"q_unit": unit, "u_unit": "N"})
    log = load_log(path)
    np.testing.assert_allclose(log.q, a["q"], rtol=1e-15, atol=0)
    np.testing.assert_allclose(log.q_ref, a["q_ref"], rtol=1e-15, atol=0)
    np.testing.assert_array_equal(log.u, a["u"])  # u is never unit-converted
    assert (log.q_unit_in_file, log.u_unit) == (unit, "N")


def test_hdf5_mapping_may_name_a_nested_dataset(tmp_path):
    a = reference_arrays()
    path = tmp_path / "log.h5"
    with h5py.File(path, "w") as f:
        g = f.create_group("run1")
        for k, v in a.items():
            g[k] = v
    log = load_log(path, mapping={"t": "run1/t", "q": "run1/q", "u": "run1/u"})
    np.testing.assert_array_equal(log.u, a["u"])
    with pytest.raises(DataError, match=r"channel 't' not found \(available: run1/\)"):
        load_log(path)


@pytest.mark.parametrize("attrs, match", [
    ({"q_unit": "in"}, r"units\.h5: attribute q_unit='in' not supported \(expected m, mm, um, rad\)"),
    ({"u_unit": "kV"}, r"units\.h5: attribute u_unit='kV' not supported \(expected V, N, A, Nm, %\)"),
])
def test_unknown_unit_attributes(tmp_path, attrs, match):
    path = tmp_path / "units.h5"
    write_h5(path, reference_arrays(10), attrs=attrs)
    with pytest.raises(DataError, match=match):
        load_log(path)


def test_q_unit_option_must_agree_with_the_attribute(tmp_path):
    path = tmp_path / "units.h5"
    write_h5(path, reference_arrays(10), attrs={"q_unit": "mm"})
    assert load_log(path, q_unit="mm").q_unit_in_file == "mm"
    with pytest.raises(UsageError, match=r"^--q-unit um disagrees with .*units\.h5: its attribute q_unit='mm'$"):
        load_log(path, q_unit="um")
    with pytest.raises(UsageError, match=r"^--q-unit: expected one of m, mm, um, rad, got 'in'$"):
        load_log(path, q_unit="in")


def test_non_text_unit_attribute_is_named_by_its_value(tmp_path):
    # Crosses the isolated HDF5 reader as a repr, not as a string: still refused, same message.
    path = tmp_path / "units.h5"
    write_h5(path, reference_arrays(10), attrs={"q_unit": np.int64(3)})
    with pytest.raises(DataError, match=r"units\.h5: attribute q_unit=(np\.int64\()?3\)? not supported"):
        load_log(path)


def _damaged_heap_h5(path) -> None:
    """An HDF5 log whose q_unit string lives in a global heap with a corrupted free-space record.

    The global heap collection ("GCOL", version 1, 8-byte lengths) holds object 1 = "mm"
    and then the free-space object 0; its size field is overwritten with 193.  With
    h5py 3.16 / HDF5 2.0 reading the attribute then never returns (found by fuzzing
    the sample log: one byte changed).
    """
    a = reference_arrays(200)
    write_h5(path, {"t": a["t"], "q": a["q"], "u": a["u"]}, attrs={"q_unit": "mm"})
    data = bytearray(path.read_bytes())
    g = data.find(b"GCOL")
    assert g > 0 and data[g + 4] == 1
    obj1 = g + 16  # header: signature, version, 3 reserved, collection size
    assert int.from_bytes(data[obj1:obj1 + 2], "little") == 1 and data[obj1 + 16:obj1 + 18] == b"mm"
    free = obj1 + 16 + 8  # object 1: index, refcount, reserved, size, "mm" padded to 8
    assert int.from_bytes(data[free:free + 2], "little") == 0
    data[free + 8:free + 16] = (193).to_bytes(8, "little")
    path.write_bytes(bytes(data))


def test_hdf5_file_that_hangs_the_library_is_refused_at_the_deadline(tmp_path, monkeypatch):
    path = tmp_path / "damaged.h5"
    _damaged_heap_h5(path)
    monkeypatch.setattr(hdf5_mod, "HDF5_READ_TIMEOUT", 2.0)
    with pytest.raises(InputFileError, match=r"damaged\.h5: not a readable HDF5 file \("):
        load_log(path)


def test_hdf5_reader_child_that_never_returns_is_killed(tmp_path, monkeypatch):
    path = tmp_path / "log.h5"
    write_h5(path, reference_arrays(10))

    def stuck(*args, **kwargs):
        while True:
            time.sleep(1.0)

    monkeypatch.setattr(hdf5_mod, "_read_hdf5_here", stuck)
    monkeypatch.setattr(hdf5_mod, "HDF5_READ_TIMEOUT", 0.5)
    with pytest.raises(InputFileError, match=r"log\.h5: not a readable HDF5 file \(the HDF5 library did not "
                                             r"finish reading it within 1 s; the file is probably damaged\)$"):
        load_log(path)


def test_hdf5_reader_child_that_dies_is_reported(tmp_path, monkeypatch):
    path = tmp_path / "log.h5"
    write_h5(path, reference_arrays(10))
    monkeypatch.setattr(hdf5_mod, "_read_hdf5_here", lambda *args, **kwargs: os._exit(3))
    with pytest.raises(InputFileError, match=r"log\.h5: not a readable HDF5 file \(the HDF5 reader stopped "
                                             r"without a result\)$"):
        load_log(path)


def test_hdf5_isolated_read_equals_the_in_process_read(tmp_path):
    a = reference_arrays(50)
    path = tmp_path / "log.h5"
    write_h5(path, a, attrs={"q_unit": "mm", "u_unit": "A"})
    data = path.read_bytes()
    args = (data, "log.h5", "HDF5", {}, True)
    here = hdf5_mod._read_hdf5_here(*args, matlab=False)
    there = hdf5_mod._read_hdf5(*args, matlab=False)
    assert (there.q_unit, there.u_unit) == (here.q_unit, here.u_unit) == ("mm", "A")
    assert there.vectors.keys() == here.vectors.keys() == {"t", "q", "u", "q_ref"}
    for ch, (arr, shown, src) in here.vectors.items():
        arr2, shown2, src2 = there.vectors[ch]
        assert (shown2, src2) == (shown, src) and arr2.dtype == arr.dtype
        np.testing.assert_array_equal(arr2, arr)
