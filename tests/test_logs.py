"""Excitation-log loaders: formats, units, mapping, errors (commission.logs)."""

from __future__ import annotations

import hashlib
import math
import os
import pathlib
import tempfile
import time

import h5py
import numpy as np
import pytest
from shared_paths import EMPS_DIR
import scipy.io
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from hypothesis.extra import numpy as hnp

import commission.logs.hdf5 as hdf5_mod
from commission.errors import CommissionError, DataError, InputFileError, UsageError
from commission.logs import ExcitationLog, load_log, parse_mapping

EMPS = EMPS_DIR
EMPS_GAIN = 35.15065188248547
EMPS_MAP = {"q": "qm", "u": "vir"}
needs_emps = pytest.mark.skipif(not (EMPS / "DATA_EMPS.mat").exists(), reason="EMPS data not present")

N = 600
FS = 1000.0


# --------------------------------------------------------------------------- #
# Writers: independent of the loader, each in the layout its format's tools use.
# --------------------------------------------------------------------------- #
def reference_arrays(n: int = N) -> dict[str, np.ndarray]:
    rng = np.random.default_rng(7)
    t = np.arange(n) / FS
    q_ref = 0.05 * np.sin(2 * np.pi * 0.5 * t)
    q = np.round((q_ref + 1e-5 * rng.standard_normal(n)) / 1e-6) * 1e-6  # 1 um encoder
    u = 2.0 * np.sin(2 * np.pi * 0.5 * t + 0.3) + 0.01 * rng.standard_normal(n)
    return {"t": t, "q": q, "u": u, "q_ref": q_ref}


def write_h5(path, arrays, attrs=None) -> None:
    with h5py.File(path, "w") as f:
        for k, v in arrays.items():
            f.create_dataset(k, data=v)
        for k, v in (attrs or {}).items():
            f.attrs[k] = v


def write_csv(path, arrays) -> None:
    names = list(arrays)
    table = np.column_stack([arrays[k] for k in names])
    # %.17g round-trips every float64 exactly.
    np.savetxt(path, table, delimiter=",", header=",".join(names), comments="", fmt="%.17g")


def write_mat5(path, arrays) -> None:
    scipy.io.savemat(path, {k: np.asarray(v)[:, None] for k, v in arrays.items()})  # N×1 like EMPS


def write_mat73(path, arrays, attrs=None, matlab_class="double") -> None:
    """HDF5 with MATLAB's v7.3 layout: 512-byte userblock header, arrays stored transposed."""
    with h5py.File(path, "w", userblock_size=512) as f:
        for k, v in arrays.items():
            ds = f.create_dataset(k, data=np.asarray(v)[None, :])  # MATLAB N×1 -> HDF5 (1, N)
            ds.attrs["MATLAB_class"] = np.bytes_(matlab_class)
        for k, v in (attrs or {}).items():
            f.attrs[k] = v
    text = b"MATLAB 7.3 MAT-file, Platform: GLNXA64, Created on: Mon Jan  1 00:00:00 2024 HDF5 schema 1.00 ."
    header = text.ljust(116) + b"\x00" * 8 + b"\x00\x02" + b"IM"
    with open(path, "r+b") as fh:
        fh.write(header)


WRITERS = {
    "h5": write_h5,
    "csv": write_csv,
    "mat": write_mat5,
    "v73.mat": write_mat73,
}


# --------------------------------------------------------------------------- #
# Round trips
# --------------------------------------------------------------------------- #
@pytest.mark.parametrize("ext", list(WRITERS))
def test_round_trip_every_format(tmp_path, ext):
    a = reference_arrays()
    path = tmp_path / f"log.{ext}"
    WRITERS[ext](path, a)
    log = load_log(path)
    for name in ("t", "q", "u", "q_ref"):
        np.testing.assert_array_equal(getattr(log, name), a[name], err_msg=name)
    assert log.n == N
    assert log.sample_rate == pytest.approx(FS, rel=1e-9)
    assert (log.u_unit, log.q_unit_in_file, log.input_gain) == ("V", "m", 1.0)
    assert log.source == str(path)
    assert log.sha256 == hashlib.sha256(path.read_bytes()).hexdigest()


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


