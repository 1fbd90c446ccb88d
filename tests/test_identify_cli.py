"""End-to-end `commission identify` through typer's CliRunner: EMPS, sample data, bad input."""

from __future__ import annotations

import json
from pathlib import Path

import h5py
import numpy as np
import pytest
from typer.testing import CliRunner

from commission.cli.main import app
from shared_paths import EMPS_DIR

EMPS = EMPS_DIR
SAMPLE = Path(__file__).resolve().parents[1] / "sample_data"
EMPS_ARGS = ["--map", "q=qm", "--map", "u=vir", "--input-gain", "35.15065188248547", "--u-unit", "N"]

runner = CliRunner()


def invoke(args: list[str]):
    return runner.invoke(app, args, catch_exceptions=False)


@pytest.fixture(scope="module")
def emps_json(tmp_path_factory) -> dict:
    if not (EMPS / "DATA_EMPS.mat").is_file():
        pytest.fail(f"EMPS data missing at {EMPS}")
    out = tmp_path_factory.mktemp("emps") / "emps.json"
    r = invoke(["identify", str(EMPS / "DATA_EMPS.mat"), *EMPS_ARGS, "--friction", "coulomb",
                "--validate-on", str(EMPS / "DATA_EMPS_PULSES.mat"), "--out", str(out)])
    assert r.exit_code == 0, r.output
    return json.loads(out.read_text())


def test_emps_reproduces_published_parameters(emps_json):
    # Published IDIM-LS values (EMPS_Description.pdf §3.4), not numbers this tool produced.
    p = emps_json["parameters"]
    assert p["M"]["value"] == pytest.approx(95.1089, rel=0.005)
    assert p["B"]["value"] == pytest.approx(203.5034, rel=0.02)
    assert p["fc"]["value"] == pytest.approx(20.3935, rel=0.03)
    assert abs(p["offset"]["value"] - (-3.1648)) <= 0.15
    assert emps_json["fit"]["relative_error"] <= 0.045
    assert emps_json["fit"]["validation_relative_error"] <= 0.065
    assert emps_json["units"] == {"u": "N", "q": "m"}
    assert p["fs"] is None and p["vs"] is None and p["xi"] is None


def test_emps_json_has_contract_shape(emps_json):
    assert emps_json["kind"] == "identification" and emps_json["schema_version"] == 1
    assert set(emps_json["fit"]) >= {"relative_error", "condition_number", "validation_relative_error"}
    th = emps_json["theta"]
    M = emps_json["parameters"]["M"]["value"]
    assert th["nominal"][0] == pytest.approx(1.0 / M)
    assert th["nominal"][1] == pytest.approx(emps_json["parameters"]["B"]["value"] / M)
    assert th["nominal"][2] == pytest.approx(-emps_json["parameters"]["offset"]["value"] / M)
    for lo, nom, hi in zip(th["min"], th["nominal"], th["max"]):
        assert lo <= nom <= hi
    assert emps_json["delta_d"] > 0
    assert set(emps_json["friction_compensation"]) == {"level", "slope"}
    assert emps_json["encoder"]["quantization"] == pytest.approx(5e-8, rel=1e-3)


