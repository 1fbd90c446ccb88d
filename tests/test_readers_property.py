"""Issue 24, must-show 5: every reader gives a valid result or the project's own error, never another exception.

Property-based (hypothesis), at least 200 examples per reader, for the readers of every
file a user hands the tool: logs (CSV; HDF5 with random structure, read in the forked child),
JSON artifacts (raw bytes; ident.json and tuning.json mutated from valid documents), the TOML
spec and gate (raw bytes; parsed tables with random keys and values), and controller.json
(mutated, with the checksum recomputed half of the time so that the schema checks are reached).
A :class:`commission.errors.CommissionError` is what the CLI turns into exit 2 with one line.

``tests/data/tuning_paper_budget8.json`` is the tuning.json of ``tune`` on the paper's axis with
``tune.budget = 8`` (a valid document to mutate; made once, since tuning takes tens of seconds).
"""

from __future__ import annotations

import copy
import hashlib
import json
import math
import pathlib
import tempfile

import h5py
import numpy as np
from hypothesis import HealthCheck, event, given, settings
from hypothesis import strategies as st

from commission.artifacts import Identification
from commission.controller_config import ControllerConfig, ControllerProvenance
from commission.errors import CommissionError
from commission.infra.files import read_toml
from commission.gate import gate_from_mapping, resolve_gate
from commission.jsonio import canonical_json, read_json
from commission.logs import load_log
from commission.paper import reference_identification
from commission.formats.spec_toml import SPEC_FIELDS
from commission.spec import spec_from_mapping
from commission.tune.api import resolve_spec
from commission.tuning import Tuning
from commission.validate import deployable_gains

EXAMPLES = 200
PROPS = settings(max_examples=EXAMPLES, deadline=None, suppress_health_check=list(HealthCheck),
                 database=None)
TUNING_DOC = json.loads((pathlib.Path(__file__).parent / "data" / "tuning_paper_budget8.json").read_text())
IDENT_DOC = reference_identification(delta_d=0.5).to_dict()


def _controller_doc() -> dict:
    t = Tuning.from_dict(copy.deepcopy(TUNING_DOC))
    cfg = ControllerConfig(gains=deployable_gains(t.arc), sample_rate=t.spec.sample_rate, units={"u": "V", "q": "m"},
                           validated={"seed": 0}, provenance=ControllerProvenance(None, "1" * 64, "2" * 64, "t", "now"))
    return cfg.to_dict()


CONTROLLER_DOC = _controller_doc()


def only_our_errors(fn, *args, **kw):
    """``fn(*args)``; a CommissionError (one line, exit 2 in the CLI) is an accepted outcome."""
    try:
        out = fn(*args, **kw)
    except CommissionError as exc:
        assert "\n" not in str(exc).strip(), str(exc)
        event(f"{getattr(fn, '__name__', 'reader')}: refused")  # --hypothesis-show-statistics
        return None
    event(f"{getattr(fn, '__name__', 'reader')}: valid")
    return out


# --------------------------------------------------------------------------- strategies

numbers = st.one_of(st.integers(-2**70, 2**70), st.floats(allow_nan=True, allow_infinity=True),
                    st.sampled_from([0, -0.0, 1e-300, 1e300, -1, 2**63 - 1, 1e9]))
leaves = st.one_of(st.none(), st.booleans(), numbers, st.text(max_size=12))
json_values = st.recursive(leaves, lambda c: st.lists(c, max_size=4) | st.dictionaries(st.text(max_size=8), c, max_size=4),
                           max_leaves=12)


def _children(node):
    if isinstance(node, dict):
        return list(node.keys())
    if isinstance(node, list):
        return list(range(len(node)))
    return []


