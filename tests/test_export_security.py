"""``commission export`` as an attacker would try it (issue 29): injection, signatures, partial outputs.

* **Injection.** Every string of controller.json that could reach a generated
  file -- ``units.u``, ``units.q``, each ``provenance`` field, free-form text in
  ``validated`` -- is set to hostile text (comment ends and starts of both
  languages, trigraphs, line breaks, directives, NUL, backslashes, non-ASCII,
  very long).  The property: either the export refuses it, naming its JSON
  path, or every generated file is *exactly* the file of a harmless
  controller with the escaped text in place of a harmless word, and the
  escaped text is a single line of :data:`commission.export.text.ESCAPED`
  characters.  The hostile configs are built as dataclasses and rendered
  directly, so the test reaches the export's own rendering whatever its loader
  refuses (defence in depth); the end-to-end tests then plant them in a
  controller.json whose checksum the attacker recomputed, compile the C with
  ``-Wall -Wextra -Werror -pedantic``, replay it, and parse the ST with blark.
* **Signatures.** ``--sign-key`` / ``COMMISSION_SIGN_KEY`` / ``--require-signature``.
* **Outputs.** A full disk, Ctrl-C, a held lock, a dangling symlink: exit 2 (or
  the interrupt), nothing written, no staging folder or lock left.
"""

from __future__ import annotations

import dataclasses
import errno
import json
import math
import signal
import subprocess
import time
from pathlib import Path

import pytest

import commission.units as units_mod
from hypothesis import HealthCheck, example, given, settings
from hypothesis import strategies as st
from typer.testing import CliRunner

import commission.export as export_mod
from commission.cli.main import app
from commission.controller_config import SIGN_KEY_ENV, ControllerConfig, ControllerProvenance
from commission.controllers import arc as A
from commission.controllers import pid as P
from commission.errors import SchemaError
from commission.export import export_c, output_names, render
from commission.export.build import build_replay, find_cc
from commission.export.text import ESCAPED, SAFE, c_comment, markdown_code, st_comment
from commission.infra.files import Outputs
from commission.gate import GateSpec, resolve_gate
from commission.jsonio import sha256_json, write_json_atomic
from commission.paper import reference_identification
from commission.spec import default_spec
from commission.tune.baseline import pid_baseline
from commission.tune.gains import base_arc_gains
from commission.validate import deployable_gains, guard_values

needs_cc = pytest.mark.skipif(find_cc() is None, reason="no C compiler (cc) on the PATH: the C export cannot be built")
runner = CliRunner()
LSB = 1e-6

#: The unit of issue 29: compiles cleanly, runs before main and leaves the replay bit-exact, if copied raw.
INJECTION = ('V */ extern int puts(const char *); static void __attribute__((constructor)) x(void)'
             '{puts("INJECTED");} /*')
#: The nastiest strings, one per hazard (and all of them at once).
NASTY = [
    INJECTION,
    "V */\n#define double int\n#error injected\n/*",
    "V ??/\n#error trigraph splice\n??= *) (* x := 1; (* // \\\n\\",
    "V\x00\x01\x1b[2J\r\n\u2028\u0085 \u00b7\u00b5\ufeff\U0001f600 \ud800 `x` <b>&amp; $N '\"",
    "V *) END_FUNCTION_BLOCK FUNCTION_BLOCK Evil (* " * 200,
]
NASTY.append("".join(NASTY[:4]))
#: Fragments hypothesis combines with arbitrary text.
FRAGMENTS = ["*/", "/*", "(*", "*)", "//", "??/", "??=", "??", "\n", "\r", "#define X 1", "#error x", "#include <x>",
             "\x00", "\\", "\\\n", "\"", "'", "`", "$", "%:", "<%", "\u00b7", "\u2028", "\ud800", "*", "/", "?"]
hostile = st.one_of(
    st.sampled_from(NASTY),
    st.lists(st.one_of(st.sampled_from(FRAGMENTS), st.text(max_size=8)), min_size=1, max_size=12).map("".join),
    st.text(min_size=0, max_size=300),
)
#: A harmless unit found nowhere else in the generated files: its escaped form is itself.
MARK = "Qunitmark"
PROVENANCE = ("tuning_sha256", "ident_sha256", "log_sha256", "tool_version", "created_utc")


