"""Safe file handling for every command: bounded inputs, checked and transactional outputs.

Inputs
------
:func:`open_input` and :func:`read_input_bytes` accept only regular files (a
symlink is followed, but what it points to must be a regular file): a FIFO
would block the tool forever and a device such as ``/dev/zero`` would feed it
without end.  A file larger than its limit is refused before it is read, and
the read itself stops at the limit (a file growing while it is read cannot
exhaust memory).  :func:`read_toml` reads a spec or gate file (UTF-8 TOML).

Outputs
-------
:class:`Outputs` is the one way a command writes files:

1. :meth:`Outputs.add` declares a *target* -- an output file (``--out``) or
   an output folder (``--out-dir``) and the names the command may write into
   it -- and checks it before any computation: not the same file as an input,
   not a folder where a file is expected (or the reverse), not a dangling
   symlink, no existing output without ``force``.
2. :meth:`Outputs.open` takes an exclusive lock per target (``fcntl.flock`` on
   ``.NAME.lock`` beside it; a second process is refused naming the holder's
   pid, command and start time) and creates a staging folder
   ``.NAME.tmp-XXXX`` beside it (inside it, for a folder that exists).  That
   both proves the location writable before the work starts.  Locks and
   staging use the *resolved* path: a folder reached through a symlink,
   ``..`` or a relative spelling is the same folder with the same lock.
3. The command writes every file into :meth:`Outputs.path`.
4. :meth:`Outputs.commit` moves the staged files into place, all or nothing:
   it removes the outputs this run did not produce (so that a folder never
   pairs a new report with an old ``controller.json``), puts every old file
   back if a move fails, and releases the locks.  SIGINT and SIGTERM are held
   during the commit and acted on after it, when the outcome is settled
   (:func:`committed_outputs` tells the CLI the set is in place).  Any
   exception before that -- including the :class:`KeyboardInterrupt` of
   Ctrl-C and the exception the CLI raises on SIGTERM -- removes the staging
   folders and locks and leaves the targets as they were; an :class:`OSError`
   of writing (a full disk) becomes one :class:`commission.errors.OutputError`
   naming the output.  An interrupted or failed run therefore leaves either
   nothing or a complete set, and never a temporary file.  (SIGKILL and power
   loss can leave a staging folder; it is named so that it is plainly not an
   output.)
"""

from __future__ import annotations

import contextlib
import datetime as _dt
import errno
import fcntl
import os
import shutil
import signal
import stat
import sys
import tempfile
import threading
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Iterable, Iterator, Sequence

from commission.errors import CommissionError, InputFileError, OutputError, SpecError, UsageError

try:  # Python >= 3.11
    import tomllib as _toml
except ModuleNotFoundError:  # pragma: no cover - Python 3.10
    import tomli as _toml  # type: ignore[no-redef]

#: Largest excitation log read, bytes (a 10-million-sample HDF5 log of four channels is 320 MB).
MAX_LOG_BYTES = 2 * 1024**3
#: Largest JSON artifact read, bytes (tuning.json of a long search is below 1 MB).
MAX_JSON_BYTES = 64 * 1024**2
#: Largest spec or gate TOML read, bytes.
MAX_TOML_BYTES = 1024**2


# --------------------------------------------------------------------------- inputs


def _mib(n: int) -> str:
    return f"{n / 1024**2:.4g} MiB"


def check_input_file(path: str | os.PathLike[str], limit: int, what: str = "file") -> os.stat_result:
    """Refuse a missing input, a folder, a FIFO, a socket or a device, or one over ``limit`` bytes.

    Returns
    -------
    os.stat_result
        Of the file (symlinks followed).

    Raises
    ------
    InputFileError
        Naming the file and what it is.
    """
    name = os.fspath(path)
    try:
        st = os.stat(name)
    except FileNotFoundError:
        raise InputFileError(f"{name}: no such file") from None
    except OSError as exc:
        raise InputFileError(f"{name}: cannot read ({exc.strerror or exc})") from None
    if stat.S_ISDIR(st.st_mode):
        raise InputFileError(f"{name}: is a directory, not a {what}")
    if not stat.S_ISREG(st.st_mode):
        kind = ("a FIFO" if stat.S_ISFIFO(st.st_mode) else "a device" if stat.S_ISCHR(st.st_mode)
                or stat.S_ISBLK(st.st_mode) else "a socket" if stat.S_ISSOCK(st.st_mode) else "not a regular file")
        raise InputFileError(f"{name}: is {kind}; give a regular file")
    if st.st_size > limit:
        raise InputFileError(f"{name}: {_mib(st.st_size)} is larger than the {_mib(limit)} this tool reads")
    return st


