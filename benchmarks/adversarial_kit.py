"""The adversarial kit: bad, hostile and interrupted inputs to every command, counted.

Run from the repository root with the tool installed::

    python benchmarks/adversarial_kit.py [--base DIR] [--only SUBSTRING] [--jobs N]

It first makes (or reuses, ``--base``) one good set of artifacts from the sample
(``commission run sample_data/axis_excitation.h5``), then runs each case as a user
or an attacker would -- a ``commission`` process on a damaged log, an edited
``ident.json``/``tuning.json``/``controller.json`` (checksums recomputed, as anyone
can), a forged or stripped signature, a hostile unit string, a signal at a chosen
moment, a full disk (a 64 KiB tmpfs, when run as root), a symlinked output folder
-- and classifies what happened:

traceback
    a Python traceback or "internal error" on stderr instead of a named refusal;
exit0-on-bad
    a case that must be refused (exit 2) exited 0;
partial
    after a refusal or a signal, an output of the command, a staging folder
    (``.*.tmp-*``) or a lock file is left where nothing was before;
data-loss
    a file that was in the output location before a refused run was changed or removed;
injection
    a generated file holds a hostile string verbatim (escaped text is harmless), or the
    exported C does not compile with ``-Werror``, or its replay prints the marker;
hang
    no answer within the case's time limit.

It prints one line per case and the totals; exit status 1 when any case is in a
failure class.  Cases run in parallel (``--jobs``, default 2): each in its own folder.
"""

from __future__ import annotations

import argparse
import concurrent.futures as cf
import copy
import hashlib
import hmac
import json
import os
import shutil
import signal
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable

ROOT = Path(__file__).resolve().parents[1]
SAMPLE = ROOT / "sample_data" / "axis_excitation.h5"
MARKER = "INJECTED"
HOSTILE_UNIT = ('V */ extern int puts(const char *); static void __attribute__((constructor)) x(void)'
                '{puts("' + MARKER + '");} /*')
HOSTILE_STRINGS = {
    "c-comment": HOSTILE_UNIT,
    "st-comment": "V *) " + MARKER + " (* ",
    "newline-define": "V\n#define " + MARKER + " 1\n#error " + MARKER,
    "trigraph": "V ??/\nint " + MARKER + ";",
    "nul": "V\x00" + MARKER,
}
FAILURES = ("traceback", "exit0-on-bad", "partial", "data-loss", "injection", "hang")


def commission_cmd() -> list[str]:
    script = Path(sys.executable).parent / "commission"
    if script.is_file():
        return [str(script)]
    return [sys.executable, "-c", "import sys; sys.argv[0]='commission'; from commission.cli.main import main; main()"]


# ------------------------------------------------------------------------------------ attacker's tools
def canonical(doc) -> str:
    return json.dumps(doc, sort_keys=True, indent=2, allow_nan=False) + "\n"


def reseal(doc: dict, key: bytes | None = None) -> dict:
    """Recompute controller.json's checksum (and signature under ``key``), as anyone can."""
    doc = {k: v for k, v in doc.items() if k not in ("checksum", "signature")}
    if key is not None:
        doc["signature"] = {"algorithm": "hmac-sha256",
                            "value": hmac.new(key, canonical(doc).encode(), hashlib.sha256).hexdigest()}
    doc["checksum"] = {"algorithm": "sha256", "value": hashlib.sha256(canonical(doc).encode()).hexdigest()}
    return doc


def write_json(path: Path, doc) -> None:
    path.write_text(json.dumps(doc, indent=2, sort_keys=True))