@pytest.fixture(scope="module")
def base():
    spec = default_spec()
    ident = reference_identification(delta_d=0.5)
    raw = base_arc_gains(ident, spec)
    limits = resolve_gate(GateSpec(), lsb=LSB, travel=spec.travel, u_max=spec.u_max)
    g = deployable_gains(raw, guard_values(raw.Ts, LSB, spec.v_max, spec.travel, limits.e_M))
    prov = ControllerProvenance("a" * 64, "b" * 64, "c" * 64, "0.1.0", "2001-06-01T00:00:00Z")
    config = ControllerConfig(gains=g, sample_rate=1.0 / g.Ts, units={"u": MARK, "q": "m"},
                              validated={"simulation": {"quantization": LSB}}, provenance=prov)
    packs = {"arc": A.arc_pack(g), "pid": P.pid_pack(pid_baseline(ident, spec)[0])}
    # The files the CLI loads carry a unit of the vocabulary load_controller accepts; the rendering
    # tests use MARK to find where the unit lands.
    file_config = dataclasses.replace(config, units={"u": "V", "q": "m"})
    return dict(config=config, file_config=file_config, packs=packs, checksum=_checksum(config))


def _render(base, config, kind, target):
    return render(kind, base["packs"][kind], config, None, "d" * 64, target=target)


def _with(config, field, value):
    """``config`` with the string ``field`` (a JSON path below $) set to ``value``."""
    section, name = field.split(".")
    if section == "units":
        return dataclasses.replace(config, units={**config.units, name: value})
    if section == "provenance":
        return dataclasses.replace(config, provenance=dataclasses.replace(config.provenance, **{name: value}))
    assert section == "validated"
    return dataclasses.replace(config, validated={**config.validated, name: value,
                                                  "simulation": {"quantization": value}})


def _checksum(config):
    return config.to_dict()["checksum"]["value"]


def _expected(base, files, unit, checksum):
    """The harmless files with the escaped ``unit`` in place of :data:`MARK`, each in its language, and
    the hostile controller's checksum in place of the harmless one's (the one other line that differs)."""
    out = {}
    for name, text in files.items():
        text = text.replace(base["checksum"], checksum)
        if name.endswith(".st"):
            out[name] = text.replace(MARK, st_comment(unit))
        elif name == "README.md":
            out[name] = text.replace(f"`{MARK}`", markdown_code(unit))
        else:
            out[name] = text.replace(MARK, c_comment(unit))
    return out


def _assert_escaped(text):
    assert set(text) <= ESCAPED and "\n" not in text
    for hazard in ("*/", "/*", "(*", "*)", "//", "??", "\\", "#"):
        assert hazard not in text


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(value=hostile, field=st.sampled_from(["units.u", "units.q", "validated.note",
                                             *(f"provenance.{n}" for n in PROVENANCE)]),
       kind=st.sampled_from(["arc", "pid"]), target=st.sampled_from(["c", "st"]))
@example(value="", field="units.q", kind="arc", target="c")  # an empty unit: the README shows the default's
def test_no_hostile_string_leaves_its_comment(base, value, field, kind, target):
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(export_mod, "VECTOR_STEPS", 60)  # the vectors carry no text; keep each example quick
        harmless = _render(base, base["config"], kind, target)
        try:
            files = _render(base, _with(base["config"], field, value), kind, target)
        except SchemaError as exc:
            # only a fixed-form field may be refused, and the message names it (one line, value escaped)
            assert field.startswith("provenance.") and f"$.provenance.{field.split('.')[1]}" in str(exc)
            assert "\n" not in str(exc) and "*/" not in str(exc)
            return
    if field.startswith("provenance."):  # accepted: then it had the field's form, a short token of safe text
        assert set(value) <= SAFE and " " not in value and len(value) <= 64
        return
    assert sorted(files) == sorted(harmless) == sorted(output_names(kind, target))
    hostile_config = _with(base["config"], field, value)
    if field == "units.u":
        _assert_escaped(c_comment(value))
        _assert_escaped(st_comment(value))
        _assert_escaped(markdown_code(value)[1:-1])
        assert files == _expected(base, harmless, value, _checksum(hostile_config))
    elif field == "units.q":  # the position unit reaches the README only, as escaped code spans
        _assert_escaped(markdown_code(value)[1:-1])
        expected = _expected(base, harmless, MARK, _checksum(hostile_config))
        # the README words q's unit as commission.units does (an empty unit is the default's)
        shown = units_mod.unit("q", {"u": MARK, "q": value})
        expected["README.md"] = expected.get("README.md", "").replace("`m`", markdown_code(shown))
        assert {n: t for n, t in files.items()} == {n: t for n, t in expected.items() if n in files}
    else:  # free-form validated text reaches no generated file (but the checksum line)
        assert files == _expected(base, harmless, MARK, _checksum(hostile_config))


