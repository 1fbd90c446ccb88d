"""Where only the evidence bound held the PID yardstick down, the ARC is also held to the faster PID the
identified plant admits (:func:`commission.tune.baseline.unbacked_pid`,
:func:`commission.validate.stage.beyond_evidence_checks`): a drive's auto-tuner does not stop at the band
the log backs, and an ARC held within the evidence that loses to that PID is not certified as better."""

from __future__ import annotations

import dataclasses
import math

import pytest

from commission.evidence import EvidenceBound
from commission.gate import BEYOND_EVIDENCE, GateSpec, safe_not_better
from commission.paper import reference_identification
from commission.report import not_better_lines
from commission.spec import spec_from_mapping
from commission.tune.baseline import YardstickChoice, pid_baseline, pid_candidates, pid_yardstick
from commission.tuning import gains_to_dict
from commission.tune.settings import DEFAULT_SETTINGS
from commission.validate import validate
from reference_tuning import reference_tuning
from test_gate_not_better import _um
from test_tune_baseline import _evaluator

FRACTIONS = DEFAULT_SETTINGS.yardstick_pole_fractions


def _pid(ident, spec, pole):
    return pid_baseline(ident, dataclasses.replace(spec, pid_pole=pole))[0]


def test_a_yardstick_held_by_the_evidence_records_the_fastest_pid_the_plant_admits():
    """A rigid log backed to 22 Hz: the yardstick is the fastest pole within the evidence; the record
    also carries the fastest pole that keeps every floor on the identified plant (recomputed here), whose
    loop is beyond the evidence, with its gains; the record round-trips."""
    ident = reference_identification(frequency_response={"source": "whole_log", "band_hz": [8.0, 22.0]})
    spec = spec_from_mapping({})
    bound = EvidenceBound(ident, spec)
    on_model = max(c.pole for c in pid_candidates(ident, spec, [f * spec.sample_rate for f in FRACTIONS])
                   if c.admissible)
    base, choice = pid_yardstick(ident, spec, _evaluator(1e-6), 1.0, pole_free=True)
    assert choice.unbacked is not None and base.pole < on_model
    pole, gains = choice.unbacked
    assert pole == pytest.approx(on_model)
    assert gains == _pid(ident, spec, on_model)
    assert not bound.pid_row(gains).holds and bound.pid_row(base.gains).holds
    d = choice.to_dict()
    assert d["unbacked_pid"]["pole"] == pytest.approx(on_model)
    assert YardstickChoice.from_dict(d).to_dict() == d


def test_no_record_where_the_evidence_did_not_hold_the_yardstick():
    """Without a frequency response (no band), and where the gate's c_u, not the evidence, held the
    PID below the fastest pole within the evidence, no unbacked PID is recorded."""
    spec = spec_from_mapping({})
    _, free = pid_yardstick(reference_identification(), spec, _evaluator(1e-6), 1.0, pole_free=True)
    assert free.unbacked is None and "unbacked_pid" not in free.to_dict()
    ident = reference_identification(frequency_response={"source": "whole_log", "band_hz": [8.0, 22.0]})
    _, held = pid_yardstick(ident, spec, _evaluator(1e-6), 1.0, pole_free=True)
    slow, m_min = held.pole, pid_baseline(ident, spec)[1]
    # c_u = k Kd x 1.2 on the worst scenario: this k lets only poles well below the evidence's through
    k = 1.0 / (1.2 * 3.0 * m_min * 0.5 * slow)
    base, chatty = pid_yardstick(ident, spec, _evaluator(k), 1.0, pole_free=True)
    assert base.pole < slow and chatty.unbacked is None


@pytest.fixture(scope="module")
def tuned():
    return reference_tuning(8)


def _with_unbacked(tuned, pole, gains):
    ys = dict(tuned.pid_yardstick or {})
    ys["unbacked_pid"] = {"pole": pole, "gains": gains_to_dict(gains)}
    return dataclasses.replace(tuned, pid_yardstick=ys)