# ------------------------------------------------------------------------------------ cases
@dataclass
class Case:
    """One adversarial run: ``setup(work)`` prepares the folder and returns the argv (after ``commission``)."""

    name: str
    setup: Callable[[Path], list[str]]
    expect: str = "refuse"            # "refuse" (exit 2), "ok" (exit 0), "either" (0/1/2, nothing else)
    out: str = "out"                  # the output location (file or folder) relative to the work folder
    env: dict = field(default_factory=dict)
    interrupt_after: float | None = None  # seconds, then SIGINT
    timeout: float = 180.0
    compile_c: bool = False           # compile and run the exported C replay
    payload: str | None = None        # a hostile string: it must never appear verbatim in an output
    needs_root: bool = False


def _copy(base: Path, work: Path, *names: str) -> None:
    for n in names:
        shutil.copy(base / n, work / n)


def json_case(name: str, artifact: str, command: list[str], mutate: Callable[[dict], object],
              reseal_key: bytes | None | str = "none", raw: Callable[[str], str] | None = None, **kw) -> Case:
    """A case that edits one artifact (``mutate`` changes the parsed document in place; ``raw`` edits its text)."""

    def setup(work: Path) -> list[str]:
        _copy(BASE, work, "ident.json", "tuning.json", "controller.json")
        p = work / artifact
        doc = json.loads(p.read_text())
        mutate(doc)
        if reseal_key != "none":
            doc = reseal(doc, reseal_key if isinstance(reseal_key, bytes) else None)
        text = json.dumps(doc, indent=2, sort_keys=True)
        if raw is not None:
            text = raw(text)
        p.write_text(text)
        return [a.replace("{w}", str(work)) for a in command]

    return Case(name, setup, **kw)


def _set(path: str, value) -> Callable[[dict], None]:
    def f(doc: dict) -> None:
        keys = path.split(".")
        d = doc
        for k in keys[:-1]:
            d = d[k]
        d[keys[-1]] = value
    return f


def _scale_box(frac: float) -> Callable[[dict], None]:
    def f(doc: dict) -> None:
        th = doc["identification"]["theta"]
        th["min"] = [v - abs(v) * frac for v in th["nominal"]]
        th["max"] = [v + abs(v) * frac for v in th["nominal"]]
        doc["provenance"]["ident_path"] = "/nonexistent/ident.json"
    return f


KEY = b"0123456789abcdef0123456789abcdef"
OTHER_KEY = b"fedcba9876543210fedcba9876543210"


def log_case(name: str, make: Callable[[Path], list[str]], extra: list[str] = (), **kw) -> Case:
    def setup(work: Path) -> list[str]:
        return ["identify", *make(work), *extra, "--out", str(work / "out" / "ident.json")]
    return Case(name, setup, out="out", **kw)


def _write(name: str, text: str | bytes) -> Callable[[Path], list[str]]:
    def f(work: Path) -> list[str]:
        p = work / name
        p.write_bytes(text if isinstance(text, bytes) else text.encode())
        return [str(p)]
    return f


def _sample_twice(work: Path) -> list[str]:
    shutil.copy(SAMPLE, work / "a.h5")
    return [str(work / "a.h5"), str(work / "a.h5")]


def _sample_and_folder(work: Path) -> list[str]:
    (work / "logs").mkdir()
    shutil.copy(SAMPLE, work / "logs" / "a.h5")
    return [str(work / "logs" / "a.h5"), str(work / "logs")]


def _sample_and_symlink(work: Path) -> list[str]:
    shutil.copy(SAMPLE, work / "a.h5")
    os.symlink(work / "a.h5", work / "b.h5")
    return [str(work / "a.h5"), str(work / "b.h5")]


def _sample(work: Path) -> list[str]:
    return [str(SAMPLE)]


def _fifo(work: Path) -> list[str]:
    os.mkfifo(work / "f.csv")
    return [str(work / "f.csv")]


def _truncated_h5(work: Path) -> list[str]:
    (work / "t.h5").write_bytes(SAMPLE.read_bytes()[:4096])
    return [str(work / "t.h5")]


def _csv(rows: list[str]) -> Callable[[Path], list[str]]:
    return _write("log.csv", "\n".join(rows) + "\n")


