"""NumPy logs (commission.logs.npy): .npy record and plain 2-D arrays, .npz named arrays, refusals.

The files are written with numpy's own savers, the layout a user's script produces; the real
case is the ODrive slow runs (../shared/data/odrive-cogging, README: shape (3, N), rows t [s],
encoder position [counts], Iq [A]), compared with numpy's plain ``np.load`` of the same file.
"""

from __future__ import annotations

import io
import zipfile

import numpy as np
import pytest
from shared_paths import ODRIVE_DIR
from typer.testing import CliRunner

from commission.cli.main import app
from commission.errors import CommissionError, DataError, InputFileError
from commission.identification import expand_log_paths
from commission.logs import load_log

ODRIVE_RUN = ODRIVE_DIR / "slow_0.03revps" / "nocomp_0.npy"
needs_odrive = pytest.mark.skipif(not ODRIVE_RUN.is_file(), reason="ODrive data not present")
ROWS = {"t": "0", "q": "1", "u": "2"}


def _arrays(n: int = 400):
    t = np.arange(n) / 1000.0
    q = 0.01 * np.sin(2 * np.pi * 3 * t)
    u = 0.5 + np.cos(2 * np.pi * 3 * t)
    return t, q, u


def test_a_plain_2d_array_is_read_by_row_or_by_column_index(tmp_path):
    t, q, u = _arrays()
    np.save(tmp_path / "rows.npy", np.vstack([u, t, q]))       # (3, N): one channel per row
    np.save(tmp_path / "cols.npy", np.column_stack([q, u, t]))  # (N, 3): one per column
    by_row = load_log(tmp_path / "rows.npy", mapping={"t": "1", "q": "2", "u": "0"})
    by_col = load_log(tmp_path / "cols.npy", mapping={"t": "2", "q": "0", "u": "1"})
    for log in (by_row, by_col):
        np.testing.assert_array_equal(log.t, t)
        np.testing.assert_array_equal(log.q, q)
        np.testing.assert_array_equal(log.u, u)
        assert log.q_ref is None


def test_q_unit_and_sample_rate_apply_to_npy_as_to_csv(tmp_path):
    t, q, u = _arrays()
    np.save(tmp_path / "a.npy", np.vstack([q * 1e3, u]))
    log = load_log(tmp_path / "a.npy", mapping={"q": "0", "u": "1"}, sample_rate=1000.0, q_unit="mm")
    np.testing.assert_allclose(log.q, q, rtol=1e-15)
    np.testing.assert_allclose(log.t, t)


def test_a_2d_array_without_indices_is_refused_naming_each_missing_channel(tmp_path):
    t, q, u = _arrays()
    np.save(tmp_path / "a.npy", np.vstack([t, q, u]))
    with pytest.raises(DataError, match=r"shape \(3, 400\).*no channel names.*--map t=ROW --map q=ROW --map u=ROW"):
        load_log(tmp_path / "a.npy")
    with pytest.raises(DataError, match=r"--map u=ROW \(0-based") as exc:
        load_log(tmp_path / "a.npy", mapping={"t": "0", "q": "1"})
    assert "q=ROW" not in str(exc.value)
    with pytest.raises(DataError, match=r"--map t=ROW.*or --sample-rate HZ"):
        load_log(tmp_path / "a.npy", mapping={"q": "1", "u": "2"})


@pytest.mark.parametrize("src", ["q", "3", "-1", "1.0"])
def test_a_2d_array_index_must_be_a_row_number_in_range(tmp_path, src):
    t, q, u = _arrays()
    np.save(tmp_path / "a.npy", np.vstack([t, q, u]))
    with pytest.raises(DataError, match=rf"channel 'q' mapped to '{src}'.*row index 0..2"):
        load_log(tmp_path / "a.npy", mapping={"t": "0", "q": src, "u": "2"})


def test_square_1d_and_3d_arrays_are_refused_with_their_shape(tmp_path):
    np.save(tmp_path / "sq.npy", np.zeros((3, 3)))
    np.save(tmp_path / "one.npy", np.zeros(50))
    np.save(tmp_path / "three.npy", np.zeros((3, 50, 2)))
    with pytest.raises(DataError, match=r"shape \(3, 3\): square"):
        load_log(tmp_path / "sq.npy", mapping=ROWS)
    for name, shape in (("one", r"\(50,\)"), ("three", r"\(3, 50, 2\)")):
        with pytest.raises(DataError, match=rf"shape {shape}; a .npy log is a 2-D array"):
            load_log(tmp_path / f"{name}.npy", mapping=ROWS)


