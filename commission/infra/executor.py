"""One interface for the independent pieces of parallel work: local threads or a Dask cluster.

Every parallel stage that ships work out (``validate``'s scenarios and Monte-Carlo plants,
``fleet``'s axes) calls :meth:`Executor.map` with a module-level function, one shared
context and a list of task items.  Two engines sit behind it:

* :class:`LocalExecutor` (the default): a thread pool with one thread per CPU, what the
  tool always did (the numba closed loop releases the GIL, so threads run on every core).
  It imports neither ``dask`` nor ``distributed``.
* :class:`DaskExecutor`: a ``dask.distributed`` cluster, asked for with
  ``--scheduler tcp://HOST:PORT``, the ``COMMISSION_SCHEDULER`` environment variable or
  ``[compute] scheduler`` in spec.toml (:func:`resolve_scheduler`: in that order).  Needs the
  optional extra ``pip install ".[dask]"``.

Why the answer does not depend on the engine
--------------------------------------------
* A task is a pure function of (shared context, item): any random draw it needs is made
  from a seed that belongs to the *task* (validate's Monte-Carlo plants are drawn on the
  client from ``default_rng(seed)`` in plant order and shipped in the task; encoder noise
  is seeded by the scenario's name), never from a worker's state.
* :meth:`Executor.map` yields the results **in task order**, whatever order they finish
  in, so every reduction downstream (quantiles, worst plants, the gate) folds them in the
  same order.  Only a bounded window of tasks is in flight or waiting to be yielded
  (:data:`WINDOW_PER_WORKER` per worker), so a long map streams: its results are not
  all held at once.

Workers and the numba kernels
-----------------------------
A Dask worker imports :mod:`commission.controllers` once; the kernels are ``cache=True``
(on-disk cache beside the sources, guarded by
:func:`commission.controllers.drop_stale_kernel_cache`), so a worker process loads them
instead of compiling them, and a worker keeps them for every later task.  The shared
context is sent once per map (as the result of one task that every task depends on, so that
a worker lost with it makes it again), not once per task.

Failures
--------
* A worker lost mid-run (a killed process, a machine that went away): the scheduler runs
  its tasks again elsewhere (Dask's ``allowed-failures``), and each task is also submitted
  with ``retries=`` :data:`TASK_RETRIES`; the map completes with the same results.
* A scheduler that cannot be reached within :data:`CONNECT_TIMEOUT_S` is a
  :class:`SchedulerError` (a :class:`commission.errors.UsageError`: exit 2) naming the address.
* ``dask`` not installed while a scheduler is asked for: a :class:`SchedulerError` naming the extra.
"""

from __future__ import annotations

import os
from concurrent.futures import FIRST_COMPLETED, ThreadPoolExecutor, wait
from typing import Any, Callable, Iterator, Mapping, Sequence

from commission.errors import UsageError

#: Environment variable naming the Dask scheduler (``tcp://HOST:PORT``).
ENV_SCHEDULER = "COMMISSION_SCHEDULER"
#: Seconds allowed to reach the scheduler before giving up (exit 2).
CONNECT_TIMEOUT_S = 5.0
#: Retries of a task whose worker failed (Dask's ``retries=``), on top of the scheduler's own rescheduling.
TASK_RETRIES = 3
#: Tasks in flight or waiting to be yielded in order, per worker thread: bounds a map's memory.
WINDOW_PER_WORKER = 4

Task = Callable[[Any, Any], Any]
Progress = Callable[[int, int], None]


class SchedulerError(UsageError):
    """A Dask scheduler was asked for and cannot be used (unreachable, or dask not installed)."""


def _check_address(address: str, source: str) -> str:
    address = address.strip()
    if not address:
        raise SchedulerError(f"{source}: empty scheduler address (expected tcp://HOST:PORT)")
    if "://" not in address:
        raise SchedulerError(f"{source} = {address!r}: expected a scheduler address such as tcp://HOST:PORT")
    return address


