"""EMPS benchmark (real data): the identification reproduces the published IDIM-LS results.

Reference: Janot, Gautier & Brunot (2019), EMPS_Description.pdf §3.4 and the
benchmark's Script_IDIM_LS.m / Script_IDIM_LS_CTV.m, summarised in
/work/shared/data/emps/README.md.  Force = gtau * vir with gtau = 35.15065188248547 N/V.
"""

from __future__ import annotations

import math
import pathlib

import numpy as np
import pytest
from shared_paths import EMPS_DIR
import scipy.io

from commission.identify import evaluate, fit_axis, quantization_step

DATA = EMPS_DIR
GTAU = 35.15065188248547

pytestmark = pytest.mark.skipif(not (DATA / "DATA_EMPS.mat").exists(), reason="EMPS data not present")

# Published values (value, std) and figures of merit.
PUBLISHED = {"M": (95.1089, 0.1085), "B": (203.5034, 1.1460), "fc": (20.3935, 0.1012), "offset": (-3.1648, 0.0444)}


def _load(name: str) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    d = scipy.io.loadmat(DATA / name)
    assert float(d["gtau"].ravel()[0]) == GTAU
    return d["t"].ravel(), d["qm"].ravel(), GTAU * d["vir"].ravel()


@pytest.fixture(scope="module")
def emps():
    return _load("DATA_EMPS.mat")


@pytest.fixture(scope="module")
def pulses():
    return _load("DATA_EMPS_PULSES.mat")


@pytest.fixture(scope="module")
def coulomb_fit(emps):
    return fit_axis(*emps, friction="coulomb")


def test_emps_preprocessing_settings(coulomb_fit):
    # 100 Hz Butterworth, decimation round(0.8*500/40) = 10, 49 samples trimmed: 2480 rows
    f = coulomb_fit
    assert (f.sample_rate, f.cutoff_hz, f.decimation, f.trim_start) == (1000.0, 100.0, 10, 49)
    assert f.residuals.size == 2480
    # EMPS has constant-velocity plateaus at two speeds only: not a friction ladder
    assert f.method == "dynamic"


def test_emps_coulomb_within_tolerances(coulomb_fit):
    f = coulomb_fit
    assert f.value("M") == pytest.approx(95.1089, rel=0.005)
    assert f.value("B") == pytest.approx(203.5034, rel=0.02)
    assert f.value("fc") == pytest.approx(20.3935, rel=0.03)
    assert f.value("offset") == pytest.approx(-3.1648, abs=0.15)
    assert f.relative_error <= 0.045


def test_emps_coulomb_reproduces_published_digits(coulomb_fit):
    f = coulomb_fit
    for name, (value, std) in PUBLISHED.items():
        assert round(f.value(name), 4) == value, name
        # The benchmark scales inv(X'X) by std(e)^2 = ||e||^2/(N-1); our std uses the
        # unbiased ||e||^2/(N-p).  Converting reproduces its printed digits.
        n, p = f.residuals.size, 4
        assert round(f.parameters[name][1] * math.sqrt((n - p) / (n - 1)), 4) == std, name
    assert round(f.condition_number, 4) == 25.9883
    assert round(100 * f.relative_error, 4) == 4.0834
    assert round(float(np.linalg.norm(f.residuals)), 4) == 108.7569
    assert round(f.residual_std, 4) == 2.1843


def test_emps_cross_test(coulomb_fit, pulses):
    e = evaluate(coulomb_fit, *pulses)
    assert e <= 0.065
    assert round(100 * e, 4) == 5.9824


def test_emps_stribeck_fit_and_cross_test(emps, pulses):
    f = fit_axis(*emps, friction="stribeck")
    assert f.method == "dynamic"
    assert set(f.parameters) == {"M", "B", "fc", "fs", "vs", "xi", "offset"}
    # the extra curve cannot fit worse than the Coulomb model it contains
    assert f.relative_error <= 0.0409
    assert f.value("M") == pytest.approx(95.1089, rel=0.005)
    assert 0 < f.value("vs") < 0.13  # inside the speeds of the log
    e = evaluate(f, *pulses)
    assert e <= 0.065


def test_emps_encoder_grid():
    _, q, _ = _load("DATA_EMPS.mat")
    assert quantization_step(q) == pytest.approx(5e-8, rel=1e-6)
    # the PULSES record was resampled or processed: not on the grid
    _, q2, _ = _load("DATA_EMPS_PULSES.mat")
    assert quantization_step(q2) is None
