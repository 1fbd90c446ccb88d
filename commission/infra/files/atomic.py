"""All-or-nothing moves of staged outputs into place, and the one error a failed write becomes.

Each file already in place is first set aside in a backup folder beside it (a hard
link, else a rename), then the new file is renamed over it; every step is recorded
so that :func:`put_back` can restore the old state.  :func:`output_error` turns an
:class:`OSError` of writing (a full disk) into one :class:`commission.errors.OutputError`
naming the output.
"""

from __future__ import annotations

import errno
import os
import tempfile
from pathlib import Path
from typing import Sequence

from commission.errors import CommissionError, OutputError
from commission.infra.files.target import Target

#: errno values that say the output location cannot take the files (full disk, quota, size limit,
#: read-only file system): whatever file the error names, it is the writing that failed.
WRITE_ERRNOS = frozenset({errno.ENOSPC, errno.EDQUOT, errno.EFBIG, errno.EROFS})


def move_all(targets: Sequence[Target], undo: list[tuple[Path, Path]]) -> None:
    """The moves of :meth:`Outputs.commit`; each step that changed the folder appends (from, to) to ``undo``."""
    umask = os.umask(0)
    os.umask(umask)
    for t in targets:
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


def put_back(undo: list[tuple[Path, Path]]) -> None:
    """Undo the steps of :func:`move_all`, last first: the old files back, then nothing else."""
    for src, dst in reversed(undo):
        try:
            os.replace(src, dst)
        except OSError:
            pass


def output_error(targets: Sequence[Target], exc: BaseException, what: str,
                 in_place: bool = False) -> "OutputError | None":
    """``exc`` as a one-line :class:`OutputError` when it is a failure to write the files of ``targets``.

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
    for t in targets:
        roots = [str(p) for p in (t.staged_at, t.backup, t.lock_path, t.real if in_place else None)
                 if p is not None]
        if any(n == r or n.startswith(r + os.sep) for n in names for r in roots):
            target = t
            break
    if target is None:
        if exc.errno not in WRITE_ERRNOS or not targets:
            return None
        target = targets[0]
    return OutputError(f"{target.flag} {target.dest}: {what} ({exc.strerror or exc}); "
                       f"nothing written or replaced")
