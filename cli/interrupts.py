"""Where a signal's exception may be raised, and putting it off until then.

Python runs a signal handler in the main thread at the next bytecode it
executes.  When the signal arrives while compiled numba code runs, that next
bytecode is usually a call the compiled code makes back into Python on its way
out (``numba.core.serialize._numba_unpickle`` fetching a constant to box the
result).  An exception raised there is not one the compiled code checks for: it
comes out as a SystemError, or the process dies with SIGSEGV, leaving its staged
outputs and locks behind.  The same holds for numba's own Python code while it
compiles or loads a kernel, whose state an exception half-way leaves broken.

So the CLI's handler asks :func:`in_compiled_code` first, and while numba's Python
code is on the stack it does not raise: :func:`redeliver` sends the signal to the
main thread again a moment later, by which time the compiled call has returned
(or the compiler has moved on) and the exception is raised in the tool's own code.
The delay a user sees is the remainder of one kernel call or one compilation.
"""

from __future__ import annotations

import os
import signal
import sys
import threading
from types import FrameType

#: Seconds before a put-off signal is sent again (long enough for a kernel's epilogue to finish).
REDELIVER_AFTER = 0.02


def in_compiled_code(frame: FrameType | None) -> bool:
    """Whether ``frame`` or a caller of it is numba's Python code (a callback from a kernel, the compiler).

    Parameters
    ----------
    frame : frame or None
        The frame a signal handler was given (None: called from Python code directly).
    """
    numba = sys.modules.get("numba")
    if frame is None or numba is None or not getattr(numba, "__file__", None):
        return False  # no numba imported: no kernel can be running
    root = os.path.dirname(numba.__file__) + os.sep
    f: FrameType | None = frame
    while f is not None:
        if f.f_code.co_filename.startswith(root):
            return True
        f = f.f_back
    return False


def redeliver(signum: int) -> None:
    """Send ``signum`` to the main thread again after :data:`REDELIVER_AFTER` seconds."""
    main = threading.main_thread().ident
    if main is None:
        return
    t = threading.Timer(REDELIVER_AFTER, signal.pthread_kill, (main, signum))
    t.daemon = True  # a signal the process no longer needs must not keep it alive
    t.start()


__all__ = ["in_compiled_code", "redeliver", "REDELIVER_AFTER"]