def test_escaping_is_per_character_and_bounded():
    assert c_comment("V/(m*s)") == "V{U+002F}(m{U+002A}s)"
    assert c_comment("\u00b5m \U0001f600") == "{U+00B5}m {U+1F600}"
    assert st_comment("*)") == "{U+002A})" and markdown_code("a`b") == "`a{U+0060}b`"
    long = c_comment("A" * 10_000)
    assert long.startswith("A" * 80) and long.endswith("{+9920 more characters}") and len(long) < 120


@pytest.mark.parametrize("field,value", [("tuning_sha256", "A" * 64), ("ident_sha256", "a" * 63),
                                         ("log_sha256", "a" * 64 + "\n"), ("created_utc", "now"),
                                         ("created_utc", "2001-06-01T00:00:00Z */"),
                                         ("tool_version", "0.1.0 */ #error"), ("tool_version", "\u0661.0")])
def test_a_provenance_field_not_of_its_form_is_refused_naming_its_path(base, field, value):
    with pytest.raises(SchemaError, match=rf"\$\.provenance\.{field}: expected"):
        _render(base, _with(base["config"], f"provenance.{field}", value), "arc", "st")


# --------------------------------------------------------------------------- compiled and parsed


def _write(files, d):
    d.mkdir(parents=True, exist_ok=True)
    for name, text in files.items():
        (d / name).write_text(text, encoding="utf-8")


@needs_cc
@pytest.mark.parametrize("i", range(len(NASTY)))
def test_hostile_unit_compiles_with_werror_and_replays_bit_exact(base, tmp_path, i):
    """Rendered directly (whatever the loader accepts): -Werror -pedantic builds, the replay is exact
    and prints nothing injected, and the files are the harmless ones with the unit escaped."""
    cfg = _with(base["config"], "units.u", NASTY[i])
    files = _render(base, cfg, "arc", "c")
    assert files == _expected(base, _render(base, base["config"], "arc", "c"), NASTY[i], _checksum(cfg))
    _write(files, tmp_path / "c")
    exe = build_replay(tmp_path / "c", "arc", tmp_path / "replay")  # -std=c99 -Wall -Wextra -Werror -pedantic
    r = subprocess.run([str(exe), str(tmp_path / "c" / "test_vectors.csv")], capture_output=True, text=True)
    assert r.returncode == 0 and " max_abs_diff 0 unequal 0 fault_mismatch 0" in r.stdout, r.stdout + r.stderr
    assert "INJECTED" not in r.stdout + r.stderr


def _attacker_file(config, path, unit, key=None):
    """controller.json with ``unit``, its checksum recomputed (and signed with ``key``, if given)."""
    doc = dataclasses.replace(config, units={**config.units, "u": unit}).to_dict(sign_key=key)
    write_json_atomic(path, doc)
    return path


