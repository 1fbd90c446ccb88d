"""Safe file handling for every command: bounded inputs, checked and transactional outputs.

Inputs
------
:func:`check_input_file` and :func:`read_input_bytes` accept only regular files (a
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

Modules
-------
:mod:`~commission.infra.files.inputs`
    The bounded readers and their size limits.
:mod:`~commission.infra.files.outputs`
    :class:`Outputs` (declaration, staging, commit, abort).
:mod:`~commission.infra.files.locks`
    The per-output lock file and its holder line.
:mod:`~commission.infra.files.atomic`
    The all-or-nothing moves of the commit and :data:`WRITE_ERRNOS`.
:mod:`~commission.infra.files.signals`
    SIGINT and SIGTERM held during a commit or an abort.
:mod:`~commission.infra.files.registry`
    The outputs open and committed in this process (asked by the CLI).
:mod:`~commission.infra.files.target`
    One declared output and its lock, staging and backup state.
"""

from commission.infra.files.atomic import WRITE_ERRNOS
from commission.infra.files.inputs import (MAX_JSON_BYTES, MAX_LOG_BYTES, MAX_TOML_BYTES, check_input_file,
                                     read_input_bytes, read_toml)
from commission.infra.files.outputs import Outputs, same_file
from commission.infra.files.registry import abort_unfinished, committed_outputs, forget_commits, unfinished

__all__ = ["MAX_LOG_BYTES", "MAX_JSON_BYTES", "MAX_TOML_BYTES", "check_input_file", "read_input_bytes",
           "read_toml", "same_file", "Outputs", "WRITE_ERRNOS", "committed_outputs", "forget_commits",
           "unfinished", "abort_unfinished"]