def compute_scheduler(data: Mapping[str, Any] | None, source: str = "spec.toml") -> str | None:
    """``[compute] scheduler`` of a parsed spec.toml (None when absent).

    ``[compute]`` takes one key, ``scheduler`` (a string, ``tcp://HOST:PORT``); it says where
    the work runs, not what is computed, so it is not part of the tuning's spec.

    Raises
    ------
    SchedulerError
        Naming ``compute.<key>``: an unknown key or a value that is not an address.
    """
    if data is None:
        return None
    table = data.get("compute")
    if table is None:
        return None
    if not isinstance(table, Mapping):
        raise SchedulerError(f"{source}: compute: expected a table, got {table!r}")
    for key in table:
        if key != "scheduler":
            raise SchedulerError(f"{source}: compute.{key}: unknown key (known in [compute]: scheduler)")
    raw = table.get("scheduler")
    if raw is None:
        return None
    if not isinstance(raw, str):
        raise SchedulerError(f"{source}: compute.scheduler = {raw!r}: expected a string such as 'tcp://HOST:PORT'")
    return _check_address(raw, f"{source}: compute.scheduler")


def resolve_scheduler(flag: str | None = None, spec_scheduler: str | None = None,
                      env: Mapping[str, str] | None = None) -> str | None:
    """The scheduler address to use: ``--scheduler``, else ``COMMISSION_SCHEDULER``, else ``[compute]``.

    None means the local executor.
    """
    env = os.environ if env is None else env
    if flag:
        return _check_address(flag, "--scheduler")
    if env.get(ENV_SCHEDULER):
        return _check_address(env[ENV_SCHEDULER], ENV_SCHEDULER)
    return spec_scheduler or None


class Executor:
    """The parallel engine of one command (see the module docstring).

    Attributes
    ----------
    kind : str
        ``"local"`` or ``"dask"``.
    workers : int
        Worker threads the map is spread over (local threads, or the cluster's total).
    address : str or None
        The scheduler's address (Dask), None locally.
    """

    kind = "local"
    address: str | None = None
    workers = 1

    def map(self, fn: Task, shared: Any, items: Sequence[Any], *,
            progress: Callable[[int], None] | None = None) -> Iterator[Any]:
        """``fn(shared, item)`` for every item; the results yielded in item order.

        Parameters
        ----------
        fn : callable(shared, item)
            A module-level function (it is pickled for a Dask worker).
        shared : object
            The context every task reads (sent once per map).
        items : sequence
            One per task.
        progress : callable(index), optional
            Called on the calling thread as each task finishes (completion order).
        """
        raise NotImplementedError

    def describe(self) -> dict[str, Any]:
        """``{"kind", "workers", "scheduler"}``, for validation.json and fleet.json (varies with the machine)."""
        return {"kind": self.kind, "workers": int(self.workers), "scheduler": self.address}

    def close(self) -> None:
        """Release the engine (a client this object opened is closed)."""

    def __enter__(self) -> "Executor":
        return self

    def __exit__(self, *exc: Any) -> None:
        self.close()


def _ordered(n: int, window: int, submit: Callable[[int], Any], wait_any: Callable[[set], tuple[set, set]],
             result: Callable[[Any], Any], progress: Callable[[int], None] | None) -> Iterator[Any]:
    """Submit at most ``window`` tasks ahead of the next one to yield; yield in task order."""
    inflight: dict[Any, int] = {}
    done: dict[int, Any] = {}
    nxt = sub = 0
    while nxt < n:
        while sub < n and sub - nxt < window:
            inflight[submit(sub)] = sub
            sub += 1
        finished, _ = wait_any(set(inflight))
        for f in finished:
            i = inflight.pop(f)
            done[i] = result(f)
            if progress is not None:
                progress(i)
        while nxt in done:
            yield done.pop(nxt)
            nxt += 1


