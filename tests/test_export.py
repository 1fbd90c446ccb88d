"""``commission export --target c`` (issue 22): the C step is the Python step, bit for bit.

The controller: the paper's identified axis with the §4.3 gains carried over
(``base_arc_gains``) and the runtime guards validate sets, written as
controller.json (the full tune/validate pipeline on the sample log runs in
the ``slow`` test at the end).  Every C build uses the system compiler with
``-std=c99 -O2 -ffp-contract=off``; without ``cc`` these tests skip.
"""

import ctypes
import importlib.util
import json
import math
import subprocess
import sys
import textwrap
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

from commission.cli.main import app
from commission.controller_config import ControllerConfig, ControllerProvenance
from commission.controllers import arc as A
from commission.controllers import pid as P
from commission.controllers.simulate import KIND_ARC, _quantize, _segment, simulate
from commission.controllers.plant import NX, P_DELAY, plant_output, plant_start
from commission.controllers.metrics import FINAL_WINDOW, indexes_kernel
from commission.export import VECTOR_STEPS, output_names, render
from commission.export.build import build_replay, build_shared, find_cc
from commission.export.translate import TranslationError, translate
from commission.gate import GateSpec, resolve_gate
from commission.jsonio import write_json_atomic
from commission.paper import reference_identification
from commission.scenarios import case1_trajectory, case2_trajectory, identified_plant, plant_substeps, scenario_matrix
from commission.spec import default_spec
from commission.tune.baseline import pid_baseline
from commission.tune.gains import base_arc_gains
from commission.validate import deployable_gains, guard_values

SAMPLE = Path(__file__).resolve().parents[1] / "sample_data" / "axis_excitation.csv"
needs_cc = pytest.mark.skipif(find_cc() is None, reason="no C compiler (cc) on the PATH: the C export cannot be built")
runner = CliRunner()
LSB = 1e-6


def _config(g):
    prov = ControllerProvenance("a" * 64, "b" * 64, "c" * 64, "0.1.0", "2001-06-01T00:00:00Z")
    return ControllerConfig(gains=g, sample_rate=1.0 / g.Ts, units={"u": "V", "q": "m"}, validated={},
                            provenance=prov)


@pytest.fixture(scope="module")
def axis(tmp_path_factory):
    spec = default_spec()
    ident = reference_identification(delta_d=0.5)
    raw = base_arc_gains(ident, spec)
    limits = resolve_gate(GateSpec(), lsb=LSB, travel=spec.travel, u_max=spec.u_max)
    g = deployable_gains(raw, guard_values(raw.Ts, LSB, spec.v_max, spec.travel, limits.e_M))
    d = tmp_path_factory.mktemp("export")
    write_json_atomic(d / "controller.json", _config(g).to_dict())
    r = runner.invoke(app, ["export", str(d / "controller.json"), "--target", "c", "--out-dir", str(d / "c")])
    assert r.exit_code == 0, r.output
    return dict(spec=spec, ident=ident, g=g, dir=d, out=d / "c")


def _vectors(path):
    import csv
    with open(path) as f:
        rows = list(csv.DictReader(f))
    return rows


def test_export_writes_every_file_and_the_vectors(axis):
    out = axis["out"]
    assert sorted(p.name for p in out.iterdir()) == sorted(output_names("arc"))
    h = (out / "commission_arc.h").read_text()
    c = (out / "commission_arc.c").read_text()
    # only <math.h> and <stdint.h>; the layout constants are the Python module's
    assert [ln for ln in h.splitlines() + c.splitlines() if ln.startswith("#include <")] == \
        ["#include <stdint.h>", "#include <math.h>", "#include <stdint.h>"]
    for name in ("P_TS", "P_DY_MAX", "S_THETA", "S_FAULT", "FAULT_JUMP", "NP", "NS"):
        assert f"#define COMMISSION_ARC_{name} {getattr(A, name)}\n" in h
    assert "malloc" not in c and "static double" in c
    rows = _vectors(out / "test_vectors.csv")
    by = {}
    for r in rows:
        by.setdefault(r["scenario"], []).append(r)
    assert list(by) == ["case1", "case2", "fault"]
    assert len(by["case1"]) == len(by["fault"]) == VECTOR_STEPS
    assert len(by["case2"]) == min(VECTOR_STEPS, case2_trajectory(axis["spec"]).render(axis["g"].Ts, 0.0).n)
    codes = {int(r["fault"]) for r in by["fault"]}
    assert codes == {0, A.FAULT_JUMP}  # the 1 m jump latches; the later NaN meets a latched fault
    assert {int(r["fault"]) for r in by["case1"] + by["case2"]} == {0}
    params = (out / "commission_arc_params.c").read_text()
    assert ControllerConfig.load(str(axis["dir"] / "controller.json")).to_dict()["checksum"]["value"] in params
    assert "2500.0 Hz" in params