def mutate(data, doc, max_edits: int = 3):
    """Up to ``max_edits`` random edits of a JSON document: replace, delete or add a field anywhere."""
    doc = copy.deepcopy(doc)
    for _ in range(data.draw(st.sampled_from([1, 1, 1, max_edits]))):
        parent, key = None, None
        node = doc
        while _children(node) and (parent is None or data.draw(st.integers(0, 3)) > 0):
            parent, key = node, data.draw(st.sampled_from(_children(node)))
            node = parent[key]
        if parent is None:
            doc = data.draw(json_values) if data.draw(st.integers(0, 20)) == 0 else doc
            continue
        action = data.draw(st.sampled_from(["replace", "scale", "scale", "scale", "delete", "add"]))
        if action == "replace":
            parent[key] = data.draw(json_values)
        elif action == "scale" and isinstance(node, (int, float)) and not isinstance(node, bool):
            parent[key] = node * data.draw(st.sampled_from([1.0, 1.0001, 0.5, 2.0, -1, 0, 1e-12, 1e12, math.inf, math.nan]))
        elif action == "delete" and isinstance(parent, dict):
            del parent[key]
        elif action == "add" and isinstance(parent, dict):
            parent[data.draw(st.text(max_size=8))] = data.draw(json_values)
        else:
            parent[key] = data.draw(json_values)
    return doc


def read_bytes(data: bytes, name: str, reader):
    """``reader(path)`` of ``data`` written to a temporary file ``name``: its result, or None if refused."""
    with tempfile.TemporaryDirectory() as d:
        p = pathlib.Path(d) / name
        p.write_bytes(data)
        return only_our_errors(reader, p)


def read_mutated(data, doc, name: str, reader, edit=None):
    """:func:`read_bytes` of ``doc`` mutated (then ``edit``-ed), as JSON."""
    doc = mutate(data, doc)
    if edit is not None:
        doc = edit(doc)
    # allow_nan: a file may hold NaN/Infinity literals, which Python's json reads back.
    return read_bytes(json.dumps(doc, allow_nan=True).encode(), name, reader)


# --------------------------------------------------------------------------- JSON artifacts


@PROPS
@given(data=st.binary(max_size=400) | st.text(max_size=400).map(str.encode))
def test_read_json_on_any_bytes(data):
    read_bytes(data, "x.json", read_json)


@PROPS
@given(data=st.data())
def test_ident_json_reader(data):
    ident = read_mutated(data, IDENT_DOC, "ident.json", lambda p: Identification.from_dict(read_json(p), source=str(p)))
    if ident is not None:  # what tune does with it before any simulation
        only_our_errors(resolve_spec, {}, "spec (defaults)", ident)


@PROPS
@given(data=st.data())
def test_tuning_json_reader(data):
    t = read_mutated(data, TUNING_DOC, "tuning.json", lambda p: Tuning.from_dict(read_json(p), source=str(p)))
    if t is not None:
        assert t.spec.sample_rate > 0 and all(math.isfinite(x) for x in t.arc.theta_min)


# --------------------------------------------------------------------------- controller.json


def _rehash(doc):
    if not isinstance(doc, dict):
        return doc
    body = {k: v for k, v in doc.items() if k != "checksum"}
    try:
        text = json.dumps(body, sort_keys=True, indent=2, allow_nan=False) + "\n"
    except (ValueError, TypeError):
        return doc
    doc["checksum"] = {"algorithm": "sha256", "value": hashlib.sha256(text.encode()).hexdigest()}
    return doc


@PROPS
@given(data=st.data(), rehash=st.booleans())
def test_controller_json_reader(data, rehash):
    from commission.runtime import load_controller

    ctrl = read_mutated(data, CONTROLLER_DOC, "controller.json", load_controller, edit=_rehash if rehash else None)
    if ctrl is not None:  # the floors of a loaded controller: finite limits
        g = ctrl.config.gains
        assert all(math.isfinite(v) and v > 0 for v in (g.u_max, g.k1s_max, g.k2s_max))


# --------------------------------------------------------------------------- TOML spec and gate

toml_scalars = st.one_of(st.booleans(), st.integers(-2**63, 2**63 - 1), st.floats(allow_nan=True, allow_infinity=True),
                         st.text(max_size=12), st.sampled_from(["20 um", "30 lsb", "0.01 %travel", "-1 m", "1e999 nm"]))
toml_values = st.recursive(toml_scalars, lambda c: st.lists(c, max_size=3) | st.dictionaries(st.text(max_size=6), c, max_size=3),
                           max_leaves=6)