def read_input_bytes(path: str | os.PathLike[str], limit: int) -> bytes:
    """The bytes of a regular input file of at most ``limit`` bytes (:func:`check_input_file`).

    The file is opened without blocking, checked again on the open descriptor
    (it may have been swapped for a FIFO since the first check), and read up to
    ``limit + 1`` bytes, so a file that grows while it is read is refused too.
    """
    name = os.fspath(path)
    check_input_file(name, limit)
    try:
        fd = os.open(name, os.O_RDONLY | getattr(os, "O_NONBLOCK", 0))
    except OSError as exc:
        raise InputFileError(f"{name}: cannot read ({exc.strerror or exc})") from None
    with os.fdopen(fd, "rb") as fh:
        if not stat.S_ISREG(os.fstat(fd).st_mode):
            raise InputFileError(f"{name}: is not a regular file; give a regular file")
        try:
            data = fh.read(limit + 1)
        except OSError as exc:
            raise InputFileError(f"{name}: cannot read ({exc.strerror or exc})") from None
    if len(data) > limit:
        raise InputFileError(f"{name}: larger than the {_mib(limit)} this tool reads")
    return data


def read_toml(path: str | os.PathLike[str]) -> dict[str, Any]:
    """Parse a UTF-8 TOML file (a tune spec or a gate).

    Raises
    ------
    InputFileError
        Missing, not a regular file, or too large.
    SpecError
        Not UTF-8 (naming the byte offset) or not valid TOML.
    """
    name = os.fspath(path)
    data = read_input_bytes(name, MAX_TOML_BYTES)
    try:
        text = data.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise SpecError(f"{name}: not UTF-8 text (byte {exc.start}: {data[exc.start:exc.start + 1]!r})") from None
    try:
        return _toml.loads(text)
    except _toml.TOMLDecodeError as exc:
        raise SpecError(f"{name}: not valid TOML ({exc})") from None
    except RecursionError:
        raise SpecError(f"{name}: nested too deeply") from None


# --------------------------------------------------------------------------- outputs


def same_file(a: str | os.PathLike[str], b: str | os.PathLike[str]) -> bool:
    """Whether two paths name the same existing file (symlinks and hard links included)."""
    try:
        return os.path.samefile(a, b)
    except OSError:
        return False


#: errno values that say the output location cannot take the files (full disk, quota, size limit,
#: read-only file system): whatever file the error names, it is the writing that failed.
WRITE_ERRNOS = frozenset({errno.ENOSPC, errno.EDQUOT, errno.EFBIG, errno.EROFS})

#: Outputs opened and neither committed nor aborted (:func:`abort_unfinished`).
_LIVE: list["Outputs"] = []
#: Targets moved into place since :func:`forget_commits` (:func:`committed_outputs`).
_COMMITTED: list[Path] = []


def committed_outputs() -> tuple[Path, ...]:
    """The targets whose files this process moved into place since :func:`forget_commits`.

    The CLI asks this when a signal arrives: once a set is in place the command is
    finished as far as the files go, and its exit code must say so (``cli/main.py``).
    """
    return tuple(_COMMITTED)


def forget_commits() -> None:
    """Start a new record for :func:`committed_outputs` (the CLI calls it as each command starts)."""
    _COMMITTED.clear()


def unfinished() -> tuple["Outputs", ...]:
    """The :class:`Outputs` opened and neither committed nor aborted yet."""
    return tuple(_LIVE)