def test_sample_data_recovers_truth_with_plots(tmp_path):
    """The bundled sample (an `excite` plan recorded on a known two-mass axis) against its truth.json."""
    doc_truth = json.loads((SAMPLE / "truth.json").read_text())
    truth = doc_truth["axis"]["parameters"]
    out = tmp_path / "ident.json"
    r = invoke(["identify", str(SAMPLE / "axis_excitation.h5"), "--plan", str(SAMPLE / "plan.json"),
                "--friction", "stribeck", "--ripple-pitch", str(truth["ripple_pitch"]["value"]),
                "--out", str(out), "--plot", str(tmp_path / "plots")])
    assert r.exit_code == 0, r.output
    doc = json.loads(out.read_text())
    p = doc["parameters"]
    # the load-force bound: the default 10 max(fc, fs), flagged so that tune may narrow it to the drive
    assert doc["bounds"]["disturbance_bound"] == pytest.approx(10 * max(p["fc"]["value"], p["fs"]["value"]))
    assert doc["bounds"]["disturbance_bound_defaulted"] is True
    # issue #31's loop: B and fc within 1 %, M within 1.5 % as on test_excite's three axes.  M carries a
    # bias on this two-mass log: over twelve recordings of the same plan (six encoder-noise seeds, each
    # on the plant with the ripple's sin per sub-step and with its anchored rotation, docs/scaling.md
    # "Tenth pass") it came out 0.45-1.02 % low, mean 0.77 %, beyond its reported std (about 0.12 %); the
    # rotation alone, a rounding-level change, moves the committed recording's M from -0.75 to -1.02 %.
    assert p["M"]["value"] == pytest.approx(truth["M"]["value"], rel=0.015)
    for k in ("B", "fc"):
        assert p[k]["value"] == pytest.approx(truth[k]["value"], rel=0.01), k
    assert p["fs"]["value"] == pytest.approx(truth["fs"]["value"], rel=0.05)
    assert p["vs"]["value"] == pytest.approx(truth["vs"]["value"], rel=0.10)
    assert p["offset"]["value"] == pytest.approx(truth["offset"]["value"], abs=0.1 * truth["fc"]["value"])
    # the frequency response from the plan's injection: the mode within 5 % in frequency and 30 % in
    # damping, on the encoder's side (non-collocated), and the delay within 0.2 sample
    fr = doc["frequency_response"]
    assert fr["source"] == "broadband"
    res = [m for m in fr["modes"] if m["kind"] == "resonance"]
    assert len(res) == 1, fr["modes"]
    assert res[0]["frequency_hz"] == pytest.approx(truth["mode_hz"]["value"], rel=0.05)
    assert res[0]["damping"] == pytest.approx(truth["mode_damping"]["value"], rel=0.30)
    assert fr["model"]["mode_load_side"] is bool(truth["mode_load_side"]["value"])
    rate = doc_truth["log"]["sample_rate_hz"]
    assert fr["delay_samples"] == pytest.approx(truth["delay"]["value"] * rate, abs=0.2)
    assert doc["encoder"]["quantization"] == pytest.approx(truth["lsb"]["value"], rel=1e-6)
    for name in ("force_fit.png", "friction_curve.png", "residuals.png", "bode.png"):
        png = tmp_path / "plots" / name
        assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def _write_h5(path: Path, t, q, u) -> Path:
    with h5py.File(path, "w") as f:
        f["t"], f["q"], f["u"] = t, q, u
    return path


def _good_arrays(n: int = 5000, fs: float = 1000.0):
    t = np.arange(n) / fs
    q = 0.01 * np.sin(2 * np.pi * 1.0 * t)
    u = 0.2 * np.sin(2 * np.pi * 1.0 * t + 0.3)
    return t, q, u


def _bad_log(kind: str, tmp: Path) -> Path:
    t, q, u = _good_arrays()
    if kind == "missing":
        return tmp / "nope.h5"
    if kind == "not_a_log":
        p = tmp / "junk.h5"
        p.write_bytes(b"\x89PNG\r\n\x1a\n" + bytes(range(256)) * 4)
        return p
    if kind == "missing_channel":
        p = tmp / "noq.h5"
        with h5py.File(p, "w") as f:
            f["t"], f["u"] = t, u
        return p
    if kind == "nan":
        q = q.copy()
        q[1234] = np.nan
    elif kind == "backwards":
        t = t.copy()
        t[777] = t[775]
    elif kind == "short":
        t, q, u = t[:50], q[:50], u[:50]
    elif kind == "constant":
        u = np.full_like(u, 0.3)
    return _write_h5(tmp / f"{kind}.h5", t, q, u)


@pytest.mark.parametrize(
    "kind, pattern",
    [
        ("missing", r"nope\.h5: no such file"),
        ("not_a_log", r"junk\.h5"),
        ("missing_channel", r"channel 'q' not found"),
        ("nan", r"q.*1234.*NaN|q.*NaN.*1234"),
        ("backwards", r"t.*not strictly increasing.*777"),
        ("short", r"too short"),
        ("constant", r"u.*constant"),
    ],
)
def test_bad_input_exits_2_with_one_line_and_no_output(kind, pattern, tmp_path):
    import re

    log = _bad_log(kind, tmp_path)
    out = tmp_path / "ident.json"
    r = runner.invoke(app, ["identify", str(log), "--out", str(out), "--plot", str(tmp_path / "p")])
    assert r.exit_code == 2, r.output
    err = r.stderr.strip()
    assert len(err.splitlines()) == 1, err
    assert err.startswith("error: ")
    assert re.search(pattern, err), err
    assert "Traceback" not in r.output
    assert not out.exists() and not (tmp_path / "p").exists()


