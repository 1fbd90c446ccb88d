"""A friction test of several logs, one constant-speed leg per file (``identify LEG... | FOLDER``).

Real data: the TRO2021 screw drives (../shared/data/screwdrive-tro2021, Mablekos-Alexiou, da Cruz
and Bergeles, IEEE T-RO 37(4), 2021), read directly from their EPOS recorder files, against the
odd parts its README tabulates (computed there independently from the same files).  Known truth:
legs simulated from a closed-form friction curve.
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest
from shared_paths import TRO2021_DIR
from test_friction_map_tro import README_ODD
from typer.testing import CliRunner

from commission.artifacts import Identification
from commission.cli.main import app
from commission.errors import CommissionError, DataError, SchemaError, UsageError
from commission.identification import expand_log_paths, identify_legs, identify_log, parse_fix
from commission.identify.friction import stribeck_friction
from commission.logs import ExcitationLog

runner = CliRunner()
tro = pytest.mark.skipif(not TRO2021_DIR.is_dir(), reason="TRO2021 data not present")


def _folder(drive: int):
    return TRO2021_DIR / f"driveNo{drive}" / "steady_state" / "0.096kg"


@pytest.fixture(scope="module")
def drives(tmp_path_factory):
    """ident.json of each drive, from one command on its folder."""
    out = {}
    for drive in (1, 2, 3):
        path = tmp_path_factory.mktemp(f"d{drive}") / "ident.json"
        res = runner.invoke(app, ["identify", str(_folder(drive)), "--out", str(path)])
        assert res.exit_code == 0, res.output
        out[drive] = (json.loads(path.read_text()), res.output)
    return out


def _odd_part(fmap: dict, rpms) -> dict[int, tuple[float, float]]:
    """rpm -> (|speed| rpm, (F(+v) - F(-v))/2 in %): for each listed speed, the forward and the backward leg
    nearest to it."""
    v, F = np.array(fmap["velocity"]) * 30 / math.pi, np.array(fmap["force"])
    pos, neg = np.flatnonzero(v > 0), np.flatnonzero(v < 0)
    out = {}
    for rpm in rpms:
        i, j = pos[np.argmin(np.abs(v[pos] - rpm))], neg[np.argmin(np.abs(-v[neg] - rpm))]
        assert abs(v[i] + v[j]) < 0.05 * rpm + 1.0  # a pair of opposite legs
        out[rpm] = (abs(v[i]), (F[i] - F[j]) / 2)
    return out


@tro
@pytest.mark.parametrize("drive", [1, 2, 3])
def test_one_command_per_drive_gives_the_readme_odd_part_within_5_percent(drives, drive):
    doc, _ = drives[drive]
    odd = _odd_part(doc["friction_map"], README_ODD[drive])
    for rpm, ref in README_ODD[drive].items():
        speed, value = odd[rpm]
        assert speed == pytest.approx(rpm, rel=0.02, abs=1.5)
        assert value == pytest.approx(ref, rel=0.05), (drive, rpm, value, ref)
    assert set(doc["friction_map"]) == {"velocity", "force", "std", "n"}
    assert doc["units"] == {"q": "rad", "u": "%"}  # rotary axis, u in the file's unit


@tro
@pytest.mark.parametrize("drive, has_dip", [(1, True), (2, False), (3, True)])
def test_the_map_shows_the_dip_of_drives_1_and_3_and_none_for_drive_2(drives, drive, has_dip):
    odd = _odd_part(drives[drive][0]["friction_map"], [1, 2, *README_ODD[drive]])
    slow = odd[min(odd)][1]
    lowest = min(value for rpm, (_, value) in odd.items() if rpm <= 100)
    dip = (slow - lowest) / lowest  # README: ~7 % (drive 1), ~10 % (drive 3), < 1 % (drive 2)
    assert (dip > 0.03) == has_dip, dip


@tro
@pytest.mark.parametrize("drive", [1, 2, 3])
def test_the_inertia_is_reported_as_not_identified_and_tune_cannot_use_it(drives, drive, tmp_path):
    doc, output = drives[drive]
    assert doc["parameters"]["M"] is None and doc["theta"] is None and doc["delta_d"] is None
    assert "no acceleration" in doc["not_identified"]["M"]
    assert "not identified: M: the logs are constant-speed legs" in " ".join(output.split())
    # The artifact loads strictly and names the gap for tune.
    ident = Identification.from_dict(doc)
    (gap,) = ident.tuning_gaps()
    assert "$.parameters.M: not identified" in gap and "--fix M=" in gap


@tro
def test_a_fixed_inertia_gives_theta_and_its_box(tmp_path):
    path = tmp_path / "d1.json"
    res = runner.invoke(app, ["identify", str(_folder(1)), "--fix", "M=0.05", "--out", str(path)])
    assert res.exit_code == 0, res.output
    doc = json.loads(path.read_text())
    assert doc["parameters"]["M"] == {"value": 0.05, "std": 0.0} and doc["not_identified"] == {}
    assert doc["theta"]["nominal"][0] == pytest.approx(1 / 0.05)
    assert doc["theta"]["min"][0] < 20.0 < doc["theta"]["max"][0]
    assert Identification.from_dict(doc).tuning_gaps() == []


@tro
@pytest.mark.parametrize("drive", [1, 2, 3])
def test_no_subset_of_the_files_gives_anything_but_a_result_or_a_named_refusal(drive):
    files = expand_log_paths([str(_folder(drive))])
    by = {f.rsplit("/", 1)[1][:-4]: f for f in files}
    subsets = [[by[n], by["n" + n]] for n in by if not n.startswith("n") and "n" + n in by]  # direction pairs
    negative = [f for f in files if Path(f).name.startswith("n")]  # n10.csv: the leg at -10 rpm
    subsets += [files, negative, [f for f in files if f not in negative]]
    subsets += [expand_log_paths([str(TRO2021_DIR / f"driveNo{drive}" / "start_stop")]) + files[:1]]
    outcomes = []
    for sub in subsets:
        try:
            identify_legs(sub)
            outcomes.append("ok")
        except CommissionError as exc:  # one line naming a file
            assert str(exc).startswith(str(TRO2021_DIR)), exc
            outcomes.append(type(exc).__name__)
    assert "ok" in outcomes  # the whole folder identifies
    assert outcomes[-1] == "DataError"  # a start-stop run is not a constant-speed leg


# --------------------------------------------------------------------------- known truth

def _leg(v: float, F: float, seconds: float = 2.0, rate: float = 1000.0, noise: float = 0.0, seed: int = 0):
    t = np.arange(int(seconds * rate)) / rate
    rng = np.random.default_rng(seed)
    return ExcitationLog(t=t, q=0.01 + v * t, u=F + noise * rng.standard_normal(t.size), q_ref=None, u_unit="V",
                         q_unit_in_file="m", input_gain=1.0, source=f"leg_{v:+.4f}.h5", sha256="0" * 64,
                         sample_rate=rate)


def _truth_legs(speeds=(0.002, 0.004, 0.008, 0.015, 0.03, 0.06, 0.12, 0.25, 0.5)):
    v = np.array([s * d for s in speeds for d in (1.0, -1.0)])
    F = 0.27 * v + stribeck_friction(v, 0.10, 0.12, 0.01, 2.0) + 0.01
    return [_leg(vi, Fi, noise=0.002, seed=i) for i, (vi, Fi) in enumerate(zip(v, F))]


@pytest.fixture
def fake_loader(monkeypatch):
    legs = {}

    def load(path, **kw):
        return legs[path]

    monkeypatch.setattr("commission.identification.legs.load_log", load)  # identify_legs
    monkeypatch.setattr("commission.identification.files.load_log", load)  # identify_files
    return legs


def test_legs_of_a_known_stribeck_curve_give_it_back(fake_loader):
    for lg in _truth_legs():
        fake_loader[lg.source] = lg
    out = identify_legs(list(fake_loader), friction="stribeck")
    p = out.ident.parameters
    assert p["B"].value == pytest.approx(0.27, rel=0.02)
    assert p["fc"].value == pytest.approx(0.10, rel=0.02) and p["fs"].value == pytest.approx(0.12, rel=0.02)
    assert p["vs"].value == pytest.approx(0.01, rel=0.1) and p["offset"].value == pytest.approx(0.01, abs=1e-3)
    assert p["M"] is None and out.ident.theta is None
    # one map entry per leg, in the legs' order: mean speed, median force, spread, samples
    fm = out.ident.extra["friction_map"]
    assert fm["velocity"][0] == pytest.approx(0.002) and fm["n"][0] == 2000
    assert fm["std"][0] == pytest.approx(0.002, rel=0.1)


def test_a_stalled_leg_is_left_out_with_a_warning_and_a_moving_file_is_refused_by_name(fake_loader):
    for lg in _truth_legs():
        fake_loader[lg.source] = lg
    stalled = _leg(0.0, 0.05)
    stalled = ExcitationLog(t=stalled.t, q=np.full(stalled.t.size, 0.2), u=stalled.u, q_ref=None, u_unit="V",
                            q_unit_in_file="m", input_gain=1.0, source="stalled.h5", sha256="0" * 64,
                            sample_rate=1000.0)
    fake_loader["stalled.h5"] = stalled
    out = identify_legs(list(fake_loader), friction="stribeck")
    assert out.excluded == ("stalled.h5",)
    assert any(w.startswith("stalled.h5: mean speed 0") for w in out.ident.extra["warnings"])
    t = np.arange(2000) / 1000.0
    fake_loader["chirp.h5"] = ExcitationLog(t=t, q=0.01 * np.sin(2 * np.pi * t), u=np.sin(t), q_ref=None,
                                            u_unit="V", q_unit_in_file="m", input_gain=1.0, source="chirp.h5",
                                            sha256="0" * 64, sample_rate=1000.0)
    with pytest.raises(DataError, match=r"^chirp\.h5: not a constant-speed leg"):
        identify_legs(list(fake_loader), friction="stribeck")


def test_too_few_speeds_is_a_named_refusal(fake_loader):
    for lg in _truth_legs(speeds=(0.1, 0.2)):
        fake_loader[lg.source] = lg
    with pytest.raises(CommissionError, match=r"distinct speeds forward and 2 backward"):
        identify_legs(list(fake_loader), friction="coulomb")


def test_an_empty_list_of_logs_is_a_named_refusal():
    from commission.identification import identify_files

    for identify in (identify_legs, identify_files):
        with pytest.raises(UsageError, match=r"^identify: no log file given"):
            identify([])


def test_fix_parses_known_parameters_only():
    assert parse_fix(["M=0.027"]) == {"M": 0.027}
    for bad in ("B=1", "M", "M=-1", "M=abc", "M=inf"):
        with pytest.raises(UsageError, match=r"^--fix"):
            parse_fix([bad])


def test_ident_json_with_m_null_needs_its_reason(fake_loader):
    for lg in _truth_legs():
        fake_loader[lg.source] = lg
    doc = identify_legs(list(fake_loader)).ident.to_dict()
    assert Identification.from_dict(json.loads(json.dumps(doc))).parameters["M"] is None
    doc["not_identified"] = {}
    with pytest.raises(SchemaError, match=r"\$\.parameters\.M: expected an object"):
        Identification.from_dict(doc)


def test_a_fixed_mass_on_an_excitation_log_is_kept_and_the_rest_agrees_with_the_free_fit():
    sample = str(Path(__file__).resolve().parents[1] / "sample_data" / "axis_excitation.h5")
    free = identify_log(sample).ident
    M = free.parameters["M"].value
    fixed = identify_log(sample, fix={"M": M}).ident
    assert fixed.parameters["M"].value == M and fixed.parameters["M"].std == 0.0
    assert fixed.extra["model"]["fixed"] == {"M": M} and fixed.not_identified() == {}
    for name in ("B", "fc", "offset"):
        assert fixed.parameters[name].value == pytest.approx(free.parameters[name].value, rel=0.02, abs=1e-3)
    assert fixed.theta.nominal[0] == pytest.approx(1 / M)


def test_a_folder_without_logs_is_refused(tmp_path):
    (tmp_path / "empty").mkdir()
    with pytest.raises(UsageError, match="a folder without log files"):
        expand_log_paths([str(tmp_path / "empty")])


@tro
def test_tune_refuses_an_identification_without_the_inertia_naming_it(drives, tmp_path):
    path = tmp_path / "d1.json"
    path.write_text(json.dumps(drives[1][0]))
    res = runner.invoke(app, ["tune", str(path), "--out", str(tmp_path / "t.json")])
    assert res.exit_code == 2
    assert "$.parameters.M: not identified" in res.output and "--fix M=VALUE" in " ".join(res.output.split())
    assert not (tmp_path / "t.json").exists()


def test_a_poor_fit_and_an_undetermined_parameter_are_flagged_with_their_figures():
    from commission.identification import fit_quality_warnings

    w = fit_quality_warnings({"B": (13.0, 33.3), "fc": (20.0, 0.5)}, relative_error=0.87, condition_number=40.0)
    assert w[0].startswith("fit: relative error 0.87 (87 % of the command is not explained")
    assert w[1].startswith("B = 13 ± 33 (256 %): not determined by this log")
    assert len(w) == 2  # fc at 2.5 % is fine
    assert fit_quality_warnings({"B": (0.27, 0.01)}, relative_error=0.04, condition_number=26.0) == []


@tro
def test_validate_on_another_friction_test_gives_the_cross_test_error_of_the_curve(tmp_path):
    # Closed form: validated on its own legs, the cross-test error is the identification's own relative error.
    path = tmp_path / "d1.json"
    res = runner.invoke(app, ["identify", str(_folder(1)), "--validate-on", str(_folder(1)), "--out", str(path)])
    assert res.exit_code == 0, res.output
    doc = json.loads(path.read_text())
    assert doc["fit"]["validation_relative_error"] == pytest.approx(doc["fit"]["relative_error"], rel=1e-9)
    assert len(doc["validation_source"]["path"]) == 32
    # another drive's legs are not explained by drive 1's curve
    res = runner.invoke(app, ["identify", str(_folder(1)), "--validate-on", str(_folder(2)), "--out", str(path),
                              "--force"])
    assert res.exit_code == 0, res.output
    other = json.loads(path.read_text())["fit"]["validation_relative_error"]
    assert other > 10 * doc["fit"]["relative_error"]
