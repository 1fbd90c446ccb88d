"""``commission fleet``: the manifest, the outlier rule, and a fleet of 12 simulated axes (issue 33, must show 3)."""

from __future__ import annotations

import json
import re
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

from commission.cli.main import app
from commission.errors import SchemaError
from commission.fleet import OUTLIER_Z, exit_code, flag_outliers, load_manifest
from refusals import assert_refused

runner = CliRunner()


def invoke(*args):
    return runner.invoke(app, [str(a) for a in args])


def test_toml_and_csv_manifests_resolve_paths_and_defaults(tmp_path):
    (tmp_path / "m.toml").write_text('[fleet]\nspec = "fast.toml"\n\n[[axis]]\nname = "x1"\nlog = "logs/x1.h5"\n\n'
                                     '[[axis]]\nname = "x2"\nlog = "/abs/x2.h5"\nspec = "x2.toml"\ngate = "g.toml"\n')
    a = load_manifest(tmp_path / "m.toml")
    assert [e.name for e in a] == ["x1", "x2"]
    assert a[0].log == str(tmp_path / "logs/x1.h5") and a[0].spec == str(tmp_path / "fast.toml") and a[0].gate is None
    assert a[1].log == "/abs/x2.h5" and a[1].spec == str(tmp_path / "x2.toml") and a[1].gate == str(tmp_path / "g.toml")
    (tmp_path / "m.csv").write_text("name,log,gate\nx1,x1.h5,\nx2,d/,g.toml\n")
    c = load_manifest(tmp_path / "m.csv")
    assert c[0].gate is None and c[1].log == str(tmp_path / "d/") and c[1].gate == str(tmp_path / "g.toml")


@pytest.mark.parametrize("text, match", [
    ("name,log\nx1,a.h5\nx1,b.h5\n", r"row 3\.name = 'x1': listed twice"),
    ("name,log\nx1,\n", r"row 2\.log: missing"),
    ("name,log,speed\nx1,a.h5,3\n", r"column 'speed': unknown"),
    ("name,spec\nx1,a.toml\n", r"no 'log' column"),
    ("name,log\n../up,a.h5\n", r"row 2\.name = '\.\./up': a folder name"),
    ("name,log\n", r"no axis listed"),
])
def test_bad_csv_manifests_name_the_row_and_key(tmp_path, text, match):
    assert_refused(tmp_path / "m.csv", text, load_manifest, SchemaError, match)


def test_bad_toml_manifest_is_exit_2_before_any_axis(tmp_path):
    p = tmp_path / "m.toml"
    p.write_text('[[axis]]\nname = "x1"\nlog = "a.h5"\nmass = 3\n')
    r = invoke("fleet", p, "--out-dir", tmp_path / "out")
    assert r.exit_code == 2 and "axis[0].mass: unknown key" in r.output
    assert not (tmp_path / "out").exists()


def _row(name, M, fc, fs=None, status="passed"):
    u = {"M": "V·s²/m", "fc": "V", "fs": "V"}
    params = {k: {"value": v, "unit": u[k]} for k, v in (("M", M), ("fc", fc), ("fs", fc * 1.2 if fs is None else fs))}
    return {"name": name, "status": status, "parameters": params, "outlier": None}


def test_outlier_rule_flags_the_doubled_friction_and_not_a_few_percent_spread():
    rng = np.random.default_rng(0)
    rows = [_row(f"x{k}", 0.032 * (1 + 0.02 * rng.standard_normal()), 0.1 * (1 + 0.01 * rng.standard_normal()))
            for k in range(10)]
    rows.append(_row("heavy-friction", 0.032, 0.2))
    rows.append({"name": "broken", "status": "error", "parameters": None, "outlier": None})
    stats = flag_outliers(rows)
    flagged = [r["name"] for r in rows if (r["outlier"] or {}).get("flagged")]
    assert flagged == ["heavy-friction"]
    assert rows[10]["outlier"]["parameters"] == ["fc", "fs"] and rows[10]["outlier"]["z"]["fc"] > OUTLIER_Z
    # the median and MAD are those of the 11 identified axes (the error row has none)
    fc = np.array([r["parameters"]["fc"]["value"] for r in rows[:11]])
    assert stats["fc"]["median"] == pytest.approx(np.median(fc))
    assert stats["fc"]["mad"] == pytest.approx(np.median(np.abs(fc - np.median(fc))))
    assert rows[11]["outlier"] is None
    # a 3-axis fleet at the relative floor: 4 % off is no fault, 30 % off is
    few = [_row("a", 1.0, 1.0), _row("b", 1.04, 1.0), _row("c", 1.0, 1.3)]
    flag_outliers(few)
    assert [bool((r["outlier"] or {}).get("flagged")) for r in few] == [False, False, True]


def test_exit_code_is_0_only_when_every_axis_passed():
    assert exit_code([{"status": "passed"}] * 3) == 0
    assert exit_code([{"status": "passed"}, {"status": "failed"}]) == 1
    assert exit_code([{"status": "passed"}, {"status": "error"}]) == 1


