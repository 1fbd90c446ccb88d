"""Build an export with the system C compiler (for its tests and benchmark, and for a user's check).

Uses ``cc`` (or ``$CC``) with :data:`commission.export.c_target.CFLAGS`;
``-ffp-contract=off`` is what keeps ``a*b + c`` two roundings, as in the
Python step.
"""

from __future__ import annotations

import os
import shutil
import subprocess
from pathlib import Path

from commission.export.c_target import CFLAGS


def find_cc() -> str | None:
    """The C compiler: ``$CC`` or ``cc`` on the PATH, None when there is none."""
    return shutil.which(os.environ.get("CC", "cc"))


def _cc(args: list[str]) -> None:
    cc = find_cc()
    if cc is None:
        raise FileNotFoundError("no C compiler: neither $CC nor cc is on the PATH")
    r = subprocess.run([cc, *CFLAGS, *args], capture_output=True, text=True)
    if r.returncode != 0:
        raise RuntimeError(f"{cc} {' '.join(args)} failed:\n{r.stderr}")


def build_replay(export_dir: str | os.PathLike[str], kind: str, exe: str | os.PathLike[str]) -> Path:
    """Compile test_main.c with the step and its parameters into ``exe``."""
    d = Path(export_dir)
    b = f"commission_{kind}"
    _cc(["-Wall", "-Wextra", "-Werror", "-pedantic", "-o", os.fspath(exe), str(d / "test_main.c"),
         str(d / f"{b}.c"), str(d / f"{b}_params.c"), "-lm"])
    return Path(exe)


def build_shared(export_dir: str | os.PathLike[str], kind: str, lib: str | os.PathLike[str],
                 extra: tuple[str, ...] = ()) -> Path:
    """Compile the step and its parameters into a shared library ``lib`` (for ctypes)."""
    d = Path(export_dir)
    b = f"commission_{kind}"
    _cc(["-shared", "-fPIC", "-o", os.fspath(lib), str(d / f"{b}.c"), str(d / f"{b}_params.c"),
         *[str(x) for x in extra], "-lm"])
    return Path(lib)
