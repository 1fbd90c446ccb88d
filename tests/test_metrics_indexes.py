"""The one Indexes record: its table, its JSON form, and the scalar and batched paths agreeing.

References: a closed form (a controller that outputs nothing leaves the axis at rest, so the
measured error is ``-q_d`` and a sine's ``e_rms`` is ``A/sqrt(2)``), and the record format
tuning.json has always written (null for NaN, then ``diverged``).
"""

import dataclasses
import json
import math

import numpy as np
import pytest

from commission.controllers.metrics import (INDEX_NAMES, INDEX_ROWS, INDEX_TABLE, SCORE_NAMES, Indexes,
                                            batch_indexes, indexes)
from commission.controllers.pid import PidGains, pid_pack
from commission.controllers.simulate import KIND_PID, simulate, simulate_batch
from commission.controllers.trajectory import Trajectory
from commission.formats import tuning_json
from commission.paper import paper_controller, reference_plant

TS = 1e-3


def test_table_is_the_record_fields_in_order():
    fields = [f.name for f in dataclasses.fields(Indexes)]
    assert list(SCORE_NAMES) == fields[:-1] and fields[-1] == "diverged"
    assert INDEX_NAMES == SCORE_NAMES[:6] and SCORE_NAMES[-1] == "u_peak"
    assert set(INDEX_ROWS) == set(SCORE_NAMES) and len(INDEX_TABLE) == len(SCORE_NAMES)
    # Errors are shown in micro position units; inputs and c_u as stored.
    assert [r.scale for r in INDEX_TABLE] == [1e6, 1e6, 1e6, 1.0, 1.0, 1.0, 1.0]
    assert [r.heading("um", "V") for r in INDEX_TABLE[:6]] == [
        "e_M (um)", "e_F (um)", "‖e‖rms (um)", "‖u‖rms (V)", "‖Δu‖rms (V)", "c_u"]
    assert [r.heading("um", "V", ascii=True) for r in INDEX_TABLE[:6]] == [
        "e_M (um)", "e_F (um)", "||e||rms (um)", "||u||rms (V)", "||du||rms (V)", "c_u"]


def test_tuning_json_rows_agree_with_the_table():
    # tuning.json's score rows are built from the one table: every index, in its order, with its unit.
    units = {f.path.rsplit(".", 1)[1]: f.unit for f in tuning_json.score_rows("$.s")[1:-1]}
    assert units == {r.name: r.unit for r in INDEX_TABLE}


def test_positional_order_is_the_table_s():
    s = Indexes(1e-6, 2e-7, 3e-7, 0.2, 0.05, 0.25, 0.9, False)
    assert s == Indexes(e_M=1e-6, e_F=2e-7, e_rms=3e-7, u_rms=0.2, du_rms=0.05, c_u=0.25, u_peak=0.9, diverged=False)


def test_record_json_null_for_nan_and_inf():
    d = Indexes.of_run(None, 12.5).to_dict()
    assert d == {"e_M": None, "e_F": None, "e_rms": None, "u_rms": None, "du_rms": None, "c_u": None,
                 "u_peak": 12.5, "diverged": True}
    d = Indexes(1e-6, 2e-7, 3e-7, 0.2, 0.05, math.inf, 0.9, False).to_dict()
    assert json.dumps(d, sort_keys=True) == (
        '{"c_u": null, "diverged": false, "du_rms": 0.05, "e_F": 2e-07, "e_M": 1e-06, "e_rms": 3e-07, '
        '"u_peak": 0.9, "u_rms": 0.2}')


def test_a_diverged_run_records_its_peak_and_nan_indexes():
    # Gains that blow up at once: the run aborts; its record keeps the peak |u| it reached.
    traj = _sine(1e-3, 2.0, 0.5)
    wild = pid_pack(PidGains(Ts=TS, M_hat=0.0, B_hat=0.0, Kp=-1e9, Ki=0.0, Kd=0.0))
    r = simulate(reference_plant(0.027), KIND_PID, wild, traj)
    b = simulate_batch(reference_plant(0.027)[None, :], KIND_PID, wild, traj).scores()[0]
    assert r.diverged and r.score().diverged and b.diverged
    assert r.score().u_peak == float(np.max(np.abs(r.u))) == b.u_peak
    assert r.score().to_dict() == b.to_dict() and all(b.to_dict()[k] is None for k in INDEX_NAMES)


def test_batch_rows_become_records():
    idx = np.array([[1.0, 2.0, 3.0, 4.0, 5.0, 6.0], [np.nan] * 6])
    recs = batch_indexes(idx, np.array([7.0, 8.0]), np.array([False, True]))
    assert recs[0] == Indexes(1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 7.0, False)
    assert recs[1].to_dict() == Indexes.of_run(None, 8.0).to_dict()
    assert all(type(x) is float for x in dataclasses.astuple(recs[0])[:-1]) and recs[1].diverged is True


def _sine(A: float, f: float, T: float) -> Trajectory:
    t = np.arange(int(round(T / TS))) * TS
    w = 2 * math.pi * f
    return Trajectory(t, A * np.sin(w * t), A * w * np.cos(w * t), -A * w * w * np.sin(w * t))


def test_scalar_and_batched_paths_give_the_same_record_on_a_known_truth_run():
    # A PID with every gain zero commands nothing: the axis stays at rest at q = 0, the measured
    # error is -q_d = -A sin(w t) over whole periods, so e_M = e_F = A and e_rms = A/sqrt(2) exactly
    # (the 2 Hz sine has its peak on a sample); u = 0 gives u_rms = du_rms = u_peak = 0 and c_u undefined.
    A = 2e-3
    traj = _sine(A, 2.0, 3.0)
    zero = pid_pack(PidGains(Ts=TS, M_hat=0.0, B_hat=0.0, Kp=0.0, Ki=0.0, Kd=0.0))
    plant = reference_plant(0.027)
    # The second row is a real closed loop (the paper's PID on Set 1's plant) on the same motion.
    kind_p, pid = paper_controller("PID", TS)
    assert kind_p == KIND_PID
    one = [simulate(plant, KIND_PID, c, traj) for c in (zero, pid)]
    scalar = [r.score() for r in one]
    batch = simulate_batch(np.stack([plant, plant]), KIND_PID, np.stack([zero, pid]), traj, workers=1).scores()
    assert not one[0].diverged and np.all(one[0].q == 0.0)
    truth = scalar[0]
    assert truth.e_rms == pytest.approx(A / math.sqrt(2), rel=1e-12)
    assert truth.e_M == pytest.approx(A, rel=1e-12) and truth.e_F == pytest.approx(A, rel=1e-12)
    assert truth.u_rms == 0.0 and truth.du_rms == 0.0 and truth.u_peak == 0.0 and math.isnan(truth.c_u)
    assert not truth.diverged
    for s, b in zip(scalar, batch):
        assert s.to_dict() == b.to_dict()  # NaN compares as null
    assert scalar[1] == batch[1] and scalar[1].e_rms < truth.e_rms  # the loop really closed
    # The six indexes are those of the metric on the run's own signals.
    r = one[1]
    ix = indexes(r.t, r.e, r.u)
    assert [getattr(ix, k) for k in INDEX_NAMES] == [getattr(batch[1], k) for k in INDEX_NAMES]