SPEC_KEYS = {(k.section, k.name): k for k in SPEC_FIELDS}
GATE_KEYS = ["e_F", "e_M", "e_rms", "c_u", "u_max", "no_divergence", "arc_vs_pid_e_rms", "arc_vs_pid_slack"]


@st.composite
def spec_tables(draw):
    out: dict = {}
    for _ in range(draw(st.integers(0, 6))):
        if draw(st.integers(0, 9)) == 0:
            out[draw(st.text(max_size=6))] = draw(toml_values)
            continue
        section, key = draw(st.sampled_from(sorted(SPEC_KEYS)))
        typ, default = SPEC_KEYS[(section, key)].type, SPEC_KEYS[(section, key)].default
        near = (default if default is not None else 1.0) * draw(st.sampled_from([0.5, 0.9, 1.0, 1.5, 2.0]))
        plausible = int(max(1, round(near))) if typ is int else float(near)
        table = out.setdefault(section, {})
        if isinstance(table, dict):  # mostly near the default, so that the combined checks are reached
            value = plausible if draw(st.integers(0, 2)) else draw(toml_values)
            table[key if draw(st.integers(0, 9)) else draw(st.text(max_size=6))] = value
    return out


@st.composite
def gate_tables(draw):
    table = {}
    for _ in range(draw(st.integers(0, 6))):
        key = draw(st.sampled_from(GATE_KEYS)) if draw(st.integers(0, 9)) else draw(st.text(max_size=6))
        table[key] = draw(toml_values)
    out = {"gate": table}
    if draw(st.integers(0, 9)) == 0:
        out[draw(st.text(max_size=6))] = draw(toml_values)
    return out


@PROPS
@given(tables=spec_tables())
def test_spec_reader(tables):
    spec = only_our_errors(spec_from_mapping, tables, "spec.toml")
    if spec is not None:
        assert 0 < spec.sample_rate <= 100e3 and 1 <= spec.moves <= 100


@PROPS
@given(tables=gate_tables(), lsb=st.sampled_from([0.0, 1e-6]))
def test_gate_reader(tables, lsb):
    gate = only_our_errors(gate_from_mapping, tables, "gate.toml")
    if gate is not None:
        only_our_errors(resolve_gate, gate, lsb=lsb, travel=0.4, u_max=10.0)


@PROPS
@given(data=st.binary(max_size=300) | st.text(max_size=300).map(str.encode))
def test_toml_file_reader_on_any_bytes(data):
    parsed = read_bytes(data, "spec.toml", read_toml)
    if parsed is not None:
        only_our_errors(spec_from_mapping, parsed, "spec.toml")
        only_our_errors(gate_from_mapping, parsed, "spec.toml")


# --------------------------------------------------------------------------- logs

cells = st.one_of(st.floats(allow_nan=True, allow_infinity=True).map(repr), st.integers(-10**30, 10**30).map(str),
                  st.sampled_from(["", " ", "nan", "inf", "-inf", "1e999", "0x10", '"1.0"', "1,5", "#", "NaN"]),
                  st.text(max_size=5))
column_names = st.sampled_from(["t", "q", "u", "q_ref", "x", "", "t ", "Q", "u"])


@st.composite
def plausible_channels(draw):
    """t increasing, q and u finite, of one length: a log the readers should accept, before any corruption."""
    n = draw(st.integers(2, 30))
    dt = draw(st.sampled_from([1e-3, 4e-4, 2e-4]))
    t = np.arange(n) * dt + draw(st.floats(0, 10))
    small = st.floats(-1e3, 1e3, allow_nan=False, allow_infinity=False)
    q = np.array(draw(st.lists(small, min_size=n, max_size=n)))
    u = np.array(draw(st.lists(small, min_size=n, max_size=n)))
    return {"t": t, "q": q, "u": u}