def test_bad_flags_exit_2(tmp_path):
    log = SAMPLE / "axis_excitation.h5"
    for args, pattern in [
        (["--map", "qm"], r"--map|NAME=SOURCE"),
        (["--input-gain", "-1"], r"--input-gain"),
        (["--payload-max-kg", "5"], r"--force-constant"),
        (["--ripple-pitch", "0"], r"--ripple-pitch"),
        (["--ripple-pitch", "fine"], r"--ripple-pitch.*auto"),
        (["--ripple-pitch", "auto", "--ripple-pitch", "0.03"], r"--ripple-pitch: give either auto"),
        (["--ripple-pitch", "none", "--ripple-pitch", "0.03"], r"--ripple-pitch: give either none"),
        (["--u-unit", "furlong"], r"--u-unit"),
    ]:
        r = runner.invoke(app, ["identify", str(log), "--out", str(tmp_path / "x.json"), *args])
        assert r.exit_code == 2, (args, r.output)
        import re

        assert re.search(pattern, r.stderr), (args, r.stderr)
        assert not (tmp_path / "x.json").exists()


@pytest.mark.parametrize("command", ["identify", "run"])
def test_an_input_gain_without_its_unit_is_refused_naming_u_unit(tmp_path, command):
    # Volts times N/V are newtons: an artifact labelled with the file's unit would be wrong.
    log = SAMPLE / "axis_excitation.h5"
    out = tmp_path / "out"
    target = ["--out", str(out)] if command == "identify" else ["--out-dir", str(out)]
    r = runner.invoke(app, [command, str(log), *target, "--input-gain", "35.15"])
    assert r.exit_code == 2, r.output
    err = r.stderr.strip()
    assert len(err.splitlines()) == 1, err
    assert "--input-gain 35.15 needs --u-unit" in err, err
    assert not out.exists() and list(tmp_path.iterdir()) == []
    # a gain of 1 leaves u in the file's unit, and a named unit is taken: both run
    if command == "identify":
        for args in (["--input-gain", "1"], ["--input-gain", "2", "--u-unit", "N"]):
            r = runner.invoke(app, [command, str(log), *target, "--force", *args])
            assert r.exit_code == 0, (args, r.output)
        assert json.loads(out.read_text())["units"]["u"] == "N"


def test_friction_auto_falls_back_to_coulomb_where_stribeck_refuses(tmp_path):
    from commission.synth import AxisTruth, ExcitationPlan, simulate_excitation, write_log_h5

    # The paper's axis (vs = 10 mm/s) on a ladder that starts at 40 mm/s: no sample below 3 vs.
    truth = AxisTruth(M=0.027, B=0.273, fc=0.10, fs=0.12, vs=0.01, xi=2.0, offset=0.0, ripple_amp=0.0,
                      ripple_pitch=0.03, lsb=1e-6, sample_rate=2500.0, u_unit="V", noise_std=0.0, u_max=10.0)
    write_log_h5(tmp_path / "fast.h5", simulate_excitation(truth, ExcitationPlan(v_min=0.04), np.random.default_rng(3)))
    out = tmp_path / "ident.json"
    r = invoke(["identify", str(tmp_path / "fast.h5"), "--out", str(out)])  # default: --friction auto
    assert r.exit_code == 0, r.output
    doc = json.loads(out.read_text())
    assert (doc["model"]["friction"], doc["model"]["friction_requested"]) == ("coulomb", "auto")
    assert doc["parameters"].get("fs") is None
    assert doc["parameters"]["M"]["value"] == pytest.approx(0.027, rel=0.03)
    assert any(w.startswith("friction auto: Stribeck curve not identifiable (too few samples below 3*vs")
               for w in doc["warnings"])
    assert "friction auto: Stribeck curve not identifiable" in " ".join(r.output.split())
    # insisting on the Stribeck model refuses the same log: exit 2, one line, nothing written
    out2 = tmp_path / "strict.json"
    r = runner.invoke(app, ["identify", str(tmp_path / "fast.h5"), "--friction", "stribeck", "--out", str(out2)])
    assert r.exit_code == 2 and "too few samples below 3*vs" in r.output and not out2.exists()


