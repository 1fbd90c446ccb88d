"""The ARC over the whole Assumption-1 box (issue 30, Build 1 and Must show 3).

Every instability the box check reports is confirmed, and every loop it calls stable is
confirmed too, by the project's nonlinear closed-loop simulator (sub-stepped plant, the compiled
``arc_step`` with its estimate starting where the check froze it), which shares none of the
check's linear algebra.  The axis is the CONTRACT sec. 5 reference plant with boxes of chosen
width; the narrowing of a defaulted payload range and the refusal of a stated one are checked
on the same axis.
"""

import dataclasses
import json
import math
from pathlib import Path

import numpy as np
import pytest

from commission.artifacts import ThetaBox
from commission.controller_config import ControllerConfig, ControllerProvenance
from commission.controllers.arc import arc_pack
from commission.controllers.plant import P_DELAY, P_FC, P_FS, P_OFFSET, P_RIPPLE_AMP
from commission.controllers.simulate import KIND_ARC, simulate
from commission.controllers.trajectory import Trajectory, sample_grid
from commission.errors import SchemaError
from commission.gate import box_checks
from commission.paper import reference_identification
from commission.robustness import BoxArcCheck, MarginFloors, box_plants, payload_box
from commission.spec import spec_from_mapping
from commission.tune.box import as_identified_box, narrow_default_payload, start_gains, validity_of
from commission.tune.constraints import box_violation

SPEC = spec_from_mapping({})
TS = SPEC.period
FLOORS = MarginFloors.from_spec(SPEC)
M = 0.027  # the reference plant's mass, V s^2/m
M0 = 0.0395  # heaviest identified mass without payload, V s^2/m (about 1.2 x 1.2 M: model margin and spread)


def axis(payload_max: float, defaulted: bool):
    """The reference identification whose box's heavy end carries ``payload_max`` (V s^2/m) of payload."""
    ref = reference_identification(delta_d=0.5)
    m_lo, m_hi = 1.0 / ref.theta.max[0], M0 + payload_max
    b_lo, b_hi = 2.4 * M0, 17.5 * m_lo
    theta = ThetaBox(ref.theta.nominal, (1.0 / m_hi, b_lo / m_hi, ref.theta.min[2]), ref.theta.max)
    bounds = {"mass_range": [m_lo, m_hi], "viscous_range": [b_lo, b_hi], "payload_range": [0.0, payload_max],
              "payload_defaulted": defaulted}
    return dataclasses.replace(ref, theta=theta, extra={"bounds": bounds})


def _settles(gains, plant, theta_hat, extra_delay: bool) -> bool:
    """True: a 10 um initial error dies out within 2 s with the estimate starting at ``theta_hat``."""
    g = dataclasses.replace(gains, theta0=tuple(theta_hat), fric_level=0.0)
    q = plant.copy()
    for i in (P_FC, P_FS, P_OFFSET, P_RIPPLE_AMP):  # the linear part the check linearises
        q[i] = 0.0
    t = sample_grid(2.0, TS)
    z = np.zeros_like(t)
    r = simulate(q, KIND_ARC, arc_pack(g), Trajectory(t=t, qd=z, dqd=z, ddqd=z), quant=0.0, y0=1e-5,
                 substeps=20, delay=extra_delay)
    return (not r.diverged) and float(np.abs(r.y[-500:]).max()) < 1e-7


def _worst_loop(ident, box):
    """The plant vector, estimate and extra delay of the check's least stable loop."""
    a = box.any_estimate
    name = a.plant.replace(" +1 sample", "")
    plant = dict(box_plants(ident, SPEC))[name]
    return plant, a.theta_hat, a.plant.endswith("+1 sample")