@needs_cc
@pytest.mark.parametrize("unit", [INJECTION, NASTY[-1]])
def test_hostile_unit_through_the_cli_is_refused_or_harmless(base, tmp_path, unit):
    """End to end: a loader that refuses the unit must name $.units.u and write nothing; one that accepts
    it must yield files that build with -Werror, replay exactly and contain the unit only escaped."""
    path = _attacker_file(base["config"], tmp_path / "controller.json", unit)
    out = tmp_path / "out"
    r = runner.invoke(app, ["export", str(path), "--out-dir", str(out)])
    if r.exit_code == 2:
        assert "$.units.u" in r.output and not out.exists()
        return
    assert r.exit_code == 0, r.output
    for name in output_names("arc"):
        text = (out / name).read_text(encoding="utf-8")
        assert unit not in text and "INJECTED" not in text
    assert c_comment(unit) in (out / "commission_arc_params.c").read_text()
    exe = build_replay(out, "arc", tmp_path / "replay")
    rr = subprocess.run([str(exe), str(out / "test_vectors.csv")], capture_output=True, text=True)
    assert rr.returncode == 0 and "INJECTED" not in rr.stdout + rr.stderr


@pytest.mark.slow  # blark builds its lark grammar on first use
@pytest.mark.parametrize("kind", ["arc", "pid"])
def test_hostile_unit_in_structured_text_parses_as_one_comment(base, kind):
    blark = pytest.importorskip("blark", reason="blark (the ST parser) is not installed")
    unit = "".join(NASTY)
    src = _render(base, _with(base["config"], "units.u", unit), kind, "st")
    (name, text), = src.items()
    harmless = _render(base, base["config"], kind, "st")
    assert src == _expected(base, harmless, unit, _checksum(_with(base["config"], "units.u", unit)))
    harmless = harmless[name]
    res = blark.parse_source_code(text)
    assert res.exception is None, res.exception
    assert text.count("FUNCTION_BLOCK ") == harmless.count("FUNCTION_BLOCK ")


# --------------------------------------------------------------------------- signatures

KEY, OTHER = b"k" * 32, b"o" * 32


@pytest.fixture()
def keys(tmp_path):
    k, o = tmp_path / "site.key", tmp_path / "other.key"
    k.write_bytes(KEY + b"\n")
    o.write_bytes(OTHER)
    return k, o


def _rehash(doc):
    """What an attacker without the key does after an edit: recompute the (unkeyed) checksum."""
    doc["checksum"]["value"] = sha256_json({k: v for k, v in doc.items() if k != "checksum"})
    return doc


def _signed_variants(config, d):
    d.mkdir(exist_ok=True)
    good = config.to_dict(sign_key=KEY)
    edited = json.loads(json.dumps(good))
    edited["bounds"]["u_max"] *= 10
    edited = _rehash(edited)
    unsigned = json.loads(json.dumps(good))
    del unsigned["signature"]
    unsigned = _rehash(unsigned)
    paths = {}
    for name, doc in (("good", good), ("edited", edited), ("unsigned", unsigned),
                      ("other", config.to_dict(sign_key=OTHER))):
        paths[name] = d / f"{name}.json"
        write_json_atomic(paths[name], doc)
    return paths


def _export(path, out, *extra, env=None):
    return runner.invoke(app, ["export", str(path), "--target", "st", "--out-dir", str(out), *extra], env=env)


@pytest.mark.parametrize("case", ["edited", "unsigned", "other"])
def test_export_with_the_key_refuses_a_tampered_unsigned_or_foreign_file(base, tmp_path, keys, case):
    """Must-show 3: signed, then u_max edited (checksum recomputed) -> exit 2, nothing written."""
    paths = _signed_variants(base["file_config"], tmp_path / "in")
    out = tmp_path / "out"
    r = _export(paths[case], out, "--sign-key", str(keys[0]))
    assert r.exit_code == 2 and r.output.startswith("error: ") and len(r.output.strip().splitlines()) == 1
    assert "$.signature" in r.output and not out.exists()
    assert not [p for p in tmp_path.iterdir() if p.name.startswith(".out")]  # no lock, no staging folder
    r = _export(paths["good"], out, "--sign-key", str(keys[0]))
    assert r.exit_code == 0, r.output
    assert sorted(p.name for p in out.iterdir()) == list(output_names("arc", "st"))