def _good_csv_rows(n: int = 2000) -> list[str]:
    import math
    return ["t,q,u"] + [f"{k / 1000},{0.01 * math.sin(k / 50)},{0.1 * math.cos(k / 50)}" for k in range(n)]


def identify_cases() -> list[Case]:
    bad_t = _good_csv_rows()
    bad_t[500] = "0.1,0,0"
    nan_q = _good_csv_rows()
    nan_q[700] = "0.699,nan,0.1"
    return [
        log_case("identify: missing file", lambda w: [str(w / "nope.h5")]),
        log_case("identify: empty .h5", _write("e.h5", b"")),
        log_case("identify: /dev/zero", lambda w: ["/dev/zero"]),
        log_case("identify: FIFO", _fifo, timeout=60),
        log_case("identify: truncated HDF5", _truncated_h5),
        log_case("identify: CSV garbage", _write("g.csv", "hello, world\n\x00\x01\x02")),
        log_case("identify: CSV header only", _csv(["t,q,u"])),
        log_case("identify: CSV three rows", _csv(_good_csv_rows(3))),
        log_case("identify: CSV non-monotone t", _csv(bad_t)),
        log_case("identify: CSV NaN in q", _csv(nan_q)),
        log_case("identify: CSV 400-digit number", _csv(_good_csv_rows()[:100] + ["9" * 400 + ",0,0"])),
        log_case("identify: same file twice", _sample_twice),
        log_case("identify: a file and its folder", _sample_and_folder),
        log_case("identify: a file and a symlink to it", _sample_and_symlink),
        log_case("identify: --fix repeated", _sample, ["--fix", "M=0.03", "--fix", "M=0.05"]),
        log_case("identify: --fix M=1e300", _sample, ["--fix", "M=1e300"]),
        log_case("identify: --fix M=1e-300", _sample, ["--fix", "M=1e-300"]),
        log_case("identify: --fix M=-1", _sample, ["--fix", "M=-1"]),
        log_case("identify: hostile --u-unit", _sample, ["--input-gain", "2", "--u-unit", HOSTILE_UNIT],
                 payload=HOSTILE_UNIT),
        log_case("identify: --u-unit parsec", _sample, ["--input-gain", "2", "--u-unit", "parsec"]),
        log_case("identify: --q-unit furlong", _sample, ["--q-unit", "furlong"]),
        log_case("identify: --input-gain nan", _sample, ["--input-gain", "nan", "--u-unit", "N"]),
        log_case("identify: --map to a missing channel", _sample, ["--map", "q=nope"]),
        log_case("identify: --k-sigma -1", _sample, ["--k-sigma", "-1"]),
        Case("identify: --out is the input, --force", lambda w: (shutil.copy(SAMPLE, w / "a.h5"),
                                                                 ["identify", str(w / "a.h5"), "--out",
                                                                  str(w / "a.h5"), "--force"])[1], out="a.h5"),
        Case("identify: --out exists, no --force",
             lambda w: (_copy(BASE, w, "ident.json"), ["identify", str(SAMPLE), "--out", str(w / "ident.json")])[1],
             out="ident.json"),
        Case("identify: --out is a folder", lambda w: ((w / "d").mkdir(), ["identify", str(SAMPLE), "--out",
                                                                        str(w / "d")])[1], out="d"),
    ]


