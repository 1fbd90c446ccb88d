"""SIGINT and SIGTERM held while a set of outputs is moved into place or removed."""

from __future__ import annotations

import contextlib
import signal
import threading
from typing import Any, Iterator

@contextlib.contextmanager
def signals_held() -> Iterator[None]:
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
