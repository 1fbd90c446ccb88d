"""Run one independent piece of output work in a child process while the pipeline goes on.

``commission run`` draws the identification figures (all of it in matplotlib, which holds
the interpreter lock) while the tuning and validation run:
:class:`ChildJob` forks a process that calls the writer and sends back its return value.
The child touches nothing but the files the writer writes; the parent collects the result
(or re-raises the child's error) before it moves any file into place, and stops the child
if a stage fails first.

Where ``fork`` is not available (Windows; macOS defaults to ``spawn``, which would re-import
and pickle everything) the writer runs in the parent when the result is asked for, exactly
as before.  Why not a thread: matplotlib's drawing holds the GIL, so a thread would only
interleave with the tuning, not run beside it.
"""

from __future__ import annotations

import multiprocessing as mp
import signal
import sys
from typing import Any, Callable

#: The signals whose handlers the child does not inherit: the CLI's handlers raise in the main
#: thread to write nothing half-done, which in the child (stopped by :meth:`ChildJob.cancel`, or
#: sent the terminal's Ctrl-C beside its parent) would print a traceback from wherever it was.
_DEFAULT_IN_CHILD = (signal.SIGINT, signal.SIGTERM)


def _child(send: Any, fn: Callable[..., Any], args: tuple) -> None:
    # The parent blocked these signals around the fork: reset their handlers, then let them in, so
    # that no signal reaches the inherited handler; a stopped child ends quietly (its files are not kept).
    for sig in _DEFAULT_IN_CHILD:
        signal.signal(sig, signal.SIG_DFL)
    signal.pthread_sigmask(signal.SIG_UNBLOCK, _DEFAULT_IN_CHILD)
    try:
        out = fn(*args)
        send.send(("ok", out))
    except BaseException as exc:  # reported to the parent, which raises it
        try:
            send.send(("error", exc))
        except Exception:  # an exception that does not pickle: its text
            send.send(("error", RuntimeError(f"{type(exc).__name__}: {exc}")))
    finally:
        send.close()


class ChildJob:
    """``fn(*args)`` in a forked child process; :meth:`result` waits for it.

    Parameters
    ----------
    fn : callable
        Writes files and returns something picklable (a list of paths).
    *args
        Its arguments (inherited by the fork, not pickled).
    """

    def __init__(self, fn: Callable[..., Any], *args: Any) -> None:
        self._fn, self._args = fn, args
        self._proc: Any = None
        # A daemonic process (a Dask worker running a fleet's axis) may not start children.
        if sys.platform.startswith("linux") and not mp.current_process().daemon:
            ctx = mp.get_context("fork")
            self._recv, send = ctx.Pipe(duplex=False)
            self._proc = ctx.Process(target=_child, args=(send, fn, args), daemon=True)
            held = signal.pthread_sigmask(signal.SIG_BLOCK, _DEFAULT_IN_CHILD)  # until the child resets them
            try:
                self._proc.start()
            finally:
                signal.pthread_sigmask(signal.SIG_SETMASK, held)
            send.close()

    def result(self) -> Any:
        """The writer's return value; its exception, re-raised, if it failed."""
        if self._proc is None:
            return self._fn(*self._args)
        try:
            status, value = self._recv.recv()
        except EOFError:
            status, value = "error", RuntimeError(
                f"the figure process ended without a result (exit code {self._proc.exitcode})")
        finally:
            self._proc.join()
            self._recv.close()
        if status == "error":
            raise value
        return value

    def cancel(self) -> None:
        """Stop the child (a stage failed: its files will not be kept)."""
        if self._proc is not None and self._proc.is_alive():
            self._proc.terminate()
            self._proc.join()


__all__ = ["ChildJob"]