def tune_cases() -> list[Case]:
    cmd = ["tune", "{w}/ident.json", "--out", "{w}/out/tuning.json"]

    def c(name, mutate, raw=None, **kw):
        return json_case(f"tune: {name}", "ident.json", cmd, mutate, raw=raw, out="out", **kw)

    return [
        c("hostile units.u", _set("units.u", HOSTILE_UNIT), payload=HOSTILE_UNIT),
        c("units.u parsec", _set("units.u", "parsec")),
        c("units.q furlong", _set("units.q", "furlong")),
        c("encoder.quantization -1e-6", _set("encoder.quantization", -1e-6)),
        c("source.sample_rate 'fast'", _set("source.sample_rate", "fast")),
        c("parameters.M.value -1", _set("parameters.M.value", -1.0)),
        c("theta min > max", lambda d: d["theta"].__setitem__("min", [v * 2 + 1 for v in d["theta"]["max"]])),
        c("kind 'tuning'", _set("kind", "tuning")),
        c("schema_version 99", _set("schema_version", 99)),
        c("400-digit integer", lambda d: None, raw=lambda t: t.replace('"schema_version": 1', '"schema_version": ' + "1" * 400)),
        c("duplicate key", lambda d: None, raw=lambda t: t.replace('"kind": "identification"',
                                                                   '"kind": "identification", "kind": "identification"')),
        c("NaN literal", lambda d: None, raw=lambda t: t.replace('"delta_d": ', '"delta_d": NaN, "x": ', 1)),
        c("deep nesting", lambda d: None, raw=lambda t: "[" * 100000 + "]" * 100000),
        c("not JSON", lambda d: None, raw=lambda t: t[: len(t) // 2]),
        c("a JSON array", lambda d: None, raw=lambda t: "[1, 2, 3]"),
        Case("tune: --out exists, no --force",
             lambda w: (_copy(BASE, w, "ident.json", "tuning.json"),
                        ["tune", str(w / "ident.json"), "--out", str(w / "tuning.json")])[1], out="tuning.json"),
    ]


def validate_cases() -> list[Case]:
    cmd = ["validate", "{w}/tuning.json", "--out-dir", "{w}/out", "--monte-carlo", "2"]

    def c(name, mutate, raw=None, **kw):
        return json_case(f"validate: {name}", "tuning.json", cmd, mutate, raw=raw, out="out", **kw)

    return [
        c("hostile units.u", _set("identification.units.u", HOSTILE_UNIT), payload=HOSTILE_UNIT),
        c("ident_path missing and box shrunk to 0.1 %", _scale_box(1e-3)),
        c("400-digit integer", lambda d: None, raw=lambda t: t.replace('"schema_version": 1', '"schema_version": ' + "7" * 400, 1)),
        c("duplicate key", lambda d: None, raw=lambda t: t.replace('"kind": "tuning"', '"kind": "tuning", "kind": "tuning"')),
        Case("validate: --monte-carlo 99999", lambda w: (_copy(BASE, w, "tuning.json", "ident.json"),
                                                         ["validate", str(w / "tuning.json"), "--out-dir", str(w / "out"),
                                                          "--monte-carlo", "99999"])[1]),
        Case("validate: gate.toml garbage", lambda w: (_copy(BASE, w, "tuning.json", "ident.json"),
                                                       (w / "g.toml").write_text("[gate\ne_rms = ]]"),
                                                       ["validate", str(w / "tuning.json"), "--out-dir", str(w / "out"),
                                                        "--gate", str(w / "g.toml")])[2]),
        Case("validate: --out-dir is a file", lambda w: (_copy(BASE, w, "tuning.json", "ident.json"),
                                                         (w / "f").write_text("keep"),
                                                         ["validate", str(w / "tuning.json"), "--out-dir", str(w / "f")])[2],
             out="f"),
        Case("validate: full disk", lambda w: _full_disk(w, ["validate", str(w / "tuning.json"), "--monte-carlo", "2",
                                                             "--out-dir"]), out="disk/out", needs_root=True,
             timeout=300),
    ]


def _full_disk(work: Path, argv: list[str]) -> list[str]:
    _copy(BASE, work, "tuning.json", "ident.json", "controller.json")
    (work / "disk").mkdir()
    subprocess.run(["mount", "-t", "tmpfs", "-o", "size=64k", "tmpfs", str(work / "disk")], check=True)
    (work / "disk" / "filler").write_bytes(b"x" * 40_000)
    return [*argv, str(work / "disk" / "out")]


def export_cases() -> list[Case]:
    cmd = ["export", "{w}/controller.json", "--target", "c", "--out-dir", "{w}/out"]

    def c(name, mutate, key: bytes | None | str = None, extra=(), env=None, raw=None, argv=None, **kw):
        return json_case(f"export: {name}", "controller.json", [*(argv or cmd), *extra], mutate, reseal_key=key,
                         raw=raw, out="out", env=env or {}, **kw)

    keyfile = ["--sign-key", "{w}/site.key"]

    def with_key(case: Case, key: bytes = KEY) -> Case:
        inner = case.setup

        def setup(work: Path) -> list[str]:
            (work / "site.key").write_bytes(key)
            return inner(work)
        case.setup = setup
        return case

    def signed(mutate_after):
        def f(doc):
            signed_doc = reseal(doc, KEY)
            doc.clear()
            doc.update(signed_doc)
            mutate_after(doc)
        return f

    cases = [c(f"hostile units.u ({k})", _set("units.u", v), key=None, payload=v, compile_c=True)
             for k, v in HOSTILE_STRINGS.items()]
    cases += [c(f"hostile units.u, target st ({k})", _set("units.u", v), key=None, payload=v,
                argv=["export", "{w}/controller.json", "--target", "st", "--out-dir", "{w}/out"])
              for k, v in HOSTILE_STRINGS.items()]
    cases += [
        c("hostile provenance.tool_version", _set("provenance.tool_version", HOSTILE_UNIT), payload=HOSTILE_UNIT,
          compile_c=True),
        c("hostile provenance.created_utc", _set("provenance.created_utc", HOSTILE_STRINGS["newline-define"]),
          payload=HOSTILE_STRINGS["newline-define"], compile_c=True),
        c("hostile provenance.log_sha256", _set("provenance.log_sha256", HOSTILE_UNIT), payload=HOSTILE_UNIT,
          compile_c=True),
        c("u_max 1e308", _set("bounds.u_max", 1e308)),
        c("sample_rate 1e-3 Hz", lambda d: (d.__setitem__("sample_rate", 1e-3), d.__setitem__("sample_period", 1e3))),
        c("sample_rate 1e9 Hz", lambda d: (d.__setitem__("sample_rate", 1e9), d.__setitem__("sample_period", 1e-9))),
        c("400-digit integer", lambda d: None, raw=lambda t: t.replace('"schema_version": 1', '"schema_version": ' + "3" * 400, 1)),
        with_key(c("signed, duplicate key", signed(lambda d: None), key="none", extra=keyfile,
                   raw=lambda t: t.replace('"kind": "controller"', '"kind": "controller", "kind": "controller"'))),
        with_key(c("signed, u_max edited, checksum recomputed", signed(lambda d: None), key="none", extra=keyfile,
                   raw=None)),
        with_key(c("signature removed", lambda d: None, key=None, extra=keyfile)),
        with_key(c("signed under another key", lambda d: None, key=OTHER_KEY, extra=keyfile)),
        with_key(c("unsigned, key from COMMISSION_SIGN_KEY", lambda d: None, key=None, env={"COMMISSION_SIGN_KEY": "site.key"})),
        c("--require-signature on an unsigned file", lambda d: None, key="none", extra=["--require-signature"]),
        Case("export: into a dangling symlink", lambda w: (_copy(BASE, w, "controller.json"),
                                                           os.symlink(w / "gone", w / "out"),
                                                           ["export", str(w / "controller.json"), "--out-dir",
                                                            str(w / "out")])[2]),
        Case("export: existing files, no --force", lambda w: (_copy(BASE, w, "controller.json"), (w / "out").mkdir(),
                                                              (w / "out" / "commission_arc.c").write_text("mine"),
                                                              ["export", str(w / "controller.json"), "--out-dir",
                                                               str(w / "out")])[3]),
        Case("export: full disk", lambda w: _full_disk(w, ["export", str(w / "controller.json"), "--out-dir"]),
             out="disk/out", needs_root=True),
        Case("export: good controller (C, compiled)", lambda w: (_copy(BASE, w, "controller.json"),
                                                                 ["export", str(w / "controller.json"), "--out-dir",
                                                                  str(w / "out")])[1], expect="ok", compile_c=True),
        Case("export: good controller (ST)", lambda w: (_copy(BASE, w, "controller.json"),
                                                        ["export", str(w / "controller.json"), "--target", "st",
                                                         "--out-dir", str(w / "out")])[1], expect="ok"),
    ]
    # the "signed, u_max edited" case: sign, then edit, then recompute the checksum only
    edited = cases[[x.name for x in cases].index("export: signed, u_max edited, checksum recomputed")]
    inner = edited.setup

    def setup(work: Path) -> list[str]:
        argv = inner(work)
        p = work / "controller.json"
        doc = json.loads(p.read_text())
        sig = doc["signature"]
        doc["bounds"]["u_max"] = doc["bounds"]["u_max"] * 10
        doc = reseal(doc)
        doc["signature"] = sig
        doc = {k: v for k, v in doc.items() if k != "checksum"}
        doc["checksum"] = {"algorithm": "sha256", "value": hashlib.sha256(canonical(doc).encode()).hexdigest()}
        write_json(p, doc)
        return argv
    edited.setup = setup
    return cases


def signal_cases() -> list[Case]:
    out = []
    for d in (0.5, 1.0, 2.0, 3.0, 4.0):
        out.append(Case(f"signal: SIGINT {d} s into export", lambda w: (_copy(BASE, w, "controller.json"),
                                                                          ["export", str(w / "controller.json"), "--out-dir",
                                                                           str(w / "out")])[1],
                        expect="either", interrupt_after=d))
    for d in (1.0, 2.0, 4.0):
        out.append(Case(f"signal: SIGINT {d} s into identify", lambda w: ["identify", str(SAMPLE), "--out",
                                                                          str(w / "out" / "ident.json")],
                        expect="either", interrupt_after=d))
    return out


def symlink_lock_case() -> Case:
    """Two exports at once, into a folder and into a symlink to it: one writes, the other is refused."""
    return Case("lock: two exports, folder and its symlink", _two_exports, expect="special")


def _two_exports(work: Path) -> list[str]:
    _copy(BASE, work, "controller.json")
    (work / "real").mkdir()
    os.symlink(work / "real", work / "link")
    return []


# ------------------------------------------------------------------------------------ running
def snapshot(p: Path) -> dict[str, str]:
    if not p.exists():
        return {}
    files = [p] if p.is_file() else [f for f in p.rglob("*") if f.is_file()]
    return {str(f): hashlib.sha256(f.read_bytes()).hexdigest() for f in files}


def leftovers(work: Path) -> list[str]:
    return [str(f.relative_to(work)) for f in work.rglob("*") if ".tmp-" in f.name or f.name.endswith(".lock")]


def injected(p: Path, payload: str | None) -> bool:
    """Whether an output file holds ``payload`` verbatim (JSON outputs: its JSON-escaped form)."""
    if not p.exists() or not payload:
        return False
    files = [p] if p.is_file() else [f for f in p.rglob("*") if f.is_file()]
    forms = {payload.encode(errors="surrogatepass"), json.dumps(payload)[1:-1].encode()}
    return any(form in f.read_bytes() for f in files for form in forms)


def compile_and_replay(out: Path) -> tuple[bool, str]:
    """(injected, note): build the export with -Werror and run the replay."""
    cc = shutil.which("cc") or shutil.which("gcc")
    if cc is None:
        return False, "no C compiler"
    srcs = [str(out / n) for n in ("test_main.c", "commission_arc.c", "commission_arc_params.c")]
    b = subprocess.run([cc, "-std=c99", "-O2", "-ffp-contract=off", "-Wall", "-Wextra", "-Werror", "-o",
                        str(out / "replay"), *srcs, "-lm"], capture_output=True, text=True)
    if b.returncode != 0:
        return MARKER in b.stderr, "does not compile: " + b.stderr.strip().splitlines()[0][:100]
    r = subprocess.run([str(out / "replay"), str(out / "test_vectors.csv")], capture_output=True, text=True,
                       timeout=120)
    return MARKER in r.stdout + r.stderr, f"replay exit {r.returncode}"


def run_case(case: Case, scratch: Path) -> tuple[str, list[str], str]:
    work = Path(tempfile.mkdtemp(prefix="kit-", dir=scratch))
    mounted = False
    try:
        if case.needs_root and os.geteuid() != 0:
            return case.name, [], "skipped (needs root for a tmpfs)"
        if case.expect == "special":
            return case.name, *_run_two_exports(case, work)
        argv = case.setup(work)
        mounted = (work / "disk").is_dir() and case.needs_root
        out = work / case.out
        before = snapshot(out)
        before_names = set(before)
        env = {**os.environ, **case.env}
        t0 = time.monotonic()
        p = subprocess.Popen([*commission_cmd(), *argv], cwd=work, env=env, stdout=subprocess.PIPE,
                             stderr=subprocess.PIPE, text=True, errors="replace")
        if case.interrupt_after is not None:
            time.sleep(case.interrupt_after)
            if p.poll() is None:
                p.send_signal(signal.SIGINT)
        try:
            stdout, stderr = p.communicate(timeout=case.timeout)
        except subprocess.TimeoutExpired:
            p.kill()
            p.communicate()
            return case.name, ["hang"], f"no answer in {case.timeout:.0f} s"
        rc = p.returncode
        classes = []
        if "Traceback" in stderr or "internal error" in stderr:
            classes.append("traceback")
        after = snapshot(out)
        if case.expect == "refuse" and rc == 0:
            classes.append("exit0-on-bad")
        if rc not in (0,):
            if set(after) - before_names or leftovers(work):
                classes.append("partial")
            if any(before[f] != after.get(f) for f in before):
                classes.append("data-loss")
        elif case.interrupt_after is not None and leftovers(work):
            classes.append("partial")
        if case.interrupt_after is not None and rc == 0 and case.out == "out" and argv[0] == "export":
            if len(after) != 6:
                classes.append("partial")
        if injected(out, case.payload):
            classes.append("injection")
        note = (stderr.strip().splitlines() or [""])[-1][:110]
        if rc == 0 and case.compile_c and (out / "test_main.c").is_file():
            inj, cnote = compile_and_replay(out)
            if inj:
                classes.append("injection")
            note = cnote
        if case.expect == "ok" and rc != 0:
            note = "expected success: " + note
            classes.append("refused-good")
        return case.name, classes, f"exit {rc} ({time.monotonic() - t0:.1f} s): {note}"
    finally:
        if mounted:
            subprocess.run(["umount", str(work / "disk")], check=False)
        shutil.rmtree(work, ignore_errors=True)


def _run_two_exports(case: Case, work: Path) -> tuple[list[str], str]:
    _two_exports(work)
    procs = [subprocess.Popen([*commission_cmd(), "export", str(work / "controller.json"), "--out-dir", str(d)],
                              cwd=work, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
             for d in (work / "real", work / "link")]
    res = [(p.wait(timeout=180), p.communicate()[1]) for p in procs]
    classes = []
    if any("Traceback" in e for _, e in res):
        classes.append("traceback")
    rcs = sorted(r for r, _ in res)
    if rcs != [0, 2]:
        classes.append("data-loss" if rcs == [0, 0] else "partial")
    if leftovers(work):
        classes.append("partial")
    return classes, f"exit codes {rcs}"


def python_api_cases() -> list[tuple[str, str]]:
    """Runtime API misuse: each snippet must raise a CommissionError (a named refusal)."""
    return [
        ("runtime: step('abc')", "c = load_controller(P); c.reset(0.0); c.step('abc', 0.0, 0.0, 0.0)"),
        ("runtime: step(None)", "c = load_controller(P); c.reset(0.0); c.step(None, 0.0, 0.0, 0.0)"),
        ("runtime: reset('x')", "c = load_controller(P); c.reset('x')"),
        ("runtime: load a 400-digit integer", "import json; d = json.loads(open(P).read()); "
         "open(P + '.2', 'w').write(open(P).read().replace('\"schema_version\": 1', '\"schema_version\": ' + '9' * 400, 1)); "
         "load_controller(P + '.2')"),
        ("runtime: key of 3 bytes", "open(P + '.k', 'wb').write(b'abc'); from commission.controller_config import "
         "load_sign_key; load_controller(P, key=load_sign_key(P + '.k'))"),
    ]


def run_python_case(name: str, code: str, scratch: Path) -> tuple[str, list[str], str]:
    work = Path(tempfile.mkdtemp(prefix="kit-", dir=scratch))
    try:
        shutil.copy(BASE / "controller.json", work / "controller.json")
        prog = ("import sys\nfrom commission.runtime import load_controller\nfrom commission.errors import "
                "CommissionError\nP = sys.argv[1]\ntry:\n    " + code + "\nexcept CommissionError as e:\n"
                "    print('refused:', type(e).__name__, str(e)[:90]); sys.exit(2)\nprint('accepted'); sys.exit(0)\n")
        r = subprocess.run([sys.executable, "-c", prog, str(work / "controller.json")], capture_output=True,
                           text=True, timeout=120)
        classes = []
        if "Traceback" in r.stderr:
            classes.append("traceback")
        if r.returncode == 0:
            classes.append("exit0-on-bad")
        return name, classes, (r.stdout.strip() or r.stderr.strip().splitlines()[-1])[:110]
    finally:
        shutil.rmtree(work, ignore_errors=True)


BASE = Path()


def main() -> int:
    global BASE
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--base", type=Path, help="folder with ident.json, tuning.json, controller.json of the sample "
                                              "(default: made now with commission run)")
    ap.add_argument("--only", default="", help="run only the cases whose name contains this")
    ap.add_argument("--jobs", type=int, default=2)
    args = ap.parse_args()
    scratch = Path(tempfile.mkdtemp(prefix="commission-kit-"))
    try:
        if args.base is None:
            args.base = scratch / "base"
            print(f"making the base artifacts: commission run {SAMPLE.relative_to(ROOT)} ...", flush=True)
            subprocess.run([*commission_cmd(), "-q", "run", str(SAMPLE), "--out-dir", str(args.base)], check=True)
        BASE = args.base.resolve()
        cases = [*identify_cases(), *tune_cases(), *validate_cases(), *export_cases(), *signal_cases(),
                 symlink_lock_case()]
        cases = [c for c in cases if args.only in c.name]
        results = []
        with cf.ThreadPoolExecutor(max(1, args.jobs)) as ex:
            futs = [ex.submit(run_case, c, scratch) for c in cases]
            futs += [ex.submit(run_python_case, n, code, scratch) for n, code in python_api_cases()
                     if args.only in n]
            for f in cf.as_completed(futs):
                name, classes, note = f.result()
                results.append((name, classes, note))
                print(f"{'FAIL ' + ','.join(classes) if classes else 'ok':<28} {name:<58} {note}", flush=True)
        print()
        print(f"{len(results)} cases")
        failed = 0
        for cls in (*FAILURES, "refused-good"):
            n = sum(cls in c for _, c, _ in results)
            failed += n
            print(f"  {cls:<14} {n}")
        return 1 if failed else 0
    finally:
        shutil.rmtree(scratch, ignore_errors=True)


if __name__ == "__main__":
    sys.exit(main())