@st.composite
def csv_texts(draw):
    if draw(st.booleans()):  # a plausible log, perhaps with one cell or the header damaged
        ch = draw(plausible_channels())
        names = list(ch)
        rows = [",".join(repr(float(ch[k][i])) for k in names) for i in range(len(ch["t"]))]
        lines = [",".join(names)] + rows
        if draw(st.booleans()):
            i = draw(st.integers(0, len(lines) - 1))
            lines[i] = draw(st.sampled_from([lines[i].replace(",", ";", 1), lines[i] + ",", "", "t,q", lines[i][:-1],
                                             lines[i].replace("0", "nan", 1)]))
        return "\n".join(lines).encode()
    delim = draw(st.sampled_from([",", ";", "\t", " "]))
    ncol = draw(st.integers(1, 5))
    header = delim.join(draw(st.lists(column_names, min_size=ncol, max_size=ncol)))
    rows = [delim.join(draw(st.lists(cells, min_size=0, max_size=ncol + 1)))
            for _ in range(draw(st.integers(0, 12)))]
    lines = ([draw(st.sampled_from(["# a comment", ""]))] if draw(st.booleans()) else []) + [header] + rows
    text = draw(st.sampled_from(["\n", "\r\n", "\r"])).join(lines)
    data = text.encode()
    if draw(st.integers(0, 9)) == 0:
        data += draw(st.binary(max_size=20))
    return data


@PROPS
@given(data=csv_texts(), sample_rate=st.none() | st.sampled_from([1000.0, 2500.0]),
       q_unit=st.none() | st.sampled_from(["m", "mm", "um"]))
def test_csv_log_reader(data, sample_rate, q_unit):
    with tempfile.TemporaryDirectory() as d:
        p = pathlib.Path(d) / "log.csv"
        p.write_bytes(data)
        log = only_our_errors(load_log, p, sample_rate=sample_rate, q_unit=q_unit)
    if log is not None:
        assert log.t.shape == log.q.shape == log.u.shape and np.all(np.isfinite(log.q))


dataset_values = st.one_of(
    st.lists(st.floats(allow_nan=True, allow_infinity=True), min_size=0, max_size=12).map(lambda v: np.array(v, np.float64)),
    st.lists(st.integers(-2**31, 2**31 - 1), min_size=0, max_size=12).map(lambda v: np.array(v, np.int32)),
    st.lists(st.booleans(), min_size=1, max_size=12).map(np.array),
    st.integers(1, 4).map(lambda n: np.zeros((n, 2))),
    st.just(np.float64(1.5)),
    st.text(st.characters(blacklist_characters="\x00", blacklist_categories=("Cs",)), max_size=6),  # HDF5 strings hold neither NUL nor a lone surrogate
)


@st.composite
def hdf5_layouts(draw):
    if draw(st.booleans()):  # a plausible log, perhaps with one channel replaced
        sets = draw(plausible_channels())
        if draw(st.booleans()):
            sets[draw(st.sampled_from(list(sets)))] = draw(dataset_values)
        attrs = {"q_unit": draw(st.sampled_from(["m", "mm", "um", "parsec"]))} if draw(st.booleans()) else {}
        return sets, attrs
    names = draw(st.lists(st.sampled_from(["t", "q", "u", "q_ref", "x", "grp/q"]), max_size=5, unique=True))
    sets = {n: draw(dataset_values) for n in names}
    attrs = {k: draw(st.one_of(st.sampled_from(["m", "mm", "um", "V", "N", "A", "furlong", ""]), st.integers(-3, 3)))
             for k in draw(st.lists(st.sampled_from(["q_unit", "u_unit"]), max_size=2, unique=True))}
    return sets, attrs


@PROPS
@given(layout=hdf5_layouts(), sample_rate=st.none() | st.just(2500.0))
def test_hdf5_log_reader(layout, sample_rate):
    sets, attrs = layout
    with tempfile.TemporaryDirectory() as d:
        p = pathlib.Path(d) / "log.h5"
        with h5py.File(p, "w") as f:
            for name, value in sets.items():
                f.create_dataset(name, data=value)
            for k, v in attrs.items():
                f.attrs[k] = v
        log = only_our_errors(load_log, p, sample_rate=sample_rate)
    if log is not None:
        assert log.t.shape == log.q.shape == log.u.shape and np.all(np.isfinite(log.u))
