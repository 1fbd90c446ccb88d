"""Issue 24, must-show 1-3: every bad input is exit 2 with one line and nothing written; outputs are
transactional and locked; the floors no gate can lower; null limits and signatures of controller.json.

A stored tuning (the paper's axis, search budget 8) is validated with zero to two
Monte-Carlo plants so that the subprocess tests (signals, two concurrent runs) stay short.
"""

from __future__ import annotations

import copy
import json
import os
import re
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
from typer.testing import CliRunner

from commission.cli.main import app, run
from commission.controller_config import ControllerConfig, ControllerProvenance
from commission.errors import SchemaError
from commission.jsonio import read_json, write_json_atomic
from commission.paper import reference_identification
from commission.runtime import load_controller

ROOT = Path(__file__).resolve().parents[1]
SAMPLE = ROOT / "sample_data" / "axis_excitation.h5"
runner = CliRunner()
#: A gate every sound or broken controller passes on its own criteria, so that only the floors decide.
LOOSE_GATE = ('[gate]\ne_F = "1 m"\ne_M = "1 m"\ne_rms = "1 m"\nc_u = 1000.0\nu_max = 1e9\n'
              'no_divergence = false\narc_vs_pid_e_rms = 1e6\narc_vs_pid_median = 1e6\narc_vs_pid_p90 = 1e6\n'
              'arc_vs_pid_nominal = 1e6\n')


#: tuning.json of ``tune`` on the paper's axis with ``tune.budget = 8`` (tuning takes tens of seconds).
TUNING_DOC = json.loads((Path(__file__).parent / "data" / "tuning_paper_budget8.json").read_text())


@pytest.fixture(scope="module")
def tuned(tmp_path_factory):
    d = tmp_path_factory.mktemp("tuning")
    doc = copy.deepcopy(TUNING_DOC)
    doc["provenance"]["ident_path"] = "not-here/ident.json"  # no ident.json at hand: checked against ident_sha256
    path = d / "tuning.json"
    write_json_atomic(path, doc)
    return path


@pytest.fixture()
def ident_json(tmp_path):
    p = tmp_path / "ident.json"
    p.write_text(json.dumps(reference_identification().to_dict()))
    return p


def listing(d: Path) -> dict[str, bytes]:
    """Every file under ``d`` (hidden ones included) with its bytes."""
    return {str(p.relative_to(d)): p.read_bytes() for p in sorted(d.rglob("*")) if p.is_file()}


def refused(r, pattern: str) -> None:
    assert r.exit_code == 2, r.output
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1, r.stderr
    assert lines[0].startswith("error: ") and re.search(pattern, lines[0]), lines[0]
    assert "Traceback" not in r.output


def invoke(*args):
    return runner.invoke(app, [str(a) for a in args])


# --------------------------------------------------------------------------- must-show 1


def test_identify_out_an_existing_folder(tmp_path):
    (tmp_path / "d").mkdir()
    before = listing(tmp_path)
    refused(invoke("identify", SAMPLE, "--out", tmp_path / "d"), r"--out .*d: is a directory")
    assert listing(tmp_path) == before


@pytest.mark.parametrize("argv", [
    lambda t, i: ["identify", SAMPLE, "--out", "/proc/x/ident.json"],
    lambda t, i: ["tune", i, "--out", "/proc/x/tuning.json"],
    lambda t, i: ["validate", t, "--out-dir", "/proc/x"],
    lambda t, i: ["run", SAMPLE, "--out-dir", "/proc/x/out"],
])
def test_unwritable_outputs_are_refused_before_any_computation(tuned, ident_json, monkeypatch, argv):
    # Any computation would fail the test: the refusal must come first.
    import commission.cli.identify_cmd as identify_cmd
    import commission.pipeline as pipeline
    import commission.tune as tune_mod
    import commission.validate.outputs as validate_mod

    def boom(*a, **k):
        raise AssertionError("computation started before the output path was checked")

    for mod, name in ((identify_cmd, "identify_log"), (tune_mod, "tune_from"), (validate_mod, "validate"),
                      (pipeline, "_stages")):
        monkeypatch.setattr(mod, name, boom)
    refused(invoke(*argv(tuned, ident_json)), r"/proc/x.*(cannot|not a folder)")


