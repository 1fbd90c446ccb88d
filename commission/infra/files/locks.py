"""The per-output lock: ``fcntl.flock`` on ``.NAME.lock`` beside the output, naming its holder.

A second process that wants the same output is refused with the holder's pid,
command and start time.  The holder unlinks the lock file while it still holds it;
:func:`take_lock` checks that the file it locked is still the one on disk, so a
process that opened the file just before that unlink starts again.
"""

from __future__ import annotations

import datetime as _dt
import errno
import fcntl
import os
import sys
import time
from pathlib import Path

from commission.errors import OutputError, UsageError
from commission.infra.files.target import Target


def make_dirs(t: Target, folder: Path) -> None:
    """Create ``folder`` and its missing parents, each recorded in ``t.made_dirs`` (removed on abort)."""
    missing = []
    q = folder.absolute()
    while not q.exists():
        missing.append(q)
        q = q.parent
    for d in reversed(missing):
        try:
            d.mkdir()
        except FileExistsError:
            continue
        except OSError as exc:
            raise UsageError(f"{t.flag} {t.dest}: cannot create {d} ({exc.strerror or exc})") from None
        t.made_dirs.append(d)


def take_lock(t: Target) -> None:
    """Take the exclusive lock of ``t`` and write the holder line into it.

    The lock file is ``.NAME.lock`` beside the resolved target, or inside an existing
    output folder whose parent is not writable (:class:`commission.infra.files.Outputs` notes).
    """
    make_dirs(t, t.real.parent)
    parent = t.real.parent
    inside = t.is_dir and t.real.is_dir() and not os.access(parent, os.W_OK)
    lock = (t.real if inside else parent) / f".{t.real.name}.lock"
    where = t.real if inside else parent
    while True:
        try:
            fd = os.open(lock, os.O_RDWR | os.O_CREAT, 0o644)
        except OSError as exc:
            raise UsageError(f"{t.flag} {t.dest}: cannot write in {where} "
                             f"({exc.strerror or exc})") from None
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError as exc:
            holder = read_holder(fd)
            os.close(fd)
            if exc.errno in (errno.EAGAIN, errno.EACCES):
                raise UsageError(f"{t.flag} {t.dest}: in use by another commission process ({holder}); "
                                 f"wait for it or choose another output") from None
            raise UsageError(f"{t.flag} {t.dest}: cannot lock {lock} ({exc.strerror or exc})") from None
        # The previous holder unlinks the lock file on release: if it did so between our
        # open and our flock, we hold a lock on a dead inode; start again.
        try:
            same = os.fstat(fd).st_ino == os.stat(lock).st_ino
        except FileNotFoundError:
            same = False
        if same:
            break
        os.close(fd)
    t.lock_fd, t.lock_path = fd, lock
    started = _dt.datetime.now(_dt.timezone.utc).strftime("%Y-%m-%dT%H:%M:%SZ")
    cmd = " ".join(os.path.basename(a) if i == 0 else a for i, a in enumerate(sys.argv[:3]))
    try:
        os.ftruncate(fd, 0)
        os.write(fd, f"pid {os.getpid()}, {cmd}, since {started}\n".encode())
    except OSError as exc:
        raise OutputError(f"{t.flag} {t.dest}: cannot write in {where} ({exc.strerror or exc}); "
                          f"nothing written") from None


def drop_lock(t: Target) -> None:
    """Unlink and close the lock of ``t`` if it holds one (unlinked while still held: see :func:`take_lock`)."""
    if t.lock_fd is not None:
        try:
            if t.lock_path is not None:
                t.lock_path.unlink()  # while still held; see the inode check in take_lock
        except OSError:
            pass
        os.close(t.lock_fd)
        t.lock_fd = None


def read_holder(fd: int, wait_s: float = 1.0) -> str:
    """The holder's ``pid ..., command, since ...`` line from its lock file.

    The holder writes that line just after its ``flock`` succeeds, so a process refused in
    between finds the file empty; it polls briefly rather than report an unknown holder.
    """
    deadline = time.monotonic() + wait_s
    while True:
        try:
            os.lseek(fd, 0, os.SEEK_SET)
            text = os.read(fd, 300).decode("utf-8", "replace").strip()
        except OSError:
            text = ""
        if text or time.monotonic() >= deadline:
            return text or "holder unknown"
        time.sleep(0.01)

