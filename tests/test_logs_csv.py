"""The CSV reader: dialects, comments, and errors naming the line and the column (commission.logs.csvfile)."""

from __future__ import annotations

import numpy as np
import pytest

from commission.errors import DataError, InputFileError
from commission.logs import load_log
from refusals import assert_refused


def test_csv_dialects_comments_quotes_semicolons(tmp_path):
    path = tmp_path / "log.csv"
    path.write_text('# exported by rig 3\nt; q ;u;mode\n0;1e-3;"0.5";run\n# pause\n0.001;2e-3;0.25;run\n\n')
    log = load_log(path)
    np.testing.assert_array_equal(log.t, [0.0, 0.001])
    np.testing.assert_array_equal(log.q, [1e-3, 2e-3])
    np.testing.assert_array_equal(log.u, [0.5, 0.25])


@pytest.mark.parametrize("content, error, match", [
    ("hello world\nthis is not, a log\n", DataError, r"bad\.csv: channel 't' not found \(available: hello world\)"),
    ("# only a comment\n\n", InputFileError, r"bad\.csv: not a readable CSV file \(no header row\)"),
    ("t,q,u\n", DataError, r"bad\.csv: no data rows after the header"),
    (b"t,q,u\n0,0\x00,0\n", InputFileError, r"bad\.csv: not a readable CSV file \(contains NUL bytes\)"),
    ("t,q,u\n0,1,2\n0.001,1,x\n", DataError, r"bad\.csv: line 3, column 'u': cannot parse 'x' as a number"),
    ("t,q,u\n0,1,2\n0.001,,2\n", DataError, r"bad\.csv: line 3, column 'q': empty cell"),
    ("t,q,u\n0,1,2\n0.001,1\n", DataError, r"bad\.csv: line 3: 2 fields, but column 'u' is field 3"),
    ("t,q,u,q\n0,1,2,3\n", DataError, r"bad\.csv: channel 'q': column 'q' appears 2 times"),
])
def test_bad_csv_is_refused_naming_the_file_line_and_column(tmp_path, content, error, match):
    assert_refused(tmp_path / "bad.csv", content, load_log, error, match)