# --------------------------------------------------------------------------- must show 3


def _write_fleet(folder: Path) -> None:
    from commission.synth import AxisTruth, ExcitationPlan, simulate_excitation, write_log_h5

    truth = AxisTruth(M=0.032, B=0.25, fc=0.10, fs=0.12, vs=0.01, xi=2.0, offset=0.01, ripple_amp=0.01,
                      ripple_pitch=0.03, lsb=0.5e-6, sample_rate=2500.0, u_unit="V", noise_std=0.1e-6, u_max=10.0)
    plan = ExcitationPlan(n_speeds=5, ms_duration=6.0, leg_max_time=0.8)  # a short log (about 17 s)
    lines = ["name,log"]
    for k in range(10):  # ten alike axes: masses within +-2 %, their own noise
        t = replace(truth, M=truth.M * (1 + 0.01 * ((k % 5) - 2)))
        write_log_h5(folder / f"x{k:02d}.h5", simulate_excitation(t, plan, np.random.default_rng(k)), q_unit="m",
                     u_unit="V")
        lines.append(f"x{k:02d},x{k:02d}.h5")
    t = replace(truth, fc=2 * truth.fc, fs=2 * truth.fs)
    write_log_h5(folder / "x10.h5", simulate_excitation(t, plan, np.random.default_rng(10)), q_unit="m", u_unit="V")
    lines.append("x10,x10.h5")
    (folder / "x11.h5").write_bytes((folder / "x00.h5").read_bytes()[:4000])  # a log cut off in transfer
    lines.append("x11,x11.h5")
    # a fast spec (search budget 8; the axes are rigid, so their first mode is stated beyond Nyquist, as
    # the rigid log cannot show it) and a gate that lets the short search's command activity pass and does
    # not hold its gains to the PID yardstick: this test is about the fleet, not the search
    (folder / "fleet.toml").write_text("[tune]\nbudget = 8\n[evidence]\nfirst_mode_hz = 50000.0\n")
    (folder / "gate.toml").write_text("[gate]\nc_u = 1.5\narc_vs_pid_median = 100.0\narc_vs_pid_p90 = 100.0\n"
                                       "arc_vs_pid_nominal = 100.0\n")
    text = "\n".join(lines) + "\n"
    (folder / "fleet.csv").write_text(text.replace("name,log", "name,log,spec,gate").replace(
        ".h5\n", ".h5,fleet.toml,gate.toml\n"))


@pytest.mark.slow
def test_fleet_of_12_axes_flags_the_doubled_friction_names_the_corrupt_log_and_resumes(tmp_path):
    src = tmp_path / "axes"
    src.mkdir()
    _write_fleet(src)
    out = tmp_path / "fleet"
    r = invoke("fleet", src / "fleet.csv", "--out-dir", out, "--monte-carlo", 4)
    assert r.exit_code == 1, r.output
    doc = json.loads((out / "fleet.json").read_text())
    rows = {row["name"]: row for row in doc["axes"]}
    assert [row["name"] for row in doc["axes"]] == [f"x{k:02d}" for k in range(12)]
    alike = [f"x{k:02d}" for k in range(10)]
    assert all(rows[n]["status"] == "passed" for n in alike), {n: rows[n]["status"] for n in alike}
    assert all((out / n / "controller.json").is_file() for n in alike)
    assert rows["x11"]["status"] == "error" and "x11.h5" in rows["x11"]["error"]
    assert "x11" in r.output and "x11.h5" in (out / "fleet.md").read_text()
    assert doc["summary"]["outliers"] == ["x10"]
    assert set(rows["x10"]["outlier"]["parameters"]) >= {"fc"}
    assert abs(rows["x10"]["parameters"]["fc"]["value"] / 0.2 - 1) < 0.1  # identified near the doubled truth
    assert rows["x00"]["parameters"]["M"]["unit"] == "V·s²/m" and rows["x00"]["e_rms"]["case1/nominal"]["pid"] > 0
    assert (out / "fleet.png").is_file() and (out / "fleet.md").read_text().count("| x") == 12
    for n in alike:  # what each certificate covers is controller.json's own validity, row for row
        claimed = json.loads((out / n / "controller.json").read_text()).get("validity")
        row = rows[n]["validity"]
        assert (row is None) == (claimed is None), n
        if row is not None:
            assert row["payload_range"] == pytest.approx(claimed["payload_range"]) and row["unit"] == claimed["unit"]
        assert rows[n]["not_better"] is False
    stamps = {n: (out / n / "validation.json").stat().st_mtime_ns for n in alike}
    # fix the corrupt log: the rerun commissions that axis only
    (src / "x11.h5").write_bytes((src / "x00.h5").read_bytes())
    r = invoke("fleet", src / "fleet.csv", "--out-dir", out, "--monte-carlo", 4)
    doc2 = json.loads((out / "fleet.json").read_text())
    assert doc2["summary"]["resumed"] == [f"x{k:02d}" for k in range(11)]
    assert {n: (out / n / "validation.json").stat().st_mtime_ns for n in alike} == stamps
    rows2 = {row["name"]: row for row in doc2["axes"]}
    assert rows2["x11"]["status"] == "passed" and not rows2["x11"]["resumed"]
    assert r.exit_code == (0 if rows2["x10"]["status"] == "passed" else 1)
    assert doc2["summary"]["outliers"] == ["x10"]