def test_a_box_unstable_by_construction_is_found_and_the_simulator_agrees():
    # A payload of 30 M: the light plant with the estimate at the heavy end sees a loop gain ~40 x the designed.
    wide = axis(30 * M, defaulted=False)
    g = start_gains(axis(3 * M, defaulted=False), SPEC)[0]  # designed for a 3 M box
    g = dataclasses.replace(g, theta_min=wide.theta.min)  # the projection allows the whole wide box
    box = BoxArcCheck(wide, SPEC)(g)
    assert not box.any_estimate.stable and box.any_estimate.spectral_radius > 1.05
    assert not box.holds(FLOORS) and box_violation(box, FLOORS) > 10
    plant, th, delayed = _worst_loop(wide, box)
    assert _settles(g, plant, th, delayed) is False
    # the same gains on the box they were designed for: the check's least stable loop settles in simulation
    narrow = axis(3 * M, defaulted=False)
    ok = BoxArcCheck(narrow, SPEC)(start_gains(narrow, SPEC)[0])
    assert ok.any_estimate.stable
    plant, th, delayed = _worst_loop(narrow, ok)
    assert _settles(start_gains(narrow, SPEC)[0], plant, th, delayed) is True


def test_the_check_covers_every_corner_and_the_modes_variants():
    ident = axis(3 * M, defaulted=False)
    mode = ident
    names = [n for n, _ in box_plants(ident, SPEC)]
    assert sorted(names) == sorted(f"theta1_{a}/theta2_{b}" for a in ("min", "max") for b in ("min", "max"))
    spec_mode = spec_from_mapping({"plant": {"mode_hz": 500.0, "mode_damping": 0.05, "mode_ratio": 0.3}})
    names = [n for n, _ in box_plants(mode, spec_mode)]
    assert len(names) == 16 and sum(n.endswith("/mode_low") for n in names) == 4
    box = BoxArcCheck(mode, spec_mode)(start_gains(mode, spec_mode)[0])
    assert len(box.at_plant) == 32  # x the two ends of the load-force range
    # (b): 4 corners + theta_hat(0) (+ the plant's theta when it is no corner) per plant, and 2 with +1 sample
    assert box.any_estimate.loops >= 16 * (5 + 2)


def test_a_defaulted_payload_the_start_gains_cannot_hold_is_narrowed_and_recorded():
    ident = axis(30 * M, defaulted=True)
    out, notes = narrow_default_payload(ident, SPEC)
    lo, hi, m0, defaulted = payload_box(out)
    assert defaulted and lo == 0.0 and 0.0 < hi < 30 * M and math.isclose(m0, M0)
    assert math.isclose(1.0 / out.theta.min[0], M0 + hi)
    assert len(notes) == 1 and "payload range narrowed" in notes[0] and "--payload-max" in notes[0]
    # what it certifies holds, with one more sample of delay at every estimate too, for one start point
    strict = BoxArcCheck(out, SPEC, delay_any_estimate=True)
    assert any(strict(g).holds(FLOORS) for g in start_gains(out, SPEC))
    # and the default range does not (its least stable loop confirmed unstable in simulation)
    full = BoxArcCheck(ident, SPEC, delay_any_estimate=True)
    boxes = [full(g) for g in start_gains(ident, SPEC)]
    assert not any(b.holds(FLOORS) for b in boxes)
    unstable = [(g, b) for g, b in zip(start_gains(ident, SPEC), boxes) if not b.any_estimate.stable]
    assert unstable
    g, b = unstable[0]
    plant, th, delayed = _worst_loop(ident, b)
    assert _settles(g, plant, th, delayed) is False
    v = validity_of(out)
    assert v["payload_range"] == [0.0, hi] and v["default_payload_range"] == [0.0, 30 * M]
    assert v["unit"] == "V·s²/m" and math.isclose(v["mass_range"][1], M0 + hi)
    # a box the start gains hold is left alone
    same, none = narrow_default_payload(axis(0.5 * M, defaulted=True), SPEC)
    assert none == () and validity_of(same) is None


def test_validate_recognises_tunes_payload_narrowing_and_nothing_else():
    from commission.validate.provenance import _undo_payload_narrowing
    ident = axis(30 * M, defaulted=True)
    out, _ = narrow_default_payload(ident, SPEC)
    doc = json.loads(json.dumps(out.to_dict()))
    _undo_payload_narrowing(doc)
    assert doc == json.loads(json.dumps(ident.to_dict()))
    # a box narrowed further by hand is not taken for tune's: the record stays and the comparison fails
    doc = json.loads(json.dumps(out.to_dict()))
    doc["theta"]["min"][0] *= 1.5
    _undo_payload_narrowing(doc)
    assert "payload_narrowed_by_tune" in doc["bounds"] and doc != json.loads(json.dumps(ident.to_dict()))


