"""Several excitation logs of one axis fitted together, each file its own segment.

Known truth: closed-loop logs of the paper's axis simulated by the generator of
``test_identify_recovery`` (friction ladder + multisine, quantised encoder).  The
second log starts where the operator re-homed the axis: its positions are shifted
by a jump at the join, as between two recordings.
"""

from __future__ import annotations

import json

import h5py
import numpy as np
import pytest
from typer.testing import CliRunner

from commission.cli.main import app
from commission.errors import DataError
from commission.identification import identify_files
from commission.identify.errors import SignalError
from commission.identify.fit import evaluate_segments, fit_axis, fit_segments
from commission.synth import write_log_h5
from test_identify_recovery import PAPER, simulate

FS = 2500.0
JUMP = 0.05  # m: position jump between the two recordings

runner = CliRunner()


@pytest.fixture(scope="module")
def two_logs():
    a = simulate(PAPER, FS, rng=np.random.default_rng(100), lsb=1e-6, noise=0.01 * PAPER["fc"])
    b = simulate(PAPER, FS, rng=np.random.default_rng(101), lsb=1e-6, noise=0.01 * PAPER["fc"])
    return a, b


def _jumped(log, jump=JUMP):
    t, q, u = log
    return t, q + jump, u


def _naive(a, b):
    """The two logs concatenated into one (times continued): every filter runs across the join."""
    t = np.concatenate([a[0], a[0][-1] + 1.0 / FS + (b[0] - b[0][0])])
    return t, np.concatenate([a[1], b[1]]), np.concatenate([a[2], b[2]])


def _rel(fit, name):
    return fit.value(name) / PAPER[name] - 1.0


def test_two_logs_fitted_as_segments_give_the_truth_within_the_single_log_tolerances(two_logs):
    a, b = two_logs
    fit = fit_segments([a, _jumped(b)], friction="stribeck")
    single = fit_axis(*a, friction="stribeck")
    assert fit.method == "steady+dynamic"
    # the tolerances of test_identify_recovery.test_stribeck_recovery
    assert abs(_rel(fit, "M")) < 0.02 and abs(_rel(fit, "B")) < 0.02
    assert abs(_rel(fit, "fc")) < 0.05 and abs(_rel(fit, "fs")) < 0.10 and abs(_rel(fit, "vs")) < 0.20
    assert fit.value("offset") == pytest.approx(PAPER["offset"], abs=0.02 * PAPER["fc"])
    # both logs' legs are in the map, and twice the rows shrink the standard deviations
    assert fit.steady_velocity.size == 2 * single.steady_velocity.size
    for name in ("M", "B", "fc"):
        assert fit.parameters[name][1] < single.parameters[name][1], name
    # the stacked rows: as many as the two logs give on their own
    assert fit.force_measured.size == single.force_measured.size + fit_axis(*b, friction="stribeck").force_measured.size
    assert np.all(np.diff(fit.t_decimated) > 0)  # the second segment's time follows the first


def test_a_position_jump_at_the_join_does_not_bias_the_fit(two_logs):
    a, b = two_logs
    plain = fit_segments([a, b], friction="stribeck")
    jumped = fit_segments([a, _jumped(b)], friction="stribeck")
    for name, (value, _) in plain.parameters.items():
        assert jumped.parameters[name][0] == pytest.approx(value, rel=1e-4), name
    assert jumped.relative_error == pytest.approx(plain.relative_error, rel=1e-4)
    # Concatenated into one log, the filtered jump is a huge spurious velocity and acceleration.
    naive = fit_axis(*_naive(a, _jumped(b)), friction="stribeck")
    assert naive.relative_error > 3 * jumped.relative_error
    # The whole-log (EMPS) regression has no legs to fall back on: the jump ruins its mass,
    # while segments give what each log gives on its own.
    seg_dyn = fit_segments([a, _jumped(b)], friction="coulomb", use_steady=False)
    singles = [fit_axis(*x, friction="coulomb", use_steady=False).value("M") for x in (a, b)]
    naive_dyn = fit_axis(*_naive(a, _jumped(b)), friction="coulomb", use_steady=False)
    assert min(singles) - 0.005 * PAPER["M"] <= seg_dyn.value("M") <= max(singles) + 0.005 * PAPER["M"]
    assert abs(_rel(seg_dyn, "M")) < 0.02
    assert abs(_rel(naive_dyn, "M")) > 0.5


def test_evaluate_segments_reproduces_the_fit_and_validates_on_other_logs(two_logs):
    a, b = two_logs
    fit = fit_segments([a, _jumped(b)], friction="stribeck")
    assert evaluate_segments(fit, [a, _jumped(b)]) == pytest.approx(fit.relative_error, rel=1e-9)
    other = simulate(PAPER, FS, rng=np.random.default_rng(7), lsb=1e-6, noise=0.01 * PAPER["fc"])
    assert evaluate_segments(fit, [other, _jumped(a, -JUMP)]) <= 1.2 * fit.relative_error


def test_a_bad_segment_is_named_by_its_index(two_logs):
    a, _ = two_logs
    short = tuple(x[:20] for x in a)
    with pytest.raises(SignalError) as exc:
        fit_segments([a, short], friction="coulomb")
    assert exc.value.segment == 1
    slow = (a[0][::2] * 2.0, a[1][::2], a[2][::2])  # half the sample rate
    with pytest.raises(SignalError, match="share their sample rate") as exc:
        fit_segments([a, slow], friction="coulomb")
    assert exc.value.segment == 1


def _write(path, log):
    t, q, u = log
    write_log_h5(path, {"t": t, "q": q, "u": u})
    return path


def test_identify_fits_several_excitation_logs_together_and_validates_on_a_folder(two_logs, tmp_path):
    a, b = two_logs
    fa, fb = _write(tmp_path / "a.h5", a), _write(tmp_path / "b.h5", _jumped(b))
    (tmp_path / "val").mkdir()
    other = simulate(PAPER, FS, rng=np.random.default_rng(7), lsb=1e-6, noise=0.01 * PAPER["fc"])
    _write(tmp_path / "val" / "c.h5", other)
    _write(tmp_path / "val" / "d.h5", _jumped(a, -0.02))
    out = tmp_path / "ident.json"
    r = runner.invoke(app, ["identify", str(fa), str(fb), "--validate-on", str(tmp_path / "val"), "--out", str(out)])
    assert r.exit_code == 0, r.output
    doc = json.loads(out.read_text())
    assert doc["source"]["path"] == [str(fa), str(fb)] and len(doc["source"]["sha256"]) == 2
    assert doc["model"]["segments"] == [a[0].size, b[0].size]
    assert doc["source"]["n_samples"] == a[0].size + b[0].size
    M = doc["parameters"]["M"]["value"]
    assert M == pytest.approx(PAPER["M"], rel=0.02)
    assert len(doc["validation_source"]["path"]) == 2
    assert doc["fit"]["validation_relative_error"] <= 1.2 * doc["fit"]["relative_error"]
    # the same through the library, and a bad file among them is named
    fit = identify_files([str(fa), str(fb)]).fit
    assert fit.value("M") == pytest.approx(M, rel=1e-12)
    with h5py.File(tmp_path / "bad.h5", "w") as f:
        for k, x in zip("tqu", a):
            f[k] = x[:100]
    with pytest.raises(DataError, match=r"bad\.h5"):
        identify_files([str(fa), str(tmp_path / "bad.h5")])