def test_a_record_array_names_its_channels(tmp_path):
    t, q, u = _arrays()
    rec = np.zeros(t.size, dtype=[("time", "f8"), ("pos", "f4"), ("u", "i4")])
    rec["time"], rec["pos"], rec["u"] = t, q, np.round(u * 100)
    np.save(tmp_path / "r.npy", rec)
    log = load_log(tmp_path / "r.npy", mapping={"t": "time", "q": "pos"})
    np.testing.assert_array_equal(log.q, q.astype(np.float32).astype(np.float64))
    np.testing.assert_array_equal(log.u, np.round(u * 100))
    with pytest.raises(DataError, match=r"channel 'q' not found \(available: time, pos, u\)"):
        load_log(tmp_path / "r.npy", mapping={"t": "time"})


def test_npz_named_arrays_and_the_map(tmp_path):
    t, q, u = _arrays()
    np.savez_compressed(tmp_path / "a.npz", time=t, qm=q[:, None], u=u, q_ref=q + 1e-3)
    log = load_log(tmp_path / "a.npz", mapping={"t": "time", "q": "qm"})
    np.testing.assert_array_equal(log.q, q)  # an N x 1 array is flattened, as for MATLAB
    np.testing.assert_array_equal(log.q_ref, q + 1e-3)
    with pytest.raises(DataError, match=r"channel 'q' mapped to 'pos', which is not in the file "
                                        r"\(available: q_ref, qm, time, u\)"):
        load_log(tmp_path / "a.npz", mapping={"t": "time", "q": "pos"})


def test_object_and_text_arrays_are_refused_by_name_without_unpickling(tmp_path):
    t, q, u = _arrays(5)
    objects = np.array([1.0, "x", None, 2.0, 3.0], dtype=object)
    np.save(tmp_path / "o.npy", objects, allow_pickle=True)
    with pytest.raises(DataError, match=r"the array holds Python objects .*allow_pickle=False"):
        load_log(tmp_path / "o.npy", mapping=ROWS)
    np.savez(tmp_path / "o.npz", t=t, q=q, u=objects)
    with pytest.raises(DataError, match=r"channel 'u' holds Python objects"):
        load_log(tmp_path / "o.npz")
    np.savez(tmp_path / "s.npz", t=t, q=q, volts=np.array(["1"] * 5))
    with pytest.raises(DataError, match=r"channel 'u' \('volts'\) holds text"):
        load_log(tmp_path / "s.npz", mapping={"u": "volts"})
    np.save(tmp_path / "c.npy", np.vstack([t, q, u]).astype(complex))
    with pytest.raises(DataError, match=r"the array is complex"):
        load_log(tmp_path / "c.npy", mapping=ROWS)


def test_a_header_that_claims_more_data_than_the_file_holds_is_refused_before_allocating(tmp_path):
    buf = io.BytesIO()
    np.lib.format.write_array_header_1_0(buf, {"descr": "<f8", "fortran_order": False, "shape": (3, 9 * 10**10)})
    (tmp_path / "big.npy").write_bytes(buf.getvalue() + np.zeros(30).tobytes())
    with pytest.raises(InputFileError, match=r"shape \(3, 90000000000\) of float64 needs \d+ bytes"):
        load_log(tmp_path / "big.npy", mapping=ROWS)


def test_a_npz_member_that_unpacks_past_the_log_limit_is_refused_before_decompressing(tmp_path, monkeypatch):
    import commission.logs.npy as npy_mod

    t, q, u = _arrays()
    np.savez_compressed(tmp_path / "a.npz", t=t, q=q, u=u)
    monkeypatch.setattr(npy_mod, "MAX_LOG_BYTES", 1000)
    with pytest.raises(InputFileError, match=r"unpack to \d+ bytes, over the 1000-byte limit"):
        load_log(tmp_path / "a.npz")


def test_damaged_files_are_one_line_refusals(tmp_path):
    t, q, u = _arrays()
    buf = io.BytesIO()
    np.save(buf, np.vstack([t, q, u]))
    (tmp_path / "cut.npy").write_bytes(buf.getvalue()[:300])
    (tmp_path / "text.npy").write_text("t,q,u\n0,0,0\n")
    (tmp_path / "bad.npz").write_bytes(b"PK\x03\x04" + b"\0" * 100)
    with zipfile.ZipFile(tmp_path / "member.npz", "w") as zf:
        zf.writestr("q.npy", b"not an array")
    for name in ("cut.npy", "text.npy", "bad.npz", "member.npz"):
        with pytest.raises(CommissionError) as exc:
            load_log(tmp_path / name, mapping=ROWS if name.endswith("npy") else {}, sample_rate=1000.0)
        assert str(exc.value).startswith(str(tmp_path / name)) and "\n" not in str(exc.value), exc.value