def test_the_beyond_evidence_runs_reproduce_the_yardsticks_own_where_they_are_the_same_pid(tuned):
    """With the yardstick itself recorded as the unbacked PID, the extra runs are the yardstick's own
    runs (same scenarios, same encoder noise): every ``<case>/beyond_evidence`` check has the value of
    its case's ``arc_vs_pid_nominal`` check, to the last bit."""
    t = _with_unbacked(tuned, tuned.pid_pole, tuned.pid)
    r = validate(t, seed=0, n_monte_carlo=2, workers=1)
    nominal = {c.scenario: c.value for c in r.verdict.checks if c.criterion == "arc_vs_pid_nominal"}
    beyond = {k: v for k, v in nominal.items() if k.endswith("/" + BEYOND_EVIDENCE)}
    assert beyond and len(beyond) == len(nominal) - len(beyond)
    for name, value in beyond.items():
        assert value == nominal[name.rsplit("/", 1)[0]]
    plain = validate(tuned, seed=0, n_monte_carlo=2, workers=1)
    assert not any(c.scenario.endswith(BEYOND_EVIDENCE) for c in plain.verdict.checks)


def test_an_arc_that_loses_to_the_pid_beyond_the_evidence_is_safe_not_better_and_names_the_evidence(tuned):
    """A faster PID than the ARC's yardstick recorded beyond the evidence, and a comparison limit only the
    beyond-evidence check is held to fail: the verdict is "safe but not better", the ARC written flagged,
    and the words name the missing evidence and the recording that raises it."""
    ident, spec = tuned.identification, tuned.spec
    fast = 2.0 * tuned.pid_pole
    t = _with_unbacked(tuned, fast, _pid(ident, spec, fast))
    r = validate(t, seed=0, n_monte_carlo=2, workers=1)
    by = {c.scenario: c for c in r.verdict.checks if c.criterion == "arc_vs_pid_nominal"}
    ratios = {k: c.value for k, c in by.items()}
    worst_beyond = max(v for k, v in ratios.items() if k.endswith(BEYOND_EVIDENCE))
    best_plain = max(v for k, v in ratios.items() if not k.endswith(BEYOND_EVIDENCE))
    # a faster PID tracks better: the ARC's ratio against it is the larger
    assert worst_beyond > best_plain
    limit = 0.5 * (worst_beyond + best_plain)
    # limits the ARC alone meets (a user's gate.toml), the quantiles out of the way
    loose = GateSpec(e_rms=_um(100), e_F=_um(200), e_M=_um(2000), arc_vs_pid_median=1e3, arc_vs_pid_p90=1e3,
                     arc_vs_pid_nominal=limit)
    r2 = validate(t, loose, seed=0, n_monte_carlo=2, workers=1)
    failed = [c for c in r2.verdict.failures if c.criterion == "arc_vs_pid_nominal"]
    if not safe_not_better(r2.verdict):
        pytest.fail(f"not a comparison-only failure: {[c.detail for c in r2.verdict.failures]}")
    assert failed and all(c.scenario.endswith("/" + BEYOND_EVIDENCE) for c in failed)
    text = " ".join(not_better_lines(r2, t))
    assert "Missing evidence:" in text and f"{fast:.4g} rad/s" in text and "commission excite" in text
    assert math.isfinite(worst_beyond)


def test_a_malformed_unbacked_record_is_refused_by_its_json_path(tuned):
    """tuning.json is loaded strictly: an unbacked PID whose gains miss a field, or carry a string, names
    ``$.pid_yardstick``; a well-formed one loads back to the same gains."""
    import json

    from commission.errors import SchemaError
    from commission.tuning import Tuning

    t = _with_unbacked(tuned, 2.0 * tuned.pid_pole, tuned.pid)
    doc = json.loads(json.dumps(t.to_dict()))
    again = Tuning.from_dict(doc)
    assert again.pid_yardstick["unbacked_pid"]["gains"] == gains_to_dict(tuned.pid)
    for bad in ({"Kp": "fast"}, {"Kd": None, "Ts": None}):
        d = json.loads(json.dumps(doc))
        d["pid_yardstick"]["unbacked_pid"]["gains"].update(bad)
        with pytest.raises(SchemaError, match=r"\$\.pid_yardstick"):
            Tuning.from_dict(d)
    d = json.loads(json.dumps(doc))
    del d["pid_yardstick"]["unbacked_pid"]["gains"]["Ki"]
    with pytest.raises(SchemaError, match=r"\$\.pid_yardstick"):
        Tuning.from_dict(d)