def test_input_gain_multiplies_u_only(tmp_path):
    a = reference_arrays()
    path = tmp_path / "log.h5"
    write_h5(path, a)
    log = load_log(path, input_gain=-2.5)
    np.testing.assert_array_equal(log.u, -2.5 * a["u"])
    np.testing.assert_array_equal(log.q, a["q"])
    assert log.input_gain == -2.5


def test_mapping_and_optional_q_ref(tmp_path):
    a = reference_arrays()
    path = tmp_path / "log.csv"
    write_csv(path, {"time": a["t"], "pos": a["q"], "cmd": a["u"], "extra": a["q_ref"]})
    log = load_log(path, mapping={"t": "time", "q": "pos", "u": "cmd"})
    assert log.q_ref is None  # not mapped, no column named q_ref
    np.testing.assert_array_equal(log.q, a["q"])
    log = load_log(path, mapping={"t": "time", "q": "pos", "u": "cmd", "q_ref": "extra"})
    np.testing.assert_array_equal(log.q_ref, a["q_ref"])


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


def test_csv_dialects_comments_quotes_semicolons(tmp_path):
    path = tmp_path / "log.csv"
    path.write_text('# exported by rig 3\nt; q ;u;mode\n0;1e-3;"0.5";run\n# pause\n0.001;2e-3;0.25;run\n\n')
    log = load_log(path)
    np.testing.assert_array_equal(log.t, [0.0, 0.001])
    np.testing.assert_array_equal(log.q, [1e-3, 2e-3])
    np.testing.assert_array_equal(log.u, [0.5, 0.25])


def test_row_and_column_vectors_are_flattened(tmp_path):
    a = reference_arrays(50)
    path = tmp_path / "rows.mat"
    scipy.io.savemat(path, {"t": a["t"][None, :], "q": a["q"][:, None], "u": a["u"]}, oned_as="row")
    log = load_log(path)
    np.testing.assert_array_equal(log.t, a["t"])
    np.testing.assert_array_equal(log.q, a["q"])


def test_integer_encoder_counts_are_accepted(tmp_path):
    path = tmp_path / "counts.h5"
    write_h5(path, {"t": np.arange(5) / FS, "q": np.arange(5, dtype=np.int32), "u": np.ones(5)},
             attrs={"q_unit": "um"})
    log = load_log(path)
    assert log.q.dtype == np.float64
    np.testing.assert_allclose(log.q, np.arange(5) * 1e-6, rtol=1e-15)


# --------------------------------------------------------------------------- #
# Time base and sample rate
# --------------------------------------------------------------------------- #
def test_sample_rate_builds_time_when_t_absent(tmp_path):
    a = reference_arrays()
    path = tmp_path / "no_t.h5"
    write_h5(path, {"q": a["q"], "u": a["u"]})
    log = load_log(path, sample_rate=2500.0)
    np.testing.assert_array_equal(log.t, np.arange(N) / 2500.0)
    assert log.sample_rate == 2500.0


def test_no_t_and_no_sample_rate_is_an_error(tmp_path):
    a = reference_arrays()
    path = tmp_path / "no_t.h5"
    write_h5(path, {"q": a["q"], "u": a["u"]})
    with pytest.raises(DataError, match=r"no_t\.h5: channel 't' not found \(available: q, u\); "
                                        r"use --map t=NAME or --sample-rate HZ"):
        load_log(path)


def test_sample_rate_with_t_is_cross_checked(tmp_path):
    a = reference_arrays()
    path = tmp_path / "log.h5"
    write_h5(path, a)
    log = load_log(path, sample_rate=1005.0)  # within 1 %: t is kept as recorded
    np.testing.assert_array_equal(log.t, a["t"])
    assert log.sample_rate == pytest.approx(FS)
    with pytest.raises(UsageError, match=r"--sample-rate 500 Hz disagrees with .*log\.h5: .* gives 1000 Hz"):
        load_log(path, sample_rate=500.0)


