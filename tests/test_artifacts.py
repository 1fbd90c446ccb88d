import copy
import json

import pytest

from commission.artifacts import Estimate, Identification, ThetaBox
from commission.errors import SchemaError
from commission.jsonio import read_json, write_json_atomic

# The example document of CONTRACT §2, verbatim.
CONTRACT_EXAMPLE = {
    "kind": "identification",
    "schema_version": 1,
    "units": {"u": "V", "q": "m"},
    "parameters": {
        "M": {"value": 0.027, "std": 0.0001},
        "B": {"value": 0.27, "std": 0.002},
        "fc": {"value": 0.10, "std": 0.001},
        "fs": {"value": 0.12, "std": 0.002},
        "vs": {"value": 0.01, "std": 0.001},
        "xi": {"value": 2.0, "std": 0.1},
        "offset": {"value": 0.0, "std": 0.001},
    },
    "fit": {"relative_error": 0.04, "condition_number": 26.0, "validation_relative_error": 0.06},
    "theta": {"nominal": [37.0, 10.1, 0.0], "min": [8.3, 2.4, -50.0], "max": [50.0, 17.5, 50.0]},
    "delta_d": 0.5,
    "friction_compensation": {"level": 0.1, "slope": 900.0},
}


def test_contract_example_loads_and_roundtrips(tmp_path):
    ident = Identification.from_dict(CONTRACT_EXAMPLE)
    assert ident.value("M") == 0.027
    assert ident.theta.min == (8.3, 2.4, -50.0)
    p = tmp_path / "ident.json"
    write_json_atomic(p, ident.to_dict())
    again = Identification.load(str(p))
    assert again == ident
    assert read_json(p) == CONTRACT_EXAMPLE


def test_coulomb_model_without_stribeck_fields():
    doc = copy.deepcopy(CONTRACT_EXAMPLE)
    for k in ("fs", "vs", "xi"):
        del doc["parameters"][k]
    doc["parameters"]["xi"] = None
    ident = Identification.from_dict(doc)
    assert ident.parameters["fs"] is None and ident.parameters["xi"] is None
    with pytest.raises(KeyError, match="fs"):
        ident.value("fs")


@pytest.mark.parametrize(
    "mutate, msg",
    [
        (lambda d: d["parameters"]["M"].__setitem__("value", "heavy"), r"\$\.parameters\.M\.value: expected a finite number"),
        (lambda d: d["parameters"]["M"].__setitem__("value", -1.0), r"\$\.parameters\.M\.value: expected a positive mass"),
        (lambda d: d["parameters"].pop("B"), r"\$\.parameters\.B: missing required field"),
        (lambda d: d["theta"].__setitem__("min", [8.3, 2.4]), r"\$\.theta\.min: expected 3 numbers"),
        (lambda d: d["theta"].__setitem__("nominal", [60.0, 10.1, 0.0]), r"\$\.theta: theta\[0\]: nominal 60 outside"),
        (lambda d: d.__setitem__("kind", "tuning"), r"\$\.kind: expected kind 'identification'"),
        (lambda d: d["fit"].__setitem__("relative_error", -0.1), r"\$\.fit\.relative_error: expected a non-negative"),
        (lambda d: d.pop("delta_d"), r"\$\.delta_d: missing required field"),
    ],
)
def test_strict_loading_names_the_json_path(mutate, msg):
    doc = copy.deepcopy(CONTRACT_EXAMPLE)
    mutate(doc)
    with pytest.raises(SchemaError, match=msg):
        Identification.from_dict(json.loads(json.dumps(doc)), source="ident.json")


def test_theta_box_rejects_nonpositive_inverse_mass():
    with pytest.raises(ValueError, match="1/M bound must be positive"):
        ThetaBox((1.0, 1.0, 0.0), (0.0, 0.0, -1.0), (2.0, 2.0, 1.0))


def test_estimate_dict():
    assert Estimate(1.5, 0.1).to_dict() == {"value": 1.5, "std": 0.1}