def test_identify_plot_onto_an_existing_file(tmp_path):
    (tmp_path / "plots").write_text("mine")
    before = listing(tmp_path)
    refused(invoke("identify", SAMPLE, "--out", tmp_path / "ident.json", "--plot", tmp_path / "plots"),
            r"--plot .*plots: exists and is not a folder")
    assert listing(tmp_path) == before


@pytest.mark.parametrize("which", ["spec", "gate"])
def test_toml_that_is_not_utf8(tuned, ident_json, tmp_path, which):
    bad = tmp_path / f"{which}.toml"
    bad.write_bytes(b"[controller]\nu_max = 10 # \xff\xfe latin-1 \xe9\n")
    before = listing(tmp_path)
    if which == "spec":
        r = invoke("tune", ident_json, "--out", tmp_path / "t.json", "--spec", bad)
    else:
        r = invoke("validate", tuned, "--out-dir", tmp_path / "v", "--gate", bad)
    refused(r, rf"{which}\.toml: not UTF-8 text \(byte \d+")
    assert listing(tmp_path) == before


@pytest.mark.parametrize("toml, key", [
    ("[controller]\nsample_rate = 1e9\n", "controller.sample_rate = 1000000000.0 Hz is outside"),
    ("[trajectory]\ndwell = 1e9\n", "trajectory.dwell = 1000000000.0 s is outside"),
    ("[trajectory]\nmoves = 100000000\n", "trajectory.moves = 100000000 is outside"),
    ("[tune]\nbudget = 9223372036854775807\n", "tune.budget = 9223372036854775807 is outside"),
    ("[tune]\nmonte_carlo = 100000000\n", "tune.monte_carlo = 100000000 is outside"),
    ("[tune]\nmargin = 2\n", "tune.margin = 2.0 is outside"),
    # each key within its range, together too long a run
    ("[trajectory]\ndwell = 60.0\nmoves = 100\n", "controller.sample_rate = 2500 Hz with a Case 2 trajectory"),
])
def test_spec_numbers_out_of_range(ident_json, tmp_path, toml, key):
    spec = tmp_path / "spec.toml"
    spec.write_text(toml)
    before = listing(tmp_path)
    refused(invoke("tune", ident_json, "--out", tmp_path / "t.json", "--spec", spec), re.escape(key))
    assert listing(tmp_path) == before