def test_the_key_from_the_environment_is_used(base, tmp_path, keys):
    paths = _signed_variants(base["file_config"], tmp_path / "in")
    env = {SIGN_KEY_ENV: str(keys[0])}
    r = _export(paths["edited"], tmp_path / "a", env=env)
    assert r.exit_code == 2 and "$.signature" in r.output and not (tmp_path / "a").exists()
    r = _export(paths["good"], tmp_path / "b", "--require-signature", env=env)
    assert r.exit_code == 0, r.output
    r = _export(paths["good"], tmp_path / "c", env={SIGN_KEY_ENV: str(keys[1])})  # the wrong site key
    assert r.exit_code == 2 and not (tmp_path / "c").exists()


def test_require_signature_refuses_without_a_key_and_unsigned_files(base, tmp_path, keys):
    paths = _signed_variants(base["file_config"], tmp_path / "in")
    r = _export(paths["good"], tmp_path / "a", "--require-signature", env={SIGN_KEY_ENV: ""})
    assert r.exit_code == 2 and "--sign-key" in r.output and not (tmp_path / "a").exists()
    r = _export(paths["unsigned"], tmp_path / "a", "--require-signature", "--sign-key", str(keys[0]))
    assert r.exit_code == 2 and "not signed" in r.output and not (tmp_path / "a").exists()
    r = _export(paths["unsigned"], tmp_path / "a", env={SIGN_KEY_ENV: ""})  # no key, no requirement: checksum only
    assert r.exit_code == 0, r.output


# --------------------------------------------------------------------------- outputs


@pytest.fixture()
def controller(base, tmp_path):
    path = tmp_path / "controller.json"
    write_json_atomic(path, base["file_config"].to_dict())
    return path


def _leftovers(folder):
    return sorted(p.name for p in folder.iterdir() if p.name.startswith("."))


@pytest.mark.parametrize("existing", [False, True])
def test_a_full_disk_leaves_nothing_and_no_staging_folder(controller, tmp_path, monkeypatch, existing):
    out = tmp_path / "out"
    if existing:  # an earlier export: it must survive a failed --force export unchanged
        assert runner.invoke(app, ["export", str(controller), "--out-dir", str(out)]).exit_code == 0
    before = {p.name: p.read_bytes() for p in out.iterdir()} if existing else None
    real, calls = export_mod.write_text_atomic, []

    def full_disk(path, text):
        calls.append(path)
        if len(calls) == 3:
            raise OSError(errno.ENOSPC, "No space left on device")
        real(path, text)

    monkeypatch.setattr(export_mod, "write_text_atomic", full_disk)
    r = runner.invoke(app, ["export", str(controller), "--out-dir", str(out), "--force"])
    assert len(calls) == 3  # two files were staged before the disk filled
    assert r.exit_code == 2 and "No space left on device" in r.output and len(r.output.strip().splitlines()) == 1
    assert "nothing was written" in r.output
    assert _leftovers(tmp_path) == []
    if existing:
        assert {p.name: p.read_bytes() for p in out.iterdir()} == before
    else:
        assert not out.exists()


def test_an_interrupt_while_writing_leaves_nothing(controller, tmp_path, monkeypatch):
    real, calls = export_mod.write_text_atomic, []

    def interrupted(path, text):
        calls.append(path)
        if len(calls) == 4:
            raise KeyboardInterrupt
        real(path, text)

    monkeypatch.setattr(export_mod, "write_text_atomic", interrupted)
    with pytest.raises(KeyboardInterrupt):
        export_c(controller, tmp_path / "out")
    assert len(calls) == 4 and not (tmp_path / "out").exists() and _leftovers(tmp_path) == []


def test_a_second_export_into_a_locked_folder_is_refused_naming_the_holder(controller, tmp_path):
    out = tmp_path / "out"
    holder = Outputs(force=False)
    holder.add_dir(out, output_names("arc", "st"), "--out-dir")
    holder.open()
    try:
        r = runner.invoke(app, ["export", str(controller), "--target", "st", "--out-dir", str(out)])
        assert r.exit_code == 2 and "in use by another commission process (pid " in r.output
        assert not out.exists()
    finally:
        holder.abort()
    r = runner.invoke(app, ["export", str(controller), "--target", "st", "--out-dir", str(out)])
    assert r.exit_code == 0, r.output
    assert _leftovers(tmp_path) == []