@pytest.mark.parametrize("kwargs, match", [
    ({"sample_rate": 0.0}, r"--sample-rate: expected a finite positive rate"),
    ({"sample_rate": math.nan}, r"--sample-rate: expected a finite positive rate"),
    ({"input_gain": 0.0}, r"--input-gain: expected a finite nonzero number"),
    ({"input_gain": math.inf}, r"--input-gain: expected a finite nonzero number"),
    ({"mapping": {"position": "qm"}}, r"--map position=qm: unknown channel 'position' \(expected one of t, q, u, q_ref\)"),
])
def test_bad_arguments_are_usage_errors(tmp_path, kwargs, match):
    path = tmp_path / "log.h5"
    write_h5(path, reference_arrays())
    with pytest.raises(UsageError, match=match):
        load_log(path, **kwargs)


# --------------------------------------------------------------------------- #
# parse_mapping
# --------------------------------------------------------------------------- #
def test_parse_mapping_accepts_name_equals_source():
    assert parse_mapping(["q=qm", " u = vir ", "q_ref=a=b"]) == {"q": "qm", "u": "vir", "q_ref": "a=b"}
    assert parse_mapping([]) == {}
    assert parse_mapping(["q=qm", "q=qm"]) == {"q": "qm"}  # a harmless repeat


@pytest.mark.parametrize("items, match", [
    (["qm"], r"--map 'qm': expected NAME=SOURCE, e\.g\. --map q=qm"),
    (["q="], r"--map 'q=': expected NAME=SOURCE"),
    (["=qm"], r"--map '=qm': expected NAME=SOURCE"),
    (["pos=qm"], r"--map 'pos=qm': unknown channel 'pos' \(expected one of t, q, u, q_ref\)"),
    (["q=qm", "q=qg"], r"--map q: given twice \('qm' and 'qg'\)"),
])
def test_parse_mapping_errors(items, match):
    with pytest.raises(UsageError, match=match):
        parse_mapping(items)


# --------------------------------------------------------------------------- #
# File and content errors
# --------------------------------------------------------------------------- #
def test_missing_file(tmp_path):
    path = tmp_path / "nope.h5"
    with pytest.raises(InputFileError, match=rf"^{path}: no such file$"):
        load_log(path)


def test_directory_and_unknown_extension(tmp_path):
    with pytest.raises(InputFileError, match=r"is a directory, not a log file"):
        load_log(tmp_path / ".")
    path = tmp_path / "log.txt"
    path.write_text("t,q,u\n0,0,0\n")
    with pytest.raises(InputFileError, match=r"log\.txt: unknown log format '\.txt' "
                                             r"\(expected \.h5, \.hdf5, \.csv, \.mat, \.npy or \.npz\)"):
        load_log(path)


PNG = b"\x89PNG\r\n\x1a\n\x00\x00\x00\rIHDR\x00\x00\x00\x10\x00\x00\x00\x10\x08\x06\x00\x00\x00\x1f\xf3\xffa" + bytes(200)


@pytest.mark.parametrize("name, match", [
    ("picture.h5", r"picture\.h5: not a readable HDF5 file \("),
    ("picture.mat", r"picture\.mat: not a readable MATLAB file \("),
    ("picture.csv", r"picture\.csv: not a readable CSV file \(not UTF-8 text at byte 0\)"),
])
def test_png_renamed_is_refused(tmp_path, name, match):
    path = tmp_path / name
    path.write_bytes(PNG)
    with pytest.raises(InputFileError, match=match):
        load_log(path)


def test_garbage_csv(tmp_path):
    path = tmp_path / "garbage.csv"
    path.write_text("hello world\nthis is not, a log\n")
    with pytest.raises(DataError, match=r"garbage\.csv: channel 't' not found \(available: hello world\)"):
        load_log(path)
    path.write_text("# only a comment\n\n")
    with pytest.raises(InputFileError, match=r"garbage\.csv: not a readable CSV file \(no header row\)"):
        load_log(path)
    path.write_text("t,q,u\n")
    with pytest.raises(DataError, match=r"garbage\.csv: no data rows after the header"):
        load_log(path)
    path.write_bytes(b"t,q,u\n0,0\x00,0\n")
    with pytest.raises(InputFileError, match=r"garbage\.csv: not a readable CSV file \(contains NUL bytes\)"):
        load_log(path)