@pytest.fixture(scope="module")
def replay_exe(axis):
    return build_replay(axis["out"], "arc", axis["dir"] / "replay")


@needs_cc
def test_c_replays_the_python_runtime_bit_for_bit(axis, replay_exe):
    exe = replay_exe
    r = subprocess.run([str(exe), str(axis["out"] / "test_vectors.csv")], capture_output=True, text=True)
    rows = len(_vectors(axis["out"] / "test_vectors.csv"))
    assert r.stdout.split() == ["rows", str(rows), "max_abs_diff", "0", "unequal", "0", "fault_mismatch", "0"]
    assert r.returncode == 0


@needs_cc
def test_replay_detects_a_one_ulp_difference(axis, tmp_path, replay_exe):
    """The replay program is not blind: one command moved by one ulp is reported."""
    lines = (axis["out"] / "test_vectors.csv").read_text().splitlines()
    i = next(k for k, ln in enumerate(lines) if ln.startswith("case2,") and float(ln.split(",")[6]) != 0.0)
    f = lines[i].split(",")
    f[6] = repr(math.nextafter(float(f[6]), math.inf))
    lines[i] = ",".join(f)
    bad = tmp_path / "v.csv"
    bad.write_text("\n".join(lines) + "\n")
    r = subprocess.run([str(replay_exe), str(bad)], capture_output=True, text=True)
    assert r.returncode == 1 and "unequal 1 " in r.stdout


def _c_closed_loop(step, init, plant, traj, Ts, substeps, quant, u_sat, e_abort, noise=None):
    """closed_loop_kernel of controllers.simulate with the C step (Python loop): the plant's input delay
    (``c_{k-n_d-1}`` over the first ``f Ts`` of a sample, ``c_{k-n_d}`` over the rest) and encoder noise
    (the scenario's own draw) as there."""
    n = traj.n
    y_o, u_o = np.empty(n), np.empty(n)
    tau = plant[P_DELAY] / Ts
    n_d = int(math.floor(tau + 1e-9))
    f = tau - n_d if tau - n_d >= 1e-9 else 0.0
    hist = np.zeros(n_d + 2)
    nh = n_d + 2
    nz = np.zeros(n) if noise is None else noise
    st = np.empty(NX)
    plant_start(plant, st, 0.0)
    y = _quantize(plant_output(plant, st) + nz[0], quant)
    init(y)
    for k in range(n):
        x = plant_output(plant, st)
        if k > 0:
            y = _quantize(x + nz[k], quant)
        assert math.isfinite(x) and abs(x - traj.qd[k]) <= e_abort
        c = step(y, traj.qd[k], traj.dqd[k], traj.ddqd[k])
        hist[k % nh] = c
        c_late = hist[(k - n_d) % nh] if k >= n_d else 0.0
        c_early = hist[(k - n_d - 1) % nh] if k >= n_d + 1 else 0.0
        y_o[k] = y
        _segment(plant, st, c_early, u_sat, 0.0, f * Ts, substeps, Ts)
        u_o[k] = _segment(plant, st, c_late, u_sat, 0.0, (1.0 - f) * Ts, substeps, Ts)
    return y_o, u_o, indexes_kernel(y_o - traj.qd, u_o, float(traj.t[-1]), Ts, n, float(FINAL_WINDOW))


def _bind(lib):
    """(step, init, params address, a state) of a compiled ARC export."""
    step, init = lib.commission_arc_step, lib.commission_arc_init
    step.restype = ctypes.c_double
    step.argtypes = [ctypes.c_void_p, ctypes.c_void_p] + [ctypes.c_double] * 4
    init.restype = None
    init.argtypes = [ctypes.c_void_p, ctypes.c_void_p, ctypes.c_double]
    p_addr = ctypes.addressof(ctypes.c_double.in_dll(lib, "commission_arc_params_validated"))
    return step, init, p_addr, (ctypes.c_double * A.NS)()


