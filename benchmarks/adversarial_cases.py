"""The cases of the adversarial kit (benchmarks/adversarial_kit.py runs and classifies them).

Each :class:`Case` prepares a work folder -- a damaged log, an edited artifact
(checksums recomputed, as anyone can), a forged or stripped signature, a hostile
unit string, a full disk, a symlinked output folder -- and names the
``commission`` command to run there; :func:`python_api_cases` are misuses of the
runtime API.  :data:`BASE` is the folder of the good artifacts the cases start
from (set by the kit before any case runs).
"""

from __future__ import annotations

import hashlib
import hmac
import json
import os
import shutil
import subprocess
import sys
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


#: The good artifacts of the sample (ident.json, tuning.json, controller.json); set by the kit's main().
BASE = Path()