@pytest.mark.parametrize("body, match", [
    ("t,q,u\n0,1,2\n0.001,1,x\n", r"bad\.csv: line 3, column 'u': cannot parse 'x' as a number"),
    ("t,q,u\n0,1,2\n0.001,,2\n", r"bad\.csv: line 3, column 'q': empty cell"),
    ("t,q,u\n0,1,2\n0.001,1\n", r"bad\.csv: line 3: 2 fields, but column 'u' is field 3"),
    ("t,q,u,q\n0,1,2,3\n", r"bad\.csv: channel 'q': column 'q' appears 2 times"),
])
def test_csv_cell_errors_name_line_and_column(tmp_path, body, match):
    path = tmp_path / "bad.csv"
    path.write_text(body)
    with pytest.raises(DataError, match=match):
        load_log(path)


def test_missing_channel_lists_what_the_file_has(tmp_path):
    path = tmp_path / "other.h5"
    write_h5(path, {"a": np.zeros(3), "b": np.zeros(3), "c": np.zeros(3), "t": np.arange(3.0), "q": np.zeros(3)})
    with pytest.raises(DataError, match=r"^.*other\.h5: channel 'u' not found \(available: a, b, c, q, t\); "
                                        r"use --map u=NAME$"):
        load_log(path)
    with pytest.raises(DataError, match=r"channel 'u' mapped to 'vir', which is not in the file \(available: a, b, c, q, t\)"):
        load_log(path, mapping={"u": "vir"})
    with pytest.raises(DataError, match=r"channel 'q_ref' mapped to 'qg', which is not in the file"):
        load_log(path, mapping={"u": "a", "q_ref": "qg"})


def test_shape_errors_name_channel_and_shapes(tmp_path):
    a = reference_arrays(100)
    path = tmp_path / "shape.h5"
    write_h5(path, dict(a, u=np.zeros((100, 3))))
    with pytest.raises(DataError, match=r"shape\.h5: channel 'u' has shape \(100, 3\); expected a 1-D array"):
        load_log(path)
    write_h5(path, dict(a, u=np.float64(1.0)))
    with pytest.raises(DataError, match=r"channel 'u' has shape \(\); expected a 1-D array"):
        load_log(path)
    write_h5(path, dict(a, u=a["u"][:99]))
    with pytest.raises(DataError, match=r"channel 'u' has shape \(99,\) but channel 'q' has shape \(100,\)"):
        load_log(path)
    write_h5(path, {k: v[:0] for k, v in a.items()})
    with pytest.raises(DataError, match=r"shape\.h5: channel 'q' is empty"):
        load_log(path)


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


def test_non_numeric_channels(tmp_path):
    a = reference_arrays(10)
    path = tmp_path / "types.mat"
    scipy.io.savemat(path, {"t": a["t"][:, None], "q": a["q"][:, None], "s": "volts",
                            "z": (a["u"] + 1j)[:, None], "st": {"x": 1.0}})
    with pytest.raises(DataError, match=r"channel 'u' \('s'\) holds text \(dtype <U5\); expected real numbers"):
        load_log(path, mapping={"u": "s"})
    with pytest.raises(DataError, match=r"channel 'u' \('z'\) is complex"):
        load_log(path, mapping={"u": "z"})
    with pytest.raises(DataError, match=r"channel 'u' \('st'\) is a struct/record"):
        load_log(path, mapping={"u": "st"})
    path73 = tmp_path / "char73.mat"
    write_mat73(path73, {"t": a["t"], "q": a["q"], "u": a["u"]}, matlab_class="char")
    with pytest.raises(DataError, match=r"char73\.mat: channel 't' has MATLAB class 'char'; expected a numeric array"):
        load_log(path73)
    pathg = tmp_path / "group.h5"
    write_h5(pathg, {"t": a["t"], "q": a["q"]})
    with h5py.File(pathg, "a") as f:
        f.create_group("u")
    with pytest.raises(DataError, match=r"group\.h5: channel 'u' is an HDF5 group, not a dataset"):
        load_log(pathg)