@needs_cc
@pytest.mark.parametrize("case", ["case1", "case2"])
def test_c_step_in_the_closed_loop_gives_the_simulated_indexes(axis, tmp_path, case):
    lib = ctypes.CDLL(str(build_shared(axis["out"], "arc", tmp_path / "libarc.so")))
    step, init, p_addr, state = _bind(lib)
    g, spec = axis["g"], axis["spec"]
    traj = (case1_trajectory if case == "case1" else case2_trajectory)(spec).render(g.Ts, 0.0)
    plant = identified_plant(axis["ident"])
    sub = plant_substeps(1.0 / g.Ts)
    y, u, idx = _c_closed_loop(lambda *a: step(state, p_addr, *a), lambda y0: init(state, p_addr, y0),
                               plant, traj, g.Ts, sub, LSB, spec.u_max, spec.travel)
    sim = simulate(plant, KIND_ARC, A.arc_pack(g), traj, substeps=sub, quant=LSB, u_sat=spec.u_max,
                   e_abort=spec.travel)
    assert np.array_equal(y, sim.y) and np.array_equal(u, sim.u)
    i = sim.indexes
    assert (idx[0], idx[1], idx[2]) == (i.e_M, i.e_F, i.e_rms)


@needs_cc
def test_pid_exports_the_same_way(axis, tmp_path):
    pg = pid_baseline(axis["ident"], axis["spec"])[0]
    files = render("pid", P.pid_pack(pg), _config(axis["g"]), None, "d" * 64)
    for name, text in files.items():
        (tmp_path / name).write_text(text)
    exe = build_replay(tmp_path, "pid", tmp_path / "replay")
    r = subprocess.run([str(exe), str(tmp_path / "test_vectors.csv")], capture_output=True, text=True)
    assert r.returncode == 0 and " max_abs_diff 0 unequal 0 fault_mismatch 0" in r.stdout
    assert "#define COMMISSION_PID_G_KP 3\n" in files["commission_pid.h"]
    assert {ln.split(",")[-1] for ln in files["test_vectors.csv"].splitlines()[1:]} == {"0", "1"}  # NaN latches


def _invoke_export(path, out):
    return runner.invoke(app, ["export", str(path), "--target", "c", "--out-dir", str(out)])


@pytest.mark.parametrize("how", ["checksum", "schema", "version", "missing"])
def test_export_refuses_what_load_controller_refuses(axis, tmp_path, how):
    doc = json.loads((axis["dir"] / "controller.json").read_text())
    if how == "checksum":
        doc["gains"]["g1"] *= 1.01  # edited after validation, checksum left as it was
    elif how == "schema":
        doc["gains"]["bogus"] = 1.0
    elif how == "version":
        doc["schema_version"] = 99
    path = tmp_path / "controller.json"
    if how != "missing":
        path.write_text(json.dumps(doc))
    out = tmp_path / "out"
    r = _invoke_export(path, out)
    assert r.exit_code == 2 and r.output.startswith("error: ") and len(r.output.strip().splitlines()) == 1
    assert not out.exists()


def test_export_refuses_a_foreign_tuning_and_pid_without_one(axis, tmp_path):
    other = tmp_path / "tuning.json"
    other.write_text("{}")
    out = tmp_path / "out"
    r = runner.invoke(app, ["export", str(axis["dir"] / "controller.json"), "--out-dir", str(out),
                            "--controller", "pid"])
    assert r.exit_code == 2 and "--tuning" in r.output and not out.exists()
    r = runner.invoke(app, ["export", str(axis["dir"] / "controller.json"), "--out-dir", str(out), "--target", "vhdl"])
    assert r.exit_code == 2 and "--target" in r.output and not out.exists()
    r = _invoke_export(axis["dir"] / "controller.json", axis["out"])  # exists
    assert r.exit_code == 2 and "--force" in r.output


def _module_from(tmp_path, name, body):
    src = tmp_path / f"{name}.py"
    src.write_text(textwrap.dedent(body))
    spec = importlib.util.spec_from_file_location(name, src)
    mod = importlib.util.module_from_spec(spec)
    sys.modules[name] = mod
    spec.loader.exec_module(mod)
    return mod


@pytest.mark.parametrize("stmt", ["u = u ** 2", "while u > 1.0:\n                u = u - 1.0", "u = max(u, 0.0)",
                                  "u = s[0:2]", "u = np.sum(p)"])
def test_translator_refuses_what_it_does_not_follow(tmp_path, stmt):
    """A change to a step the translator cannot follow fails the export, naming the function and line."""
    mod = _module_from(tmp_path, "fake_step", f"""
        import math
        import numpy as np
        P_A = 0

        def step(p, s, y):
            u = p[P_A] * y
            {stmt}
            return u
        """)
    with pytest.raises(TranslationError, match=r"fake_step\.step, line 8"):
        translate(mod, ["step"], {"p": ("NP", True), "s": ("NS", False)}, "x_")


