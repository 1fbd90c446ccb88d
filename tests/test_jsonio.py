import json

import pytest

from commission.errors import SchemaError, UsageError
from commission.jsonio import Reader, read_json, write_json_atomic


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


@pytest.mark.parametrize(
    "doc, call, msg",
    [
        ({"p": {"M": {"value": "abc"}}}, lambda r: r.obj("p").obj("M").num("value"), r"\$\.p\.M\.value: expected a finite number"),
        ({"p": {}}, lambda r: r.obj("p").num("x"), r"\$\.p\.x: missing required field"),
        ({"v": [1, "x", 3]}, lambda r: r.vec("v", 3), r"\$\.v\[1\]"),
        ({"v": [1, 2]}, lambda r: r.vec("v", 3), r"\$\.v: expected 3 numbers"),
        ({"kind": "tuning", "schema_version": 1}, lambda r: r.header("identification", 1), r"expected kind 'identification'"),
        ({"kind": "identification", "schema_version": 9}, lambda r: r.header("identification", 1), r"unsupported schema_version 9"),
    ],
)
def test_reader_names_json_path(doc, call, msg):
    with pytest.raises(SchemaError, match=msg):
        call(Reader(doc, source="x.json"))