def abort_unfinished(keep: Iterable["Outputs"] = ()) -> None:
    """Abort every :class:`Outputs` still open but those in ``keep`` (staging, backups and locks removed).

    ``with outputs:`` aborts on any exception, but an interrupt can land between a
    statement and the ``with`` that would clean up after it; the CLI calls this when a
    command ends (keeping what was open before it started, :func:`unfinished`) so that
    no staging folder or lock file outlives the command.
    """
    kept = {id(o) for o in keep}
    for o in list(_LIVE):
        if id(o) not in kept:
            o.abort()


@contextlib.contextmanager
def _signals_held() -> Iterator[None]:
    """Hold SIGINT and SIGTERM for the duration: recorded, then handed to the previous handlers after.

    Python runs signal handlers in the main thread between bytecodes, and a signal
    sent to the process may be taken by any thread (numba's, a pool's), so blocking
    it with ``pthread_sigmask`` in the main thread does not stop a
    :class:`KeyboardInterrupt` in the middle of a sequence of renames.  Replacing the
    Python-level handlers does: the signal is noted, the block finishes, and the
    handler in place before (the CLI's, or ``default_int_handler``) then decides.
    Outside the main thread handlers cannot be set, but neither can an interrupt be
    raised there: nothing to do.
    """
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    got: list[int] = []

    def record(signum: int, frame: object) -> None:
        got.append(signum)

    old: dict[int, Any] = {}
    try:
        for s in (signal.SIGINT, signal.SIGTERM):
            prev = signal.getsignal(s)
            if prev is None or prev is signal.SIG_IGN:
                continue  # a handler set outside Python, or an ignored signal: leave it as it is
            old[s] = prev
            signal.signal(s, record)
        yield
    finally:
        for s, prev in old.items():
            signal.signal(s, prev)
        for s in dict.fromkeys(got):
            prev = old[s]
            if prev is signal.SIG_DFL:
                signal.raise_signal(s)
            elif callable(prev):
                prev(s, None)


@dataclass
class _Target:
    dest: Path          # the output file, or the output folder, as the user spelled it
    names: tuple[str, ...]  # files of a folder target; (dest.name,) for a file target
    is_dir: bool
    flag: str
    real: Path = Path()  # dest with every symlink, ``..`` and ``.`` resolved: where the files go
    lock_fd: int | None = None
    lock_path: Path | None = None
    staging: Path | None = None
    staged_at: Path | None = None  # the staging folder, remembered after commit for final()
    backup: Path | None = None  # the replaced files during commit (same folder: renames only)
    moved_whole: bool = False  # the staging folder itself became the output folder
    made_dirs: list[Path] = field(default_factory=list)

    @property
    def folder(self) -> Path:
        return self.real if self.is_dir else self.real.parent

    def final(self, name: str) -> Path:
        """Where the staged file ``name`` goes."""
        return self.real / name if self.is_dir else self.real


def _resolved(p: Path) -> Path:
    """``p`` with every symlink, ``..`` and ``.`` resolved (parts that do not exist yet kept as written)."""
    return Path(os.path.realpath(p))


