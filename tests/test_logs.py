"""Excitation-log loading through every format: round trips, options, errors (commission.logs.load_log).

The format-specific behaviour is pinned beside its reader: test_logs_hdf5.py,
test_logs_csv.py, test_logs_mat.py, test_logs_npy.py, test_logs_epos.py; the
ExcitationLog type in test_logs_model.py.
"""

from __future__ import annotations

import hashlib
import math
import pathlib
import tempfile

import h5py
import numpy as np
import pytest
import scipy.io
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from hypothesis.extra import numpy as hnp
from log_writers import FS, N, WRITERS, reference_arrays, write_csv, write_h5, write_mat73

from commission.errors import CommissionError, DataError, InputFileError, UsageError
from commission.logs import load_log, parse_mapping


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


def test_integer_encoder_counts_are_accepted(tmp_path):
    path = tmp_path / "counts.h5"
    write_h5(path, {"t": np.arange(5) / FS, "q": np.arange(5, dtype=np.int32), "u": np.ones(5)},
             attrs={"q_unit": "um"})
    log = load_log(path)
    assert log.q.dtype == np.float64
    np.testing.assert_allclose(log.q, np.arange(5) * 1e-6, rtol=1e-15)


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
