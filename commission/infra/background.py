"""Run one independent piece of output work in a child process while the pipeline goes on.

``commission run`` draws the identification figures (all of it in matplotlib, which holds
the interpreter lock) while the tuning and validation run:
:class:`ChildJob` forks a process that calls the writer and sends back its return value.
The child touches nothing but the files the writer writes; the parent collects the result
(or re-raises the child's error) before it moves any file into place, and stops the child
if a stage fails first.

A job may also hand back several results in turn (``steps``; the function is then a
generator): ``run`` identifies the log in the child, sends the outcome back as soon as it is
there, and draws its figures from it while the parent tunes.  The parent meanwhile loads
what the tuning needs, so the two overlap on a machine with two cores.

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


def _child(send: Any, fn: Callable[..., Any], args: tuple, steps: int) -> None:
    # The parent blocked these signals around the fork: reset their handlers, then let them in, so
    # that no signal reaches the inherited handler; a stopped child ends quietly (its files are not kept).
    for sig in _DEFAULT_IN_CHILD:
        signal.signal(sig, signal.SIG_DFL)
    signal.pthread_sigmask(signal.SIG_UNBLOCK, _DEFAULT_IN_CHILD)
    try:
        out = fn(*args)
        for value in (out if steps > 1 else (out,)):  # a generator's values as they come
            send.send(("ok", value))
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
        Writes files and returns something picklable (a list of paths); with ``steps`` > 1
        a generator function that yields ``steps`` picklable values.
    *args
        Its arguments (inherited by the fork, not pickled).
    steps : int, optional
        How many values ``fn`` hands back; :meth:`result` returns the next one per call, in the
        order they were yielded.  Default 1: ``fn``'s return value.
    """

    def __init__(self, fn: Callable[..., Any], *args: Any, steps: int = 1) -> None:
        self._fn, self._args, self._steps = fn, args, steps
        self._proc: Any = None
        self._gen: Any = None  # without fork: the generator, advanced one step per result()
        # A daemonic process (a Dask worker running a fleet's axis) may not start children.
        if sys.platform.startswith("linux") and not mp.current_process().daemon:
            ctx = mp.get_context("fork")
            self._recv, send = ctx.Pipe(duplex=False)
            self._proc = ctx.Process(target=_child, args=(send, fn, args, steps), daemon=True)
            held = signal.pthread_sigmask(signal.SIG_BLOCK, _DEFAULT_IN_CHILD)  # until the child resets them
            try:
                self._proc.start()
            finally:
                signal.pthread_sigmask(signal.SIG_SETMASK, held)
            send.close()

    def result(self) -> Any:
        """The writer's return value (its next value, with ``steps``); its exception, re-raised, if it failed.

        After the last value or an error the child has ended and no further call is allowed.
        """
        if self._proc is None:
            if self._steps == 1:
                return self._fn(*self._args)
            if self._gen is None:
                self._gen = self._fn(*self._args)
            return next(self._gen)
        self._steps -= 1
        try:
            status, value = self._recv.recv()
        except EOFError:
            status, value = "error", RuntimeError(
                f"the figure process ended without a result (exit code {self._proc.exitcode})")
        # (A signal raised while waiting leaves the child to cancel(), which stops it instead of waiting.)
        if status == "error" or self._steps == 0:  # the child has ended or is ending
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