@pytest.mark.parametrize("argv, flag", [
    (lambda t: ["validate", t, "--out-dir", "v", "--monte-carlo", 100000000], "--monte-carlo"),
    (lambda t: ["validate", t, "--out-dir", "v", "--workers", 0], "--workers"),
    (lambda t: ["run", SAMPLE, "--out-dir", "v", "--workers", 100000], "--workers"),
    (lambda t: ["paper-table", "--substeps", 1000000000], "--substeps"),
])
def test_flags_out_of_range(tuned, tmp_path, monkeypatch, capsys, argv, flag):
    # Through the console script's run(): click's own range errors are one line there too.
    monkeypatch.chdir(tmp_path)
    assert run([str(a) for a in argv(tuned)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("error: ") and flag in err[0], err
    assert list(tmp_path.iterdir()) == []


def _nested(depth: int) -> str:
    return "[" * depth + "]" * depth


def test_deeply_nested_json_everywhere(tuned, tmp_path):
    deep = tmp_path / "deep.json"
    deep.write_text(_nested(200_000))
    before = listing(tmp_path)
    refused(invoke("tune", deep, "--out", tmp_path / "t.json"), r"deep\.json: not valid JSON \(nested too deeply\)")
    refused(invoke("validate", deep, "--out-dir", tmp_path / "v"), r"nested too deeply")
    with pytest.raises(SchemaError, match="nested too deeply"):
        load_controller(deep)
    assert listing(tmp_path) == before


def test_ident_json_with_an_absurd_log_rate(ident_json, tmp_path):
    doc = json.loads(ident_json.read_text())
    doc.setdefault("source", {})["sample_rate"] = 1e9
    ident_json.write_text(json.dumps(doc))
    before = listing(tmp_path)
    refused(invoke("tune", ident_json, "--out", tmp_path / "t.json"),
            r"controller\.sample_rate \(the log's rate\) = 1000000000\.0 Hz is outside")
    assert listing(tmp_path) == before


def test_csv_symlink_to_dev_zero_fifo_and_device_are_refused(tmp_path):
    (tmp_path / "zero.csv").symlink_to("/dev/zero")
    os.mkfifo(tmp_path / "fifo.csv")
    before = sorted(p.name for p in tmp_path.iterdir())
    refused(invoke("identify", tmp_path / "zero.csv", "--out", tmp_path / "i.json"), r"zero\.csv: is a device")
    refused(invoke("identify", tmp_path / "fifo.csv", "--out", tmp_path / "i.json"), r"fifo\.csv: is a FIFO")
    refused(invoke("tune", tmp_path / "fifo.csv", "--out", tmp_path / "t.json"), r"fifo\.csv: is a FIFO")
    assert sorted(p.name for p in tmp_path.iterdir()) == before


def test_oversized_log_is_refused_before_it_is_read(tmp_path, monkeypatch):
    import commission.logs as logs

    big = tmp_path / "big.csv"
    big.write_text("t,q,u\n" + "0.0,0.0,0.0\n" * 1000)
    monkeypatch.setattr(logs, "MAX_LOG_BYTES", 100)
    refused(invoke("identify", big, "--out", tmp_path / "i.json"), r"big\.csv: .* larger than the")
    assert not (tmp_path / "i.json").exists()


def test_output_that_is_an_input_is_refused_even_with_force(tmp_path, ident_json):
    log = tmp_path / "L.h5"
    log.write_bytes(SAMPLE.read_bytes())
    for force in ([], ["--force"]):
        refused(invoke("identify", log, "--out", log, *force), r"--out .*L\.h5: is also an input")
        refused(invoke("tune", ident_json, "--out", ident_json, *force), r"--out .*ident\.json: is also an input")
    assert log.read_bytes() == SAMPLE.read_bytes()
    assert json.loads(ident_json.read_text()) == reference_identification().to_dict()


def test_identify_no_longer_overwrites_silently(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    (tmp_path / "ident.json").write_text("{}")
    refused(invoke("identify", SAMPLE), r"--out ident\.json: exists; pass --force to overwrite")
    assert (tmp_path / "ident.json").read_text() == "{}"
    r = invoke("identify", SAMPLE, "--force")
    assert r.exit_code == 0, r.output
    assert read_json(tmp_path / "ident.json")["kind"] == "identification"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["ident.json"]  # no temporary file, no lock left


def test_an_unexpected_error_is_one_line_with_a_log_and_no_traceback(monkeypatch, capsys, tmp_path):
    import commission.cli.identify_cmd as identify_cmd

    def bug(*a, **k):
        raise ZeroDivisionError("a bug")

    monkeypatch.setattr(identify_cmd, "identify_log", bug)
    monkeypatch.setenv("TMPDIR", str(tmp_path))
    import tempfile

    monkeypatch.setattr(tempfile, "tempdir", None)
    code = run(["identify", str(SAMPLE), "--out", str(tmp_path / "i.json")])
    err = capsys.readouterr().err
    assert code == 2
    lines = err.strip().splitlines()
    assert len(lines) == 1 and "Traceback" not in err, err
    m = re.fullmatch(r"error: internal error \(ZeroDivisionError: a bug\); please report it with the log (\S+)",
                     lines[0])
    assert m, lines[0]
    log = Path(m.group(1))
    assert log.parent == tmp_path and "Traceback" in log.read_text() and "ZeroDivisionError" in log.read_text()
    assert not (tmp_path / "i.json").exists()


def test_usage_errors_are_one_line(capsys):
    assert run(["identify"]) == 2
    assert run(["validate", "x.json", "--no-such-flag"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 2 and all(e.startswith("error: ") for e in err), err


def _commission(*args, **kw):
    """The installed console script (as a user runs it), else the same entry point through python."""
    script = Path(sys.executable).parent / "commission"
    head = [str(script)] if script.is_file() else [
        sys.executable, "-c", "import sys; sys.argv[0] = 'commission'; from commission.cli.main import main; main()"]
    return subprocess.Popen([*head, *map(str, args)], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, **kw)


def _in_package(frame_file: str) -> bool:
    """Whether a traceback frame is in this package's own code, wherever it is installed.

    Not "under the checkout": a virtual environment inside the checkout (the usual
    newcomer layout) puts the interpreter's import machinery and the console script
    there too, and those run before the package can install its handlers."""
    import commission.cli
    import commission.controllers
    import commission.identify

    roots = {Path(m.__file__).resolve().parent for m in (commission, commission.cli, commission.identify,
                                                          commission.controllers)}
    f = Path(frame_file).resolve()
    return any(f.is_relative_to(r) for r in roots)


@pytest.mark.parametrize("delay", [0.0, 0.02, 0.05, 0.1, 0.2, 0.4, 0.8, 1.2])
def test_ctrl_c_during_start_up_is_clean(tmp_path, delay):
    p = _commission("identify", SAMPLE, "--out", tmp_path / "i.json", cwd=tmp_path)
    time.sleep(delay)
    p.send_signal(signal.SIGINT)
    out, err = p.communicate(timeout=60)
    if p.returncode == 0:  # it finished before the signal (or Python dropped the interrupt in a finaliser,
        # "Exception ignored in ...": a KeyboardInterrupt raised inside __del__ cannot propagate)
        assert read_json(tmp_path / "i.json")["kind"] == "identification"
        return
    frames = re.findall(r'File "([^"]+)"', err)
    if not err.startswith("interrupted") and not any(_in_package(f) for f in frames):
        # The signal came before the first line of this package ran: the interpreter starting
        # ("Fatal Python error: init_...", or a bare "KeyboardInterrupt" from site's start-up
        # hooks) or the launcher's import system still looking for the package. No program can
        # handle that window (tens of ms); nothing is written in it.
        assert p.returncode != 0 and not list(tmp_path.iterdir())
        return
    assert "Traceback" not in err, err
    # 130 once the tool runs; killed by SIGINT itself (-2) if it came before Python had started
    assert p.returncode in (130, -signal.SIGINT), (p.returncode, err)
    if p.returncode == 130:
        assert err.strip().splitlines()[-1] in ("interrupted", "interrupted: no output written or replaced"), err
    assert list(tmp_path.iterdir()) == []


# --------------------------------------------------------------------------- must-show 2

def _names(d: Path) -> list[str]:
    return sorted(p.name for p in d.iterdir()) if d.exists() else []


def _no_leftovers(parent: Path) -> None:
    left = [p.name for p in parent.iterdir() if ".tmp-" in p.name or p.name.endswith(".lock")]
    assert not left, left


def _validate_argv(tuned, out):
    return ["validate", tuned, "--out-dir", out, "--monte-carlo", 2, "--workers", 1, "--force"]


_KERNEL_INTERRUPTED = """
import os, signal, sys, threading
import numpy as np
from commission.cli.main import run
from commission.identify import ripple

kernel = ripple._powers
calls = []
def search_hit_by_ctrl_c(k, *rest):
    # One Ctrl-C, landing while the compiled ripple search runs: the grid is made 10 x finer so
    # that the kernel is busy for seconds and the signal arrives 0.3 s into it (or, in a fresh
    # install, while numba compiles it: it is then taken once the compiler is done).
    if not calls:
        threading.Timer(0.3, os.kill, (os.getpid(), signal.SIGINT)).start()
    calls.append(k.size)
    return kernel(np.linspace(k[0], k[-1], 10 * k.size), *rest)
ripple._powers = search_hit_by_ctrl_c
sys.exit(run(["identify", sys.argv[1], "--out", sys.argv[2]]))
"""


def test_ctrl_c_while_a_compiled_kernel_runs_is_clean(tmp_path):
    """A signal that arrives inside compiled numba code is taken when the kernel has returned: raising
    it in the kernel's call back into Python (boxing its result) killed the process with SIGSEGV and
    left the staged output and the lock behind."""
    p = subprocess.run([sys.executable, "-c", _KERNEL_INTERRUPTED, str(SAMPLE), str(tmp_path / "i.json")],
                       capture_output=True, text=True, timeout=600, cwd=tmp_path)
    assert p.returncode == 130, (p.returncode, p.stderr[-2000:])
    assert "Traceback" not in p.stderr and "Fatal Python error" not in p.stderr, p.stderr
    assert p.stderr.strip().splitlines()[-1] == "interrupted: no output written or replaced"
    assert list(tmp_path.iterdir()) == []


def test_two_concurrent_validations_into_one_folder_exactly_one_proceeds(tuned, tmp_path):
    out = tmp_path / "v"
    procs = [_commission(*_validate_argv(tuned, out), cwd=tmp_path) for _ in range(2)]
    res = [(p.wait(timeout=300), *p.communicate()) for p in procs]
    codes = sorted(r[0] for r in res)
    assert codes[0] in (0, 1) and codes[1] == 2, res
    loser = next(r for r in res if r[0] == 2)
    assert re.fullmatch(r"error: --out-dir \S+: in use by another commission process \(pid \d+, commission "
                        r"validate .*, since .*\); wait for it or choose another output\n", loser[2]), loser[2]
    assert "validation.json" in _names(out) and "report.md" in _names(out)
    _no_leftovers(tmp_path)


@pytest.mark.parametrize("sig", [signal.SIGTERM, signal.SIGINT])
def test_a_signal_at_any_moment_leaves_nothing_or_a_complete_set(tuned, tmp_path, sig):
    ref = tmp_path / "ref"
    p = _commission(*_validate_argv(tuned, ref), cwd=tmp_path)
    t0 = time.perf_counter()
    p.communicate(timeout=300)
    took = time.perf_counter() - t0
    full = _names(ref)
    assert {"validation.json", "report.md"} <= set(full)
    for k, frac in enumerate((0.1, 0.4, 0.7, 0.95)):
        existing = bool(k % 2)
        if True:
            out = tmp_path / f"v{k}{int(existing)}"
            if existing:  # an earlier complete set that must survive or be wholly replaced
                out.mkdir()
                for n in full:
                    (out / n).write_bytes((ref / n).read_bytes())
            before = listing(out) if existing else None
            p = _commission(*_validate_argv(tuned, out), cwd=tmp_path)
            time.sleep(frac * took)
            p.send_signal(sig)
            _, err = p.communicate(timeout=300)
            assert "Traceback" not in err, err
            # Never -sig: a signal while the interpreter shuts down cannot kill it with the set in place.
            assert p.returncode in (0, 1, 128 + sig), (p.returncode, err)
            names = _names(out)
            assert names in ([], full) if not existing else names == full, (frac, names)
            if p.returncode in (0, 1):  # finished: the new set is in place
                assert names == full and (not existing or listing(out) != before), (frac, p.returncode)
            else:  # 130/143: nothing written or replaced
                assert (listing(out) == before) if existing else names == [], (frac, p.returncode, err)
                assert err.strip().splitlines()[-1].endswith(": no output written or replaced"), err
            _no_leftovers(tmp_path)
            _no_leftovers(out) if out.exists() else None


def test_a_full_disk_under_validate_is_one_line_and_leaves_everything_as_it_was(tuned, tmp_path, monkeypatch):
    import errno

    import commission.validate.outputs as validate

    out = tmp_path / "v"
    out.mkdir()
    (out / "report.md").write_text("the old report\n")
    before = listing(out)

    def full(path, text):  # the report half-written, then the disk is full
        Path(path).write_text(text[: len(text) // 2])
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))

    monkeypatch.setattr(validate, "write_text_atomic", full)
    r = invoke(*_validate_argv(tuned, out))
    assert r.exit_code == 2, r.output
    assert re.fullmatch(r"error: --out-dir \S+/v: cannot write \(No space left on device\); nothing written or "
                        r"replaced", r.stderr.strip().splitlines()[-1]), r.stderr  # after the progress bar
    assert "Traceback" not in r.output
    assert listing(out) == before
    _no_leftovers(tmp_path)


# --------------------------------------------------------------------------- must-show 3


def _loose(tmp_path):
    g = tmp_path / "loose.toml"
    g.write_text(LOOSE_GATE)
    return g


def test_a_loose_gate_still_emits_a_sound_controller(tuned, tmp_path):
    out = tmp_path / "v"
    r = invoke("validate", tuned, "--out-dir", out, "--gate", _loose(tmp_path), "--monte-carlo", 1)
    assert r.exit_code == 0, r.output
    assert (out / "controller.json").exists()


@pytest.mark.parametrize("how", ["u_max_null", "caps_null", "gains_x10"])
def test_a_gate_that_switches_off_a_floor_emits_no_controller(tuned, tmp_path, how):
    doc = read_json(tuned)
    if how == "u_max_null":
        doc["arc"]["u_max"] = None
    elif how == "caps_null":
        doc["arc"]["k1s_max"] = None
        doc["arc"]["k2s_max"] = None
    else:  # limit-cycles at the input limit: sits at the rail
        for k in ("g1", "g2", "k1s_max", "k2s_max"):
            doc["arc"][k] *= 10.0
    bad = tmp_path / "tuning.json"
    write_json_atomic(bad, doc)
    out = tmp_path / "v"
    r = invoke("validate", bad, "--out-dir", out, "--gate", _loose(tmp_path), "--monte-carlo", 1)
    assert r.exit_code == 1, r.output
    assert (out / "report.md").exists() and not (out / "controller.json").exists()
    assert "floor:" in (out / "report.md").read_text()
    failures = read_json(out / "validation.json")["failures"]
    # The loose gate file's own criteria all pass: what refuses is a floor (and, where the loop
    # itself is broken, the spec's stability-margin floors, which gate.toml cannot set either).
    assert any(c["criterion"].startswith("floor:") for c in failures)
    if how == "u_max_null":  # without caps, or with x10 gains, the loop may diverge: the gate's indexes fail too
        assert all(c["criterion"].startswith("floor:") or c["criterion"] in ("margins", "margins_box")
                   for c in failures), failures


@pytest.fixture(scope="module")
def config(tuned):
    from commission.tuning import Tuning
    from commission.validate import deployable_gains

    t = Tuning.load(str(tuned))
    return ControllerConfig(gains=deployable_gains(t.arc), sample_rate=t.spec.sample_rate, units={"u": "V", "q": "m"},
                            validated={}, provenance=ControllerProvenance(None, "1" * 64, "2" * 64, "t", "now"))


def _rehash(doc):
    import hashlib

    body = {k: v for k, v in doc.items() if k != "checksum"}
    text = json.dumps(body, sort_keys=True, indent=2) + "\n"
    doc["checksum"] = {"algorithm": "sha256", "value": hashlib.sha256(text.encode()).hexdigest()}
    return doc


@pytest.mark.parametrize("field", ["u_max", "k1s_max", "k2s_max"])
@pytest.mark.parametrize("value", [None, "Infinity", "NaN", -1.0])
def test_load_controller_refuses_null_or_non_finite_limits(config, tmp_path, field, value):
    doc = _rehash(_set(copy.deepcopy(config.to_dict()), field, value))
    p = tmp_path / "controller.json"
    text = json.dumps(doc).replace('"Infinity"', "Infinity").replace('"NaN"', "NaN")
    p.write_text(text)
    with pytest.raises(SchemaError, match=rf"\$\.bounds\.{field}: "):
        load_controller(p)


def _set(doc, field, value):
    doc["bounds"][field] = value
    return doc


def test_signed_controller_is_verified_and_unsigned_or_resigned_files_are_refused(config, tmp_path):
    key, other = b"k" * 32, b"o" * 32
    signed = tmp_path / "signed.json"
    write_json_atomic(signed, config.to_dict(sign_key=key))
    unsigned = tmp_path / "unsigned.json"
    write_json_atomic(unsigned, config.to_dict())
    resigned = tmp_path / "resigned.json"
    write_json_atomic(resigned, config.to_dict(sign_key=other))
    assert load_controller(signed, key=key).config.gains == config.gains
    assert load_controller(signed).config.gains == config.gains  # no key: the checksum only
    with pytest.raises(SchemaError, match=r"\$\.signature: missing: the file is not signed"):
        load_controller(unsigned, key=key)
    with pytest.raises(SchemaError, match=r"\$\.signature: does not match the signing key"):
        load_controller(resigned, key=key)
    # an edit with a recomputed checksum passes the checksum but not the signature
    doc = read_json(signed)
    doc["bounds"]["u_max"] = 1e3
    edited = tmp_path / "edited.json"
    edited.write_text(json.dumps(_rehash(doc)))
    assert load_controller(edited).config.gains.u_max == 1e3  # what the plain checksum cannot catch
    with pytest.raises(SchemaError, match=r"\$\.signature: does not match"):
        load_controller(edited, key=key)


def test_validate_signs_with_a_key_file_or_the_environment(tuned, tmp_path, monkeypatch):
    keyfile = tmp_path / "site.key"
    keyfile.write_text("0123456789abcdef0123456789abcdef\n")
    gate = _loose(tmp_path)
    r = invoke("validate", tuned, "--out-dir", tmp_path / "a", "--gate", gate, "--monte-carlo", 0,
               "--sign-key", keyfile)
    assert r.exit_code == 0, r.output
    key = b"0123456789abcdef0123456789abcdef"
    load_controller(tmp_path / "a" / "controller.json", key=key)
    monkeypatch.setenv("COMMISSION_SIGN_KEY", str(keyfile))
    r = invoke("validate", tuned, "--out-dir", tmp_path / "b", "--gate", gate, "--monte-carlo", 0)
    assert r.exit_code == 0, r.output
    load_controller(tmp_path / "b" / "controller.json", key=key)
    short = tmp_path / "short.key"
    short.write_text("abc")
    refused(invoke("validate", tuned, "--out-dir", tmp_path / "c", "--sign-key", short),
            r"--sign-key .*short\.key: the key has 3 bytes")
    assert not (tmp_path / "c").exists()


def test_validate_checks_the_provenance_chain(tmp_path):
    from commission.jsonio import sha256_file

    doc = copy.deepcopy(TUNING_DOC)
    ipath = tmp_path / "ident.json"
    write_json_atomic(ipath, doc["identification"])  # the identification this tuning was made from
    doc["provenance"].update(ident_path=str(ipath), ident_sha256=sha256_file(ipath))
    tpath = tmp_path / "tuning.json"
    write_json_atomic(tpath, doc)
    r = invoke("validate", tpath, "--out-dir", tmp_path / "ok", "--gate", _loose(tmp_path), "--monte-carlo", 0)
    assert r.exit_code == 0, r.output
    ctrl = read_json(tmp_path / "ok" / "controller.json")
    assert ctrl["provenance"]["tuning_sha256"] == sha256_file(tpath)
    assert ctrl["provenance"]["ident_sha256"] == sha256_file(ipath)
    # tuning.json edited: the disturbance validate sizes from it no longer the identified one
    doc = read_json(tpath)
    doc["identification"]["delta_d"] *= 0.1
    edited = tmp_path / "edited.json"
    write_json_atomic(edited, doc)
    refused(invoke("validate", edited, "--out-dir", tmp_path / "e"), r"\$\.identification: differs from .*ident\.json")
    # ident.json replaced since the tuning
    doc = read_json(ipath)
    doc["delta_d"] = 0.6
    write_json_atomic(ipath, doc)
    refused(invoke("validate", tpath, "--out-dir", tmp_path / "f"), r"\$\.provenance\.ident_sha256: .* is not the sha256")
    assert not (tmp_path / "e").exists() and not (tmp_path / "f").exists()
