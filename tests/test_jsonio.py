import json

import pytest

from commission.errors import UsageError
from commission.jsonio import read_json, write_json_atomic


def test_atomic_write_sorted_and_roundtrip(tmp_path):
    p = tmp_path / "a.json"
    write_json_atomic(p, {"b": 1, "a": [1.5, 2]})
    text = p.read_text()
    assert text.index('"a"') < text.index('"b"')
    assert read_json(p) == {"a": [1.5, 2], "b": 1}
    assert [x.name for x in tmp_path.iterdir()] == ["a.json"]


def test_refuses_overwrite_without_force(tmp_path):
    p = tmp_path / "a.json"
    write_json_atomic(p, {"x": 1})
    with pytest.raises(UsageError, match="--force"):
        write_json_atomic(p, {"x": 2}, overwrite=False)
    assert json.loads(p.read_text()) == {"x": 1}


def test_nan_is_refused_and_nothing_written(tmp_path):
    p = tmp_path / "n.json"
    with pytest.raises(ValueError):
        write_json_atomic(p, {"x": float("nan")})
    assert list(tmp_path.iterdir()) == []