class LocalExecutor(Executor):
    """Threads on this machine (default one per CPU); one thread runs the tasks in order, inline."""

    kind = "local"

    def __init__(self, workers: int | None = None) -> None:
        self.workers = max(1, (os.cpu_count() or 1) if workers is None else int(workers))

    def map(self, fn: Task, shared: Any, items: Sequence[Any], *,
            progress: Callable[[int], None] | None = None) -> Iterator[Any]:
        if self.workers == 1 or len(items) <= 1:
            for i, item in enumerate(items):
                out = fn(shared, item)
                if progress is not None:
                    progress(i)
                yield out
            return
        with ThreadPoolExecutor(max_workers=self.workers) as ex:
            yield from _ordered(len(items), WINDOW_PER_WORKER * self.workers,
                                lambda i: ex.submit(fn, shared, items[i]),
                                lambda fs: wait(fs, return_when=FIRST_COMPLETED),
                                lambda f: f.result(), progress)


def _context(shared: Any) -> Any:
    return shared


class DaskExecutor(Executor):
    """A ``dask.distributed`` cluster.

    Parameters
    ----------
    address : str, optional
        ``tcp://HOST:PORT`` of the scheduler; connected within :data:`CONNECT_TIMEOUT_S`.
    client : distributed.Client, optional
        An open client instead (tests, a ``LocalCluster``); it is not closed by :meth:`close`.
    retries : int
        Dask ``retries=`` of every task.
    """

    kind = "dask"

    def __init__(self, address: str | None = None, *, client: Any = None, retries: int = TASK_RETRIES,
                 timeout: float = CONNECT_TIMEOUT_S) -> None:
        try:
            import distributed
        except ImportError as exc:
            raise SchedulerError(f"scheduler {address or '(client)'}: the Dask executor needs the optional extra "
                                 f"(pip install \"commission[dask]\"): {exc}") from None
        self._own = client is None
        if client is None:
            if address is None:
                raise SchedulerError("DaskExecutor: give a scheduler address or a client")
            try:
                client = distributed.Client(address, timeout=timeout, set_as_default=False)
            except (OSError, TimeoutError, ValueError) as exc:
                raise SchedulerError(f"scheduler {address}: cannot be reached within {timeout:g} s "
                                     f"({type(exc).__name__}: {str(exc).splitlines()[0] if str(exc) else ''})"
                                     ) from None
        self.client = client
        self.address = getattr(client.scheduler, "address", address) if address is None else address
        self.retries = int(retries)
        self._distributed = distributed
        self._maps = 0

    @property
    def workers(self) -> int:  # type: ignore[override]
        return max(1, sum(self.client.nthreads().values()))

    def map(self, fn: Task, shared: Any, items: Sequence[Any], *,
            progress: Callable[[int], None] | None = None) -> Iterator[Any]:
        import uuid

        tag = f"commission-{getattr(fn, '__name__', 'task')}-{uuid.uuid4().hex[:12]}"
        # A task that returns the context, not Client.scatter: scattered data lost with its worker
        # cannot be made again, a task's result can (the scheduler holds its arguments).
        ref = self.client.submit(_context, shared, key=f"{tag}-context", pure=False, retries=self.retries)
        d = self._distributed

        def submit(i: int) -> Any:
            return self.client.submit(fn, ref, items[i], key=f"{tag}-{i}", retries=self.retries, pure=False)

        def wait_any(fs: set) -> tuple[set, set]:
            with self.client.as_current():  # this client, not a process-wide default (set_as_default=False)
                res = d.wait(list(fs), return_when="FIRST_COMPLETED")
            return set(res.done), set(res.not_done)

        try:
            yield from _ordered(len(items), WINDOW_PER_WORKER * self.workers, submit, wait_any,
                                lambda f: f.result(), progress)
        finally:
            del ref

    def close(self) -> None:
        if self._own:
            self.client.close()


def make_executor(scheduler: str | None = None, workers: int | None = None) -> Executor:
    """The executor for a resolved scheduler address (:func:`resolve_scheduler`): Dask or local threads.

    ``workers`` is the local thread count; with a scheduler the cluster decides.
    """
    if scheduler:
        return DaskExecutor(scheduler)
    return LocalExecutor(workers)


__all__ = ["ENV_SCHEDULER", "CONNECT_TIMEOUT_S", "TASK_RETRIES", "Executor", "LocalExecutor", "DaskExecutor",
           "SchedulerError", "make_executor", "resolve_scheduler", "compute_scheduler"]
