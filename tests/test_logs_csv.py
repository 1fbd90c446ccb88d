"""The CSV reader: dialects, comments, and errors naming the line and the column (commission.logs.csvfile)."""

from __future__ import annotations

import numpy as np
import pytest

from commission.errors import DataError, InputFileError
from commission.logs import load_log


def test_csv_dialects_comments_quotes_semicolons(tmp_path):
    path = tmp_path / "log.csv"
    path.write_text('# exported by rig 3\nt; q ;u;mode\n0;1e-3;"0.5";run\n# pause\n0.001;2e-3;0.25;run\n\n')
    log = load_log(path)
    np.testing.assert_array_equal(log.t, [0.0, 0.001])
    np.testing.assert_array_equal(log.q, [1e-3, 2e-3])
    np.testing.assert_array_equal(log.u, [0.5, 0.25])


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