def test_translator_keeps_python_order_of_operations(tmp_path):
    mod = _module_from(tmp_path, "fake_order", """
        def step(p, s, y):
            return y - p[0] - p[1] * y * y / p[2]
        """)
    code, _ = translate(mod, ["step"], {"p": ("NP", True), "s": ("NS", False)}, "x_")
    assert "return ((y - p[0]) - (((p[1] * y) * y) / p[2]));" in code


@pytest.mark.slow
@needs_cc
def test_sample_pipeline_export_matches_validate(tmp_path):
    """The sample log through `commission run`, then export (ARC and PID, with --tuning): bit-exact
    replays, and the C ARC in the closed loop gives validate's nominal e_M, e_F, e_rms (controller.json)."""
    from commission.tuning import Tuning
    from commission.jsonio import read_json

    out = tmp_path / "axis"
    r = runner.invoke(app, ["run", str(SAMPLE), "--out-dir", str(out)])
    assert r.exit_code == 0, r.output
    for kind in ("arc", "pid"):
        r = runner.invoke(app, ["export", str(out / "controller.json"), "--out-dir", str(tmp_path / kind),
                                "--controller", kind, "--tuning", str(out / "tuning.json")])
        assert r.exit_code == 0, r.output
        exe = build_replay(tmp_path / kind, kind, tmp_path / f"replay_{kind}")
        rr = subprocess.run([str(exe), str(tmp_path / kind / "test_vectors.csv")], capture_output=True, text=True)
        assert rr.returncode == 0 and " max_abs_diff 0 unequal 0 fault_mismatch 0" in rr.stdout
    tuning = Tuning.from_dict(read_json(out / "tuning.json"))
    nominal = read_json(out / "controller.json")["validated"]["nominal"]
    lib = ctypes.CDLL(str(build_shared(tmp_path / "arc", "arc", tmp_path / "libarc.so")))
    step, init, p_addr, state = _bind(lib)
    g, spec = tuning.arc, tuning.spec
    # validate's nominal scenarios as validate builds them: the identified plant (its mode and delay), the
    # encoder's quantization and noise (drawn per scenario name)
    nominal_sc = {sc.name: sc for sc in scenario_matrix(tuning.identification, spec, rng=np.random.default_rng(0),
                                                        n_monte_carlo=0)}
    for case in ("case1", "case2"):
        sc = nominal_sc[f"{case}/nominal"]
        traj = sc.trajectory.render(g.Ts, sc.y0)
        _, _, idx = _c_closed_loop(lambda *a: step(state, p_addr, *a), lambda y0: init(state, p_addr, y0),
                                   sc.plant, traj, g.Ts, plant_substeps(1.0 / g.Ts), sc.quantization, spec.u_max,
                                   spec.travel, noise=sc.noise(traj.n))
        assert (idx[0], idx[1], idx[2]) == (nominal[case]["e_M"], nominal[case]["e_F"], nominal[case]["e_rms"])


@pytest.mark.slow  # blark builds its lark grammar on first use: about 20 s
@pytest.mark.parametrize("kind", ["arc", "pid"])
def test_structured_text_function_block_parses_and_carries_the_params(axis, tmp_path, kind):
    blark = pytest.importorskip("blark", reason="blark (the ST parser) is not installed")
    import re
    from commission.export.c_target import TARGETS
    from commission.export.st_target import st_source

    if kind == "arc":
        r = runner.invoke(app, ["export", str(axis["dir"] / "controller.json"), "--target", "st",
                                "--out-dir", str(tmp_path)])
        assert r.exit_code == 0, r.output
        src = (tmp_path / "FB_CommissionArc.st").read_text()
        p = A.arc_pack(axis["g"])
    else:
        p = P.pid_pack(pid_baseline(axis["ident"], axis["spec"])[0])
        src = st_source(TARGETS["pid"], p, ["test"])
    res = blark.parse_source_code(src)
    assert res.exception is None, res.exception
    fb = "FB_CommissionArc" if kind == "arc" else "FB_CommissionPid"
    assert f"FUNCTION_BLOCK {fb}" in src and "METHOD Init" in src and "METHOD Step : LREAL" in src
    # the parameters, written by Init, read back exactly (inf as the INF member)
    got = {int(i): v for i, v in re.findall(r"^p\[(\d+)\] := (\S+);$", src, flags=re.M)}
    assert sorted(got) == list(range(p.shape[0]))
    for i, v in got.items():
        assert (math.isinf(p[i]) and v == "INF") or float(v) == p[i]
    # the packed layout is the Python module's
    mod = A if kind == "arc" else P
    for name in ("S_FAULT", "NS"):
        assert f"    {name} : DINT := {getattr(mod, name)};" in src
    # a method per translated function
    assert src.count("(* translated from ") == len(TARGETS[kind].functions)