def test_runs_second_try_cuts_a_defaulted_payload_to_the_axis_as_identified_and_validate_can_undo_it():
    from commission.report.verdict import validity_lines
    from commission.validate.provenance import _undo_payload_narrowing
    ident = axis(3 * M, defaulted=True)
    out, notes = as_identified_box(ident, "over the payloads 0..0.081 the gate failed (fixed arc_vs_pid_median)")
    lo, hi, m0, defaulted = payload_box(out)
    assert (lo, hi) == (0.0, 0.0) and defaulted and math.isclose(m0, M0)
    assert math.isclose(1.0 / out.theta.min[0], M0)  # the heavy end is the identified spread's: no payload
    assert out.theta.max == ident.theta.max and out.theta.min[2] == ident.theta.min[2]
    v = validity_of(out)
    assert v["payload_range"] == [0.0, 0.0] and v["default_payload_range"] == [0.0, 3 * M]
    assert "arc_vs_pid_median" in v["reason"] and len(notes) == 1 and "--payload-max" in notes[0]

    class Tuned:  # what the report reads of a tuning: its validity record
        validity = v
    first = validity_lines(Tuned())[0]
    assert first.startswith("**Certified for the axis as identified (no payload) only**") and "not the default" in first
    doc = json.loads(json.dumps(out.to_dict()))
    _undo_payload_narrowing(doc)  # validate's provenance check gives back ident.json's box
    assert doc == json.loads(json.dumps(ident.to_dict()))
    # a stated payload range, or one already cut to none, is not tried again
    assert as_identified_box(axis(3 * M, defaulted=False), "x") is None
    assert as_identified_box(out, "x") is None


def test_a_stated_payload_is_never_narrowed_and_the_gate_refuses_naming_the_corner():
    ident = axis(30 * M, defaulted=False)
    out, notes = narrow_default_payload(ident, SPEC)
    assert out is ident and notes == ()
    g = start_gains(ident, SPEC)[0]
    checks = box_checks(BoxArcCheck(ident, SPEC)(g), FLOORS)
    failed = [c for c in checks if not c.passed]
    assert failed and all(c.criterion == "margins_box" for c in failed)
    assert any(c.scenario.startswith("box/theta1_") for c in failed)
    # and on a box the gains hold, every box check passes
    ok = axis(0.5 * M, defaulted=False)
    assert all(c.passed for c in box_checks(BoxArcCheck(ok, SPEC)(start_gains(ok, SPEC)[0]), FLOORS))


def _controller(validity):
    g = start_gains(reference_identification(delta_d=0.5), SPEC)[0]
    prov = ControllerProvenance(log_sha256="a" * 64, ident_sha256="b" * 64, tuning_sha256="c" * 64,
                                tool_version="test", created_utc="2001-06-01T00:00:00Z")
    return ControllerConfig(gains=g, sample_rate=1.0 / g.Ts, units={"u": "V", "q": "m"}, validated={},
                            provenance=prov, validity=validity)


def test_controller_json_loads_with_and_without_validity():
    v = {"payload_range": [0.0, 0.05], "mass_range": [0.02, 0.09], "unit": "V·s²/m",
         "default_payload_range": [0.0, 0.081], "payload_defaulted": True, "reason": "r"}
    doc = _controller(v).to_dict()
    assert ControllerConfig.from_dict(json.loads(json.dumps(doc))).validity == v
    plain = _controller(None).to_dict()
    assert "validity" not in plain and ControllerConfig.from_dict(plain).validity is None
    bad = dict(doc)
    bad["validity"] = {**v, "payload_range": [0.05, 0.0]}
    with pytest.raises(SchemaError, match=r"\$\.validity\.payload_range"):
        ControllerConfig.from_dict(bad)


# --------------------------------------------------------------------------- the sample, end to end

SAMPLE = Path(__file__).resolve().parents[1] / "sample_data" / "axis_excitation.h5"


