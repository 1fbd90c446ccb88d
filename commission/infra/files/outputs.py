"""The checked, locked, all-or-nothing set of files one command writes (:class:`Outputs`).

The steps are described in :mod:`commission.infra.files`; the lock is in
:mod:`commission.infra.files.locks`, the moves of the commit and the error a failed write
becomes in :mod:`commission.infra.files.atomic`, and the record of open and committed
outputs in :mod:`commission.infra.files.registry`.
"""

from __future__ import annotations

import os
import shutil
import tempfile
from pathlib import Path
from typing import Any, Iterable, Sequence

from commission.errors import OutputError, UsageError
from commission.infra.files import registry
from commission.infra.files.atomic import move_all, output_error, put_back
from commission.infra.files.locks import drop_lock, take_lock
from commission.infra.files.signals import signals_held
from commission.infra.files.target import Target, resolved


def same_file(a: str | os.PathLike[str], b: str | os.PathLike[str]) -> bool:
    """Whether two paths name the same existing file (symlinks and hard links included)."""
    try:
        return os.path.samefile(a, b)
    except OSError:
        return False



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
    dropped.  SIGINT and SIGTERM are held meanwhile (:func:`signals_held`) and
    handed on after, so a signal during the commit is acted on once the outcome is
    settled: the set in place and recorded, or the old state and nothing recorded.
    """

    def __init__(self, *, force: bool, inputs: Iterable[str | os.PathLike[str] | None] = ()) -> None:
        self.force = force
        self.inputs = [os.fspath(p) for p in inputs if p is not None]
        self._targets: list[Target] = []
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
        self._add(Target(dest, (dest.name,), False, flag, resolved(dest)))
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
        self._add(Target(dest, tuple(names), True, flag, resolved(dest)))
        return dest

    def _add(self, t: Target) -> None:
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
        registry.LIVE.append(self)
        try:
            for t in self._targets:
                take_lock(t)
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
        with signals_held():
            try:
                for t in self._targets:  # a file nobody declared was never checked against --force
                    assert t.staging is not None
                    stray = sorted(f.name for f in t.staging.iterdir() if f.name not in t.names)
                    if stray:
                        raise RuntimeError(f"{t.dest}: undeclared outputs {stray} (add them to the command's "
                                           f"output names)")
                undo: list[tuple[Path, Path]] = []
                try:
                    move_all(self._targets, undo)
                except BaseException:
                    put_back(undo)  # the old files, then nothing else
                    raise
            except BaseException as exc:
                failed = output_error(self._targets, exc, "cannot move the outputs into place", in_place=True)
                self.abort()
                if failed is not None:
                    raise failed from None
                raise
            # The point of no return: every file is in place.
            self.committed = True
            registry.COMMITTED.extend(t.dest for t in self._targets)
            for t in self._targets:
                for d in (None if t.moved_whole else t.staging, t.backup):
                    if d is not None:
                        shutil.rmtree(d, ignore_errors=True)
                t.staging = t.backup = None
                t.made_dirs = []
            self._release()

    def abort(self) -> None:
        """Remove staging folders, locks and folders this run created; leave the targets as they were."""
        with signals_held():
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
            drop_lock(t)
        self._open = False
        if self in registry.LIVE:
            registry.LIVE.remove(self)

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
        failed = output_error(self._targets, exc, "cannot write")
        self.abort()
        if failed is not None:
            raise failed from None