def test_csv_in_millimetres_with_q_unit_identifies_as_the_metre_log(tmp_path):
    # The bundled CSV (metres) rewritten in mm: with --q-unit mm the fit must not change.
    table = np.genfromtxt(SAMPLE / "axis_excitation.csv", delimiter=",", names=True)
    mm = tmp_path / "axis_mm.csv"
    cols = [table["t"], table["q"] * 1e3, table["u"], table["q_ref"] * 1e3]
    np.savetxt(mm, np.column_stack(cols), delimiter=",", header="t,q,u,q_ref", comments="", fmt="%.17g")
    out_m, out_mm = tmp_path / "m.json", tmp_path / "mm.json"
    assert invoke(["identify", str(SAMPLE / "axis_excitation.csv"), "--out", str(out_m)]).exit_code == 0
    r = invoke(["identify", str(mm), "--q-unit", "mm", "--out", str(out_mm)])
    assert r.exit_code == 0, r.output
    dm, dmm = (json.loads(p.read_text()) for p in (out_m, out_mm))
    assert (dm["source"]["q_unit"], dmm["source"]["q_unit"]) == ("m", "mm")
    pm, pmm = dm["parameters"], dmm["parameters"]
    for k in ("M", "B", "fc", "offset"):
        assert pmm[k]["value"] == pytest.approx(pm[k]["value"], rel=1e-9), k


def test_q_unit_contradicting_the_file_is_exit_2_and_writes_nothing(tmp_path):
    out = tmp_path / "ident.json"
    r = runner.invoke(app, ["identify", str(SAMPLE / "axis_excitation.h5"), "--q-unit", "mm", "--out", str(out)])
    assert r.exit_code == 2
    assert not out.exists()
    r2 = runner.invoke(app, ["identify", str(SAMPLE / "axis_excitation.h5"), "--q-unit", "in", "--out", str(out)])
    assert r2.exit_code == 2 and "--q-unit: expected one of m, mm, um, rad, got 'in'" in r2.output


def test_the_default_ripple_search_finds_the_samples_ripple_and_with_it_the_stribeck_rise(tmp_path):
    """The sample's fit without a ripple (``--ripple-pitch none``) keeps Coulomb friction only: the force
    ripple (0.01 V at 30 mm) on the slow legs hides the Stribeck rise (fs 0.12 V at vs 10 mm/s,
    truth.json).  By default (as with ``--ripple-pitch auto``) identify finds the pitch on the
    constant-velocity legs, and the fit then recovers the ripple and the rise as the known pitch does."""
    truth = json.loads((SAMPLE / "truth.json").read_text())["axis"]["parameters"]
    docs = {}
    for tag, extra in (("none", ["--ripple-pitch", "none"]), ("auto", ["--ripple-pitch", "auto"]), ("default", [])):
        out = tmp_path / f"{tag}.json"
        r = invoke(["identify", str(SAMPLE / "axis_excitation.h5"), "--out", str(out), *extra])
        assert r.exit_code == 0, r.output
        docs[tag] = json.loads(out.read_text())
    assert docs["none"]["parameters"]["fs"] is None and docs["none"]["model"]["ripple_pitch"] is None
    assert "ripple_search" not in docs["none"]["model"]
    assert docs["default"]["parameters"] == docs["auto"]["parameters"]
    assert docs["default"]["model"]["ripple_search"] == docs["auto"]["model"]["ripple_search"]
    doc = docs["auto"]
    search, p = doc["model"]["ripple_search"], doc["parameters"]
    assert search["pitch"] == doc["model"]["ripple_pitch"] == pytest.approx(truth["ripple_pitch"]["value"], rel=0.005)
    assert doc["model"]["ripple_amp"]["value"] == pytest.approx(truth["ripple_amp"]["value"], rel=0.05)
    assert p["fs"]["value"] == pytest.approx(truth["fs"]["value"], rel=0.02)
    assert p["vs"]["value"] == pytest.approx(truth["vs"]["value"], rel=0.05)
    assert doc["warnings"][0].startswith("ripple pitch auto: 0.0299")