def test_a_folder_of_npy_runs_is_listed_like_other_logs(tmp_path):
    t, q, u = _arrays()
    for name in ("b.npy", "a.npz", "notes.txt"):
        (tmp_path / name).write_bytes(b"")
    assert [p.rsplit("/", 1)[1] for p in expand_log_paths([str(tmp_path)])] == ["a.npz", "b.npy"]


@needs_odrive
def test_the_odrive_run_reads_as_its_readme_describes():
    rows = np.load(ODRIVE_RUN)  # numpy's own reader, default allow_pickle=False
    log = load_log(ODRIVE_RUN, mapping=ROWS, q_unit="rad")
    np.testing.assert_array_equal(log.t, rows[0])
    np.testing.assert_array_equal(log.q, rows[1])
    np.testing.assert_array_equal(log.u, rows[2])
    # README: about 14000 samples at 0.03 rev/s over 33.3 s, one revolution of 8192 counts
    assert 13000 < log.n < 16000 and 30 < log.t[-1] < 40
    assert 7000 < log.q[-1] - log.q[0] < 9500


@needs_odrive
def test_the_odrive_run_without_a_map_says_which_rows_to_name():
    res = CliRunner().invoke(app, ["identify", str(ODRIVE_RUN), "--out", "/nonexistent/i.json"])
    assert res.exit_code == 2
    text = " ".join(res.output.split())
    assert "shape (3, 14732)" in text and "--map t=ROW --map q=ROW --map u=ROW" in text


# --------------------------------------------------------------------------- any bytes: our error or a log

from hypothesis import HealthCheck, given, settings  # noqa: E402
from hypothesis import strategies as st  # noqa: E402


def _valid_bytes(kind: str) -> bytes:
    t, q, u = _arrays(20)
    buf = io.BytesIO()
    if kind == "npy":
        np.save(buf, np.vstack([t, q, u]))
    else:
        np.savez(buf, t=t, q=q, u=u) if kind == "npz" else np.savez_compressed(buf, t=t, q=q, u=u)
    return buf.getvalue()


@st.composite
def mutated(draw):
    kind = draw(st.sampled_from(["npy", "npz", "npzc"]))
    data = bytearray(_valid_bytes(kind))
    for _ in range(draw(st.integers(1, 6))):
        op = draw(st.sampled_from(["flip", "cut", "insert"]))
        at = draw(st.integers(0, max(len(data) - 1, 0)))
        if op == "flip" and data:
            data[at] = draw(st.integers(0, 255))
        elif op == "cut":
            del data[at:at + draw(st.integers(1, 64))]
        else:
            data[at:at] = draw(st.binary(min_size=1, max_size=16))
    return kind, bytes(data)


@settings(max_examples=200, deadline=None, suppress_health_check=list(HealthCheck), database=None)
@given(case=mutated())
def test_a_damaged_numpy_file_gives_a_log_or_a_one_line_refusal(case, tmp_path_factory):
    kind, data = case
    path = tmp_path_factory.mktemp("npy") / ("log.npy" if kind == "npy" else "log.npz")
    path.write_bytes(data)
    try:
        log = load_log(path, mapping=ROWS if kind == "npy" else {})
    except CommissionError as exc:
        assert "\n" not in str(exc).strip() and str(exc).startswith(str(path)), exc
    else:
        assert log.t.shape == log.q.shape == log.u.shape


arrays = st.one_of(
    st.tuples(st.sampled_from(["<f8", "<f4", "<i4", "|u1", "|b1", "<c16", "<U3", ">f8"]),
              st.lists(st.integers(0, 6), min_size=0, max_size=3)).map(
        lambda a: np.zeros(tuple(a[1]), dtype=a[0])),
    st.integers(1, 5).map(lambda n: np.zeros(n, dtype=[("t", "f8"), ("q", "f8"), ("u", "O")])),
)


@settings(max_examples=200, deadline=None, suppress_health_check=list(HealthCheck), database=None)
@given(arr=arrays, as_npz=st.booleans(), rate=st.none() | st.just(1000.0))
def test_any_array_gives_a_log_or_a_one_line_refusal(arr, as_npz, rate, tmp_path_factory):
    path = tmp_path_factory.mktemp("arr") / ("log.npz" if as_npz else "log.npy")
    with open(path, "wb") as fh:
        if as_npz:
            np.savez(fh, t=arr, q=arr, u=arr)
        else:
            np.save(fh, arr, allow_pickle=True)
    try:
        log = load_log(path, mapping={} if as_npz else ROWS, sample_rate=rate)
    except CommissionError as exc:
        assert "\n" not in str(exc).strip() and str(exc).startswith(str(path)), exc
    else:
        assert log.t.shape == log.q.shape == log.u.shape and log.n > 0