class Outputs:
    """The files one command writes, checked up front and moved into place together (module docstring).

    Parameters
    ----------
    force : bool
        Overwrite existing outputs (the ``--force`` flag of every command).
    inputs : sequence of path
        Files the command reads; an output that is one of them is refused even with ``force``.

    Notes
    -----
    Every file operation uses the target's *resolved* path (symlinks, ``..`` and ``.``
    resolved; what the user typed stays in messages and in :meth:`final`).  One folder
    therefore has one lock whatever its spelling, and the files are written into the
    folder a symlink points to rather than over the symlink.

    Where the lock goes: ``.NAME.lock`` beside the resolved target, so that a folder
    that does not exist yet has its lock too (it appears in one rename at commit).  An
    existing output folder whose parent is not writable (``--out-dir .`` in a home
    folder under a read-only ``/home``) takes the lock inside itself instead: such a
    folder can only be written in place, so every process that may write it takes the
    same lock.  The staging folder of an existing output folder is inside it (the same
    file system, so that every move is a rename).

    The commit is all or nothing.  Each file already in place is first set aside in
    a backup folder beside it (a hard link, else a rename), then the new file is
    renamed over it; an error on the way (a full disk, a permission) puts every
    file back as it was before the error is reported, and only when every target is
    in place is the commit recorded (:func:`committed_outputs`) and the backups
    dropped.  SIGINT and SIGTERM are held meanwhile (:func:`_signals_held`) and
    handed on after, so a signal during the commit is acted on once the outcome is
    settled: the set in place and recorded, or the old state and nothing recorded.
    """

    def __init__(self, *, force: bool, inputs: Iterable[str | os.PathLike[str] | None] = ()) -> None:
        self.force = force
        self.inputs = [os.fspath(p) for p in inputs if p is not None]
        self._targets: list[_Target] = []
        self._open = False
        #: Every file in place (set by :meth:`commit` at its point of no return).
        self.committed = False

    # -- declaration (before any computation) ------------------------------------------------
    def add_file(self, path: str | os.PathLike[str], flag: str) -> Path:
        """Declare an output file (``--out``); returns its final path."""
        dest = Path(path)
        if dest.is_dir():
            raise UsageError(f"{flag} {dest}: is a directory; give a file name such as {dest / 'out.json'}")
        if dest.name in ("", ".", ".."):
            raise UsageError(f"{flag} {dest}: not a file name")
        if dest.is_symlink() and not dest.exists():
            raise UsageError(f"{flag} {dest}: a symlink to {os.readlink(dest)}, which does not exist; "
                             f"remove the link or give another name")
        self._check_not_input(dest, flag)
        if dest.exists() or dest.is_symlink():
            if not self.force:
                raise UsageError(f"{flag} {dest}: exists; pass --force to overwrite")
            if not dest.is_file():
                raise UsageError(f"{flag} {dest}: exists and is not a regular file")
        self._check_parent(dest.parent, flag, dest)
        self._add(_Target(dest, (dest.name,), False, flag, _resolved(dest)))
        return dest

    def add_dir(self, path: str | os.PathLike[str], names: Sequence[str], flag: str) -> Path:
        """Declare an output folder (``--out-dir``) and every name the command may write into it."""
        dest = Path(path)
        if dest.is_symlink() and not dest.exists():
            raise UsageError(f"{flag} {dest}: a symlink to {os.readlink(dest)}, which does not exist; "
                             f"create that folder or give another")
        if dest.exists() and not dest.is_dir():
            raise UsageError(f"{flag} {dest}: exists and is not a folder")
        for n in names:
            p = dest / n
            self._check_not_input(p, flag)
            if (p.exists() or p.is_symlink()) and not self.force:
                raise UsageError(f"{p}: exists; pass --force to overwrite")
            if p.is_dir():
                raise UsageError(f"{p}: is a directory; remove it")
        self._check_parent(dest if dest.exists() else dest.parent, flag, dest)
        self._add(_Target(dest, tuple(names), True, flag, _resolved(dest)))
        return dest

    def _add(self, t: _Target) -> None:
        for o in self._targets:
            if o.real == t.real:
                raise UsageError(f"{t.flag} {t.dest}: the same place as {o.flag} {o.dest}; give two outputs")
        self._targets.append(t)

    def _check_not_input(self, p: Path, flag: str) -> None:
        for src in self.inputs:
            if same_file(p, src) or os.path.abspath(p) == os.path.abspath(src):
                raise UsageError(f"{flag} {p}: is also an input of this command; write elsewhere")

    @staticmethod
    def _check_parent(parent: Path, flag: str, dest: Path) -> None:
        # The nearest existing ancestor must be a folder; the lock and staging folder
        # created by open() then prove it writable before any computation.
        q = parent.absolute()
        while not q.exists() and q != q.parent:
            q = q.parent
        if not q.is_dir():
            raise UsageError(f"{flag} {dest}: {q} is not a folder")

    # -- lock and staging ----------------------------------------------------------------------
    def open(self) -> "Outputs":
        """Lock every target and create its staging folder (proves the location writable)."""
        _LIVE.append(self)
        try:
            for t in self._targets:
                self._lock(t)
                where = t.real if t.is_dir and t.real.is_dir() else t.real.parent
                try:
                    t.staging = Path(tempfile.mkdtemp(prefix=f".{t.real.name}.tmp-", dir=where))
                except OSError as exc:
                    raise OutputError(f"{t.flag} {t.dest}: cannot write in {where} ({exc.strerror or exc}); "
                                      f"nothing written") from None
                t.staged_at = t.staging
        except BaseException:
            self.abort()
            raise
        self._open = True
        return self

    def _makedirs(self, t: _Target, folder: Path) -> None:
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

    def _lock(self, t: _Target) -> None:
        self._makedirs(t, t.real.parent)
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
                holder = _read_holder(fd)
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

    # -- writing -------------------------------------------------------------------------------
    def path(self, dest: str | os.PathLike[str]) -> Path:
        """Where to write the output whose final path is ``dest`` (inside the staging folder)."""
        if not self._open:
            raise RuntimeError("Outputs.path before open()")
        d = Path(dest)
        for t in self._targets:
            assert t.staging is not None
            if not t.is_dir and d == t.dest:
                return t.staging / t.dest.name
            if t.is_dir and d.parent == t.dest and d.name in t.names:
                return t.staging / d.name
        raise ValueError(f"{dest}: not a declared output")

    def staging(self, dest: str | os.PathLike[str]) -> Path:
        """The staging folder of the folder target ``dest`` (to hand to writers that take a folder)."""
        for t in self._targets:
            if t.is_dir and t.dest == Path(dest):
                assert t.staging is not None
                return t.staging
        raise ValueError(f"{dest}: not a declared output folder")

    def final(self, staged: str | os.PathLike[str]) -> Path:
        """The final path of a file written into a staging folder."""
        s = Path(staged)
        for t in self._targets:
            if t.staged_at is not None and s.parent == t.staged_at:
                return t.dest if not t.is_dir else t.dest / s.name
        raise ValueError(f"{staged}: not in a staging folder")

    def commit(self) -> None:
        """Move every staged file into place, all or nothing (class notes), and release the locks.

        Raises
        ------
        OutputError
            A file could not be moved (e.g. a full disk); everything was put back and
            the staging folders and locks removed.
        """
        if not self._open:
            raise RuntimeError("Outputs.commit before open()")
        with _signals_held():
            try:
                for t in self._targets:  # a file nobody declared was never checked against --force
                    assert t.staging is not None
                    stray = sorted(f.name for f in t.staging.iterdir() if f.name not in t.names)
                    if stray:
                        raise RuntimeError(f"{t.dest}: undeclared outputs {stray} (add them to the command's "
                                           f"output names)")
                undo: list[tuple[Path, Path]] = []
                try:
                    self._move_all(undo)
                except BaseException:
                    for src, dst in reversed(undo):  # put back: the old files, then nothing else
                        try:
                            os.replace(src, dst)
                        except OSError:
                            pass
                    raise
            except BaseException as exc:
                failed = self._output_error(exc, "cannot move the outputs into place", in_place=True)
                self.abort()
                if failed is not None:
                    raise failed from None
                raise
            # The point of no return: every file is in place.
            self.committed = True
            _COMMITTED.extend(t.dest for t in self._targets)
            for t in self._targets:
                for d in (None if t.moved_whole else t.staging, t.backup):
                    if d is not None:
                        shutil.rmtree(d, ignore_errors=True)
                t.staging = t.backup = None
                t.made_dirs = []
            self._release()

    def _move_all(self, undo: list[tuple[Path, Path]]) -> None:
        """The moves of :meth:`commit`; each step that changed the folder appends (from, to) to ``undo``."""
        umask = os.umask(0)
        os.umask(umask)
        for t in self._targets:
            assert t.staging is not None
            for f in t.staging.iterdir():
                os.chmod(f, 0o666 & ~umask)  # mkstemp/mkdtemp create 0600/0700
            if t.is_dir and not t.real.exists():
                os.chmod(t.staging, 0o777 & ~umask)
                os.rename(t.staging, t.real)  # the whole set appears at once
                undo.append((t.real, t.staging))
                t.moved_whole = True
                continue
            t.backup = Path(tempfile.mkdtemp(prefix=f".{t.real.name}.old-", dir=t.folder))
            for n in t.names:
                src, dst = t.staging / n, t.final(n)
                if dst.exists() or dst.is_symlink():
                    kept = t.backup / n
                    try:
                        os.link(dst, kept, follow_symlinks=False)  # dst stays in place until the rename
                    except OSError:
                        os.rename(dst, kept)
                    undo.append((kept, dst))
                    if not src.exists():
                        if dst.exists() or dst.is_symlink():
                            dst.unlink()  # an output this run did not produce (e.g. controller.json)
                        continue
                if src.exists():
                    os.rename(src, dst)
                    undo.append((dst, src))

    def _output_error(self, exc: BaseException, what: str, in_place: bool = False) -> "OutputError | None":
        """``exc`` as a one-line :class:`OutputError` when it is a failure to write this command's files.

        That is: an :class:`OSError` naming a file in a staging folder (or, during the
        commit, ``in_place``, in a target), or one whose errno says the disk cannot take
        the files (:data:`WRITE_ERRNOS`) whatever it names.  Anything else (an input
        that cannot be read, a bug) is left as it is.
        """
        if not isinstance(exc, OSError) or isinstance(exc, CommissionError):
            return None
        names = [os.path.realpath(os.fsdecode(n)) for n in (exc.filename, exc.filename2)
                 if isinstance(n, (str, bytes, os.PathLike))]
        target = None
        for t in self._targets:
            roots = [str(p) for p in (t.staged_at, t.backup, t.lock_path, t.real if in_place else None)
                     if p is not None]
            if any(n == r or n.startswith(r + os.sep) for n in names for r in roots):
                target = t
                break
        if target is None:
            if exc.errno not in WRITE_ERRNOS or not self._targets:
                return None
            target = self._targets[0]
        return OutputError(f"{target.flag} {target.dest}: {what} ({exc.strerror or exc}); "
                           f"nothing written or replaced")

    def abort(self) -> None:
        """Remove staging folders, locks and folders this run created; leave the targets as they were."""
        with _signals_held():
            for t in self._targets:
                for d in (t.staging, t.backup):
                    if d is not None:
                        shutil.rmtree(d, ignore_errors=True)
                t.staging = t.backup = None
            self._release()
            for t in self._targets:
                for d in reversed(t.made_dirs):
                    try:
                        d.rmdir()
                    except OSError:
                        break
                t.made_dirs = []

    def _release(self) -> None:
        for t in self._targets:
            if t.lock_fd is not None:
                try:
                    if t.lock_path is not None:
                        t.lock_path.unlink()  # while still held; see the inode check in _lock
                except OSError:
                    pass
                os.close(t.lock_fd)
                t.lock_fd = None
        self._open = False
        if self in _LIVE:
            _LIVE.remove(self)

    def __enter__(self) -> "Outputs":
        return self.open()

    def __exit__(self, exc_type: Any, exc: Any, tb: Any) -> None:
        if exc_type is None:
            if self._open:
                try:
                    self.commit()  # aborts itself on failure before its point of no return
                except BaseException:
                    self.abort()  # an interrupt as the commit started; a no-op once it committed
                    raise
            return
        failed = self._output_error(exc, "cannot write")
        self.abort()
        if failed is not None:
            raise failed from None


def _read_holder(fd: int, wait_s: float = 1.0) -> str:
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


__all__ = ["MAX_LOG_BYTES", "MAX_JSON_BYTES", "MAX_TOML_BYTES", "check_input_file", "read_input_bytes",
           "read_toml", "same_file", "Outputs", "WRITE_ERRNOS", "committed_outputs", "forget_commits",
           "unfinished", "abort_unfinished"]
