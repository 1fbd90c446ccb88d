"""Plausibility of q's unit: the EMPS log written in mm but read as metres (data: ../shared/data/emps,
Janot, Gautier and Brunot, EMPS benchmark, nonlinearbenchmark.org 2019)."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.io
from shared_paths import EMPS_DIR

from commission.checks import check_log
from commission.logs import load_log

pytestmark = pytest.mark.skipif(not (EMPS_DIR / "DATA_EMPS.mat").exists(), reason="EMPS data not present")


@pytest.fixture(scope="module")
def emps_mm_csv(tmp_path_factory):
    d = scipy.io.loadmat(EMPS_DIR / "DATA_EMPS.mat")
    path = tmp_path_factory.mktemp("mm") / "emps_mm.csv"
    q_mm = d["qm"].ravel() * 1e3
    np.savetxt(path, np.c_[d["t"].ravel(), q_mm, d["vir"].ravel()], delimiter=",", header="t,q,u",
               comments="", fmt="%.10g")
    return path


def test_mm_read_as_m_warns_naming_q_unit(emps_mm_csv):
    warns = check_log(load_log(emps_mm_csv)).warnings
    speed = [w for w in warns if "peak speed" in w]
    assert len(speed) == 1 and "--q-unit mm" in speed[0]
    # README: EMPS peaks near 0.128 m/s (filtered); read as m the figure is ~1000x that.
    figure = float(speed[0].split("peak speed ")[1].split(" ")[0])
    assert 50 < figure < 500


def test_same_file_with_q_unit_mm_gives_no_plausibility_warning(emps_mm_csv):
    warns = check_log(load_log(emps_mm_csv, q_unit="mm")).warnings
    assert not [w for w in warns if "--q-unit" in w]