def test_a_dangling_symlink_as_out_dir_is_a_named_refusal(controller, tmp_path):
    link = tmp_path / "link"
    link.symlink_to(tmp_path / "nowhere")
    r = runner.invoke(app, ["export", str(controller), "--target", "st", "--out-dir", str(link)])
    assert r.exit_code == 2 and r.output.startswith("error: --out-dir ") and "symlink" in r.output
    assert r.exception is None or isinstance(r.exception, SystemExit)
    assert not (tmp_path / "nowhere").exists() and link.is_symlink() and _leftovers(tmp_path) == []


def test_the_controller_file_cannot_be_an_output(controller, tmp_path):
    out = tmp_path / "out"
    out.mkdir()
    (out / "FB_CommissionArc.st").symlink_to(controller)
    r = runner.invoke(app, ["export", str(controller), "--target", "st", "--out-dir", str(out), "--force"])
    assert r.exit_code == 2 and "is also an input" in r.output
    assert json.loads(controller.read_text())["kind"] == "controller"


def test_the_export_escapes_the_unit_in_every_file_it_names(base):
    """Sanity of the property's premise: the harmless mark is where the unit goes, in each language."""
    files = _render(base, base["config"], "arc", "c")
    assert f"command in {MARK}." in files["commission_arc_params.c"]
    assert f"command in `{MARK}`." in files["README.md"]
    assert sum(MARK in t for t in files.values()) == 2
    st_text = _render(base, base["config"], "arc", "st")["FB_CommissionArc.st"]
    assert f"command in {MARK}." in st_text


def _commission(*args, cwd):
    """The installed console script (as a user runs it), else the same entry point through python."""
    import sys

    script = Path(sys.executable).parent / "commission"
    head = [str(script)] if script.is_file() else [
        sys.executable, "-c", "import sys; sys.argv[0] = 'commission'; from commission.cli.main import main; main()"]
    return subprocess.Popen([*head, *map(str, args)], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            cwd=cwd)


@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM])
def test_a_signal_during_an_export_leaves_nothing_or_the_whole_set(controller, tmp_path, sig):
    """Issue 29 found 3 of 6 files after a Ctrl-C: now the folder is empty (exit 128 + sig) or complete."""
    took = math.inf
    for k in range(2):  # the faster of two (the first may pay cold caches: its signals would all land late)
        t0 = time.perf_counter()
        p = _commission("export", controller, "--out-dir", tmp_path / f"ref{k}", cwd=tmp_path)
        assert p.wait(timeout=300) == 0, p.communicate()
        took = min(took, time.perf_counter() - t0)
    full = sorted(output_names("arc"))
    codes = []
    for k, frac in enumerate((0.3, 0.6, 0.9)):
        out = tmp_path / f"out{k}"
        p = _commission("export", controller, "--out-dir", out, cwd=tmp_path)
        time.sleep(frac * took)
        p.send_signal(sig)
        _, err = p.communicate(timeout=300)
        assert "Traceback" not in err, err
        names = sorted(q.name for q in out.iterdir()) if out.exists() else []
        assert p.returncode in (0, 128 + sig, -sig), (p.returncode, err)
        # 0 or -sig (the signal came as the interpreter shut down after the move): the set is in place
        assert names == full if p.returncode in (0, -sig) else names in ([], full), (frac, p.returncode, names)
        codes.append(p.returncode)
        assert [q.name for q in tmp_path.iterdir() if ".tmp-" in q.name or q.name.endswith(".lock")] == []
    assert 128 + sig in codes, codes  # at least one signal landed while the export ran


def test_the_key_file_cannot_be_an_output(base, tmp_path):
    """A key file named like an output (README.md) in --out-dir is never overwritten, even with --force."""
    out = tmp_path / "out"
    out.mkdir()
    key = out / "README.md"
    key.write_bytes(KEY)
    path = tmp_path / "signed.json"
    write_json_atomic(path, base["file_config"].to_dict(sign_key=KEY))
    for extra, env in ((["--sign-key", str(key)], None), ([], {SIGN_KEY_ENV: str(key)})):
        r = runner.invoke(app, ["export", str(path), "--out-dir", str(out), "--force", *extra], env=env)
        assert r.exit_code == 2 and "is also an input" in r.output and key.read_bytes() == KEY