def test_inputs_hash_follows_the_files_contents_and_the_options(tmp_path):
    from commission.fleet import AxisEntry, inputs_sha256

    (tmp_path / "a.h5").write_bytes(b"log")
    (tmp_path / "s.toml").write_text("[tune]\nbudget = 8\n")
    e = AxisEntry("x", str(tmp_path / "a.h5"), str(tmp_path / "s.toml"))
    h = inputs_sha256(e, {"seed": 0, "monte_carlo": 4})
    assert h == inputs_sha256(e, {"seed": 0, "monte_carlo": 4})
    assert h != inputs_sha256(e, {"seed": 1, "monte_carlo": 4})
    (tmp_path / "s.toml").write_text("[tune]\nbudget = 9\n")
    assert h != inputs_sha256(e, {"seed": 0, "monte_carlo": 4})
    assert inputs_sha256(AxisEntry("x", str(tmp_path / "missing.h5")), {}) is None  # never resumed


def test_fleet_md_escapes_what_came_from_the_manifest_and_the_files():
    """An error row's log path and message come from the manifest and the axis's files: in fleet.md
    they are a code span and escaped text, so no link, tag or table cell can be injected."""
    from commission.fleet import fleet_markdown

    hostile = "bad](http://evil.example)<script>x</script>|cell"
    doc = {"summary": {"axes": 1, "passed": 0, "failed": 0, "errors": 1, "outliers": [], "exit_code": 1},
           "axes": [{"name": "x1", "status": "error", "log": "/d/`x](http://evil).h5", "error": f"SchemaError: {hostile}",
                     "elapsed_s": 0.1}],
           "statistics": {}}
    md = fleet_markdown(doc, None)
    errors = md.split("## Errors", 1)[1].split("## Outliers", 1)[0]
    outside_spans = re.sub(r"`[^`]*`", "", errors)  # inside a code span nothing is a link
    assert "](http" not in outside_spans.replace("\\](http", "") and "<script>" not in errors
    assert "`/d/'x](http://evil).h5`" in errors and "\\|cell" in errors


def test_fleet_md_says_what_each_certificate_covers_and_what_run_tried():
    """The verdict cell of a passed axis names a narrowed payload range (or "as identified") in its unit;
    a failed axis whose ARC was written flagged says "safe, not better"; run's failed second try is listed
    under the axis, escaped like every text that quotes the files."""
    from commission.fleet import fleet_markdown

    params = {k: {"value": 1.0, "unit": "V"} for k in ("M", "B", "fc", "fs", "offset")}
    base = {"parameters": params, "margins": None, "e_rms": None, "elapsed_s": 1.0, "outlier": None}
    rows = [
        {**base, "name": "a1", "status": "passed", "validity": None},
        {**base, "name": "a2", "status": "passed", "validity": {"payload_range": [0.0, 0.0266], "unit": "V·s²/m"}},
        {**base, "name": "a3", "status": "passed", "validity": {"payload_range": [0.0, 0.0], "unit": "kg"}},
        {**base, "name": "a6", "status": "passed",  # a unit edited into fleet.json before a resume
         "validity": {"payload_range": [0.0, 1.0], "unit": "kg|<b>x</b>](http://evil)"}},
        {**base, "name": "a4", "status": "failed", "not_better": True, "also_tried": None},
        {**base, "name": "a5", "status": "failed", "not_better": False,
         "also_tried": "the axis as identified failed too (case1/x](http://evil) e_rms)"},
    ]
    doc = {"summary": {"axes": 6, "passed": 4, "failed": 2, "errors": 0, "outliers": [], "exit_code": 1},
           "axes": rows, "statistics": {}}
    md = fleet_markdown(doc, None)
    cells = {line.split("|")[1].strip(): line.split("|")[2].strip() for line in md.splitlines()
             if re.match(r"\| a[1-5] ", line)}
    assert cells == {"a1": "PASSED", "a2": "PASSED for payloads 0 to 0.0266 V·s²/m only",
                     "a3": "PASSED as identified (no payload)",
                     "a4": "FAILED: safe, not better than the PID (controller\\_not\\_better.json)", "a5": "FAILED"}
    a6 = next(line for line in md.splitlines() if line.startswith("| a6 "))
    assert "<b>" not in a6 and "](http" not in a6.replace("\\](http", "") and "kg\\|" in a6
    tried = md.split("## Second tries", 1)[1].split("##", 1)[0]
    assert "**a5**" in tried and "**a4**" not in tried
    assert "](http" not in tried.replace("\\](http", "")