@pytest.mark.slow
def test_the_samples_passed_report_shows_no_unstable_or_below_floor_gated_row(tmp_path):
    from commission.pipeline import run_all
    from commission.tuning import Tuning
    out = tmp_path / "run"
    run_all(str(SAMPLE), out)
    report = (out / "report.md").read_text()
    tuning = Tuning.load(str(out / "tuning.json"))
    assert tuning.box is not None and tuning.box.holds(FLOORS)
    g = tuning.guarantees
    assert g["margins_over_box_at_plant_estimate"].holds and g["stability_over_box_any_estimate"].holds
    from commission.validate import check_provenance
    check_provenance(tuning, str(out / "tuning.json"))  # ident.json beside it: the narrowing is tune's
    alone = tmp_path / "alone"
    alone.mkdir()
    (alone / "tuning.json").write_bytes((out / "tuning.json").read_bytes())
    (out / "ident.json").rename(tmp_path / "ident-away.json")  # provenance.ident_path points there
    check_provenance(Tuning.load(str(alone / "tuning.json")), str(alone / "tuning.json"))  # and without it
    if "**Gate: PASSED**" in report:
        table = report.split("## Stability margins")[1].split("\n\n")[2].splitlines()[2:]
        assert table
        for row in table:
            cells = [c.strip() for c in row.strip("|").split("|")]
            assert cells[7] == "yes", row  # stable
            assert cells[8].startswith("met") or cells[8].startswith("*not gated*"), row
        assert "UNSTABLE" not in report.split("**The whole theta box.**")[1].split("\n")[0]


def test_a_defaulted_payload_the_drive_cannot_move_is_narrowed_to_what_it_can_not_refused():
    """A +-2.5 V drive cannot move the default box's heaviest plant (30 M of payload) at the least
    envelope the tool defaults to: the defaulted payload is cut to the largest the drive moves (the
    bisection's answer checked on both sides), recorded so that validate undoes it, even after the
    box check narrows it again; a stated payload is left for default_envelope to refuse."""
    from commission.errors import SpecError
    from commission.robustness import narrowed_ident
    from commission.tune.box import fit_payload_to_drive
    from commission.tune.defaults import default_envelope
    from commission.validate.provenance import _undo_payload_narrowing

    spec = spec_from_mapping({"controller": {"u_max": 2.5}})
    ident = axis(30 * M, defaulted=True)
    with pytest.raises(SpecError, match="controller.u_max"):
        default_envelope(spec, ident, set())
    out, notes = fit_payload_to_drive(spec, ident, set())
    lo, hi, _, defaulted = payload_box(out)
    assert defaulted and 0.0 < hi < 30 * M
    assert len(notes) == 1 and "the drive" in notes[0] and "--payload-max" in notes[0]
    default_envelope(spec, out, set())  # the narrowed box is one the drive moves ...
    with pytest.raises(SpecError):  # ... and a little more payload is not
        default_envelope(spec, narrowed_ident(ident, hi * 1.01), set())
    assert validity_of(out)["default_payload_range"] == [0.0, 30 * M]
    twice, _ = narrow_default_payload(out, spec)
    doc = json.loads(json.dumps(twice.to_dict()))
    _undo_payload_narrowing(doc)
    assert doc == json.loads(json.dumps(ident.to_dict()))
    stated = axis(30 * M, defaulted=False)
    same, none = fit_payload_to_drive(spec, stated, set())
    assert same is stated and none == ()


def test_the_early_stopping_holds_answers_as_the_whole_check():
    """BoxArcCheck.holds (stops at the first loop that settles it) gives the whole check's holds(),
    on boxes that hold and boxes that fail (unstable, below a floor), with and without the delayed estimates."""
    answers = []
    for payload, designed in ((3 * M, 3 * M), (30 * M, 3 * M), (10 * M, 3 * M), (3 * M, 10 * M)):
        ident = axis(payload, defaulted=False)
        for g in start_gains(axis(designed, defaulted=False), SPEC)[:3]:
            g = dataclasses.replace(g, theta_min=ident.theta.min)
            for delayed in (False, True):
                chk = BoxArcCheck(ident, SPEC, delay_any_estimate=delayed)
                whole = chk(g).holds(FLOORS)
                assert chk.holds(g, FLOORS) == whole
                answers.append(whole)
    assert any(answers) and not all(answers)
