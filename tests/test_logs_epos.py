"""EPOS Studio recorder files (commission.logs.epos) on the real TRO2021 screw-drive data.

Data: ../shared/data/screwdrive-tro2021 (Mablekos-Alexiou, da Cruz, Bergeles, IEEE T-RO 37(4), 2021;
github.com/RViMLab/TRO2021-Dynamic-Modelling), described in its README.
"""

from __future__ import annotations

import math
import shutil

import numpy as np
import pytest
from shared_paths import TRO2021_DIR
from typer.testing import CliRunner

from commission.cli.main import app
from commission.errors import DataError, UsageError
from commission.identify.friction import StribeckNotIdentifiableError, fit_separable
from commission.logs import load_log

pytestmark = pytest.mark.skipif(not TRO2021_DIR.is_dir(), reason="TRO2021 data not present")


def steady(drive: int, name: str):
    return TRO2021_DIR / f"driveNo{drive}" / "steady_state" / "0.096kg" / name


def test_epos_file_reads_as_rotary_log_with_its_header_period():
    log = load_log(steady(1, "10.csv"))
    assert log.n == 500
    assert log.q_unit_in_file == "rad" and log.u_unit == "%"
    # README: drive 1 at 10 rpm has Ts = 51.2 ms; the first row reads -10 rpm and -32.0 %.
    assert np.allclose(np.diff(log.t), 0.0512)
    assert log.u[0] == -32.0
    # q is the integral of the velocity: its mean slope is the mean speed, about -10 rpm (file's sign).
    speed_rpm = (log.q[-1] - log.q[0]) / (log.t[-1] - log.t[0]) * 30 / math.pi
    assert -11 < speed_rpm < -9


def test_header_without_scale_lines_and_annotated_first_rows():
    assert load_log(steady(1, "n2.csv")).n == 500  # README: no Scale: lines
    # README: three re-saved files carry a hand-edited first row ("...,,was -8.9"): dropped.
    for name in ("1.csv", "2.csv", "n1.csv"):
        log = load_log(steady(3, name))
        assert log.n == 499
        assert abs(log.u[0]) < 100  # the edited rows held -1200, -800, -400 %


def test_recognised_from_content_and_format_forces(tmp_path):
    other = tmp_path / "run.dat"
    shutil.copy(steady(2, "50.csv"), other)
    assert load_log(other).q_unit_in_file == "rad"
    # Forcing the generic CSV reader: the EPOS header is not a t,q,u header.
    with pytest.raises(DataError, match="channel 't' not found"):
        load_log(steady(2, "50.csv"), fmt="csv")
    with pytest.raises(UsageError, match="--format"):
        load_log(steady(2, "50.csv"), fmt="xml")


def test_every_tro2021_file_exits_0_or_2_without_traceback():
    files = sorted(TRO2021_DIR.glob("driveNo*/*/**/*.csv"))
    assert len(files) == 114  # README: 114 CSV files
    runner = CliRunner()
    codes = []
    for f in files:
        res = runner.invoke(app, ["identify", str(f), "--out", "/dev/null"])
        assert res.exit_code in (0, 2), (f, res.exit_code, res.exception)
        assert res.exception is None or isinstance(res.exception, SystemExit), (f, res.exception)
        codes.append(res.exit_code)
    # Single constant-speed runs cannot give a Coulomb level apart from the offset: most are refused.
    assert codes.count(2) > 100


def test_stalled_leg_is_not_identifiable_instead_of_log_zero():
    v = np.linspace(-1, 1, 50)
    Phi = np.c_[np.sign(v), np.ones_like(v)]
    with pytest.raises(StribeckNotIdentifiableError, match="slowest speed"):
        fit_separable(Phi, ("fc", "offset"), lambda vs, xi: np.sign(v), lambda vs, xi: (v, v), v,
                      vs_bounds=(0.0, 0.5))


def test_an_epos_log_says_its_position_was_integrated_from_velocity_a_measured_one_does_not():
    """Only a recorder's integrated velocity gets the 1-rpm quantum allowance of the leg detector."""
    from pathlib import Path

    assert load_log(steady(1, "10.csv")).q_from_velocity is True
    sample = Path(__file__).resolve().parents[1] / "sample_data" / "axis_excitation.h5"
    assert load_log(str(sample)).q_from_velocity is False