@pytest.mark.parametrize("attrs, match", [
    ({"q_unit": "in"}, r"units\.h5: attribute q_unit='in' not supported \(expected m, mm, um, rad\)"),
    ({"u_unit": "kV"}, r"units\.h5: attribute u_unit='kV' not supported \(expected V, N, A, Nm, %\)"),
])
def test_unknown_unit_attributes(tmp_path, attrs, match):
    path = tmp_path / "units.h5"
    write_h5(path, reference_arrays(10), attrs=attrs)
    with pytest.raises(DataError, match=match):
        load_log(path)


@pytest.mark.parametrize("ext, unit, per_metre", [("csv", "mm", 1e3), ("mat", "um", 1e6), ("h5", "m", 1.0)])
def test_q_unit_option_converts_files_without_the_attribute(tmp_path, ext, unit, per_metre):
    a = reference_arrays(40)
    scaled = {**a, "q": a["q"] * per_metre, "q_ref": a["q_ref"] * per_metre}
    path = tmp_path / f"log.{ext}"
    WRITERS[ext](path, scaled)
    log = load_log(path, q_unit=unit)
    assert log.q_unit_in_file == unit
    np.testing.assert_allclose(log.q, a["q"], rtol=1e-15, atol=0.0)
    np.testing.assert_allclose(log.q_ref, a["q_ref"], rtol=1e-15, atol=0.0)


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


# --------------------------------------------------------------------------- #
# Property-based tests
# --------------------------------------------------------------------------- #
PROPS = settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])

finite = st.floats(allow_nan=False, allow_infinity=False, width=64)


@st.composite
def channel_arrays(draw):
    n = draw(st.integers(min_value=1, max_value=40))
    arr = hnp.arrays(np.float64, n, elements=finite)
    return {"t": draw(arr), "q": draw(arr), "u": draw(arr)}


@PROPS
@given(arrays=channel_arrays(), ext=st.sampled_from(["csv", "h5", "mat", "v73.mat"]))
def test_random_finite_arrays_round_trip(arrays, ext):
    with tempfile.TemporaryDirectory() as d:
        path = pathlib.Path(d) / f"r.{ext}"
        WRITERS[ext](path, arrays)
        log = load_log(path)
    for name, arr in arrays.items():
        np.testing.assert_array_equal(getattr(log, name), arr, err_msg=name)
        # Exact bits, including the sign of zero.
        assert np.array_equal(np.signbit(getattr(log, name)), np.signbit(arr))


def _valid_file_bytes(ext: str) -> bytes:
    a = reference_arrays(64)
    with tempfile.TemporaryDirectory() as d:
        path = pathlib.Path(d) / f"v.{ext}"
        WRITERS[ext](path, a)
        return path.read_bytes()


VALID = {ext: _valid_file_bytes(ext) for ext in WRITERS}


@st.composite
def broken_file(draw):
    """Random bytes, a truncated valid file, or (CSV, MAT v5) a valid file with bytes overwritten.

    In-place corruption of HDF5 internals is not generated: libhdf5 itself can
    loop forever on some (e.g. a damaged global heap), which no reader can
    turn into an error without running it in a child process.
    """
    ext = draw(st.sampled_from(list(WRITERS)))
    valid = VALID[ext]
    kind = draw(st.sampled_from(["random", "truncated", "overwritten"] if ext in ("csv", "mat") else ["random", "truncated"]))
    if kind == "random":
        data = draw(st.binary(max_size=3000))
    elif kind == "truncated":
        data = valid[: draw(st.integers(0, len(valid) - 1))]
    else:
        data = bytearray(valid)
        for _ in range(draw(st.integers(1, 8))):
            data[draw(st.integers(0, len(data) - 1))] = draw(st.integers(0, 255))
        data = bytes(data)
    return ext, data


@PROPS
@given(case=broken_file())
def test_broken_files_give_a_clean_commission_error(case):
    ext, data = case
    with tempfile.TemporaryDirectory() as d:
        path = pathlib.Path(d) / f"broken.{ext}"
        path.write_bytes(data)
        try:
            log = load_log(path)
        except CommissionError as exc:
            assert str(exc).startswith(str(path)), str(exc)
            assert "\n" not in str(exc)
        else:
            # Overwriting a data byte can leave a valid file; it must still be a consistent log.
            assert log.t.shape == log.q.shape == log.u.shape
