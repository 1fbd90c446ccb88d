"""One BLAS thread for small dense problems, without re-scanning the loaded libraries each time.

The stability margins, box checks and evidence bounds solve thousands of small dense
problems (a 10-state Schur form, a 12 x 12 eigenvalue problem); BLAS threads cost more
than they gain there, so they run with BLAS on one thread.  ``threadpoolctl.threadpool_limits``
finds the BLAS libraries of the process anew on every call (walking every loaded shared
object), which a search pays hundreds of times; :func:`one_blas_thread` finds them once
(:class:`threadpoolctl.ThreadpoolController`, built at first use, when numpy and scipy's
libraries are loaded) and only sets and restores the limit.
"""

from __future__ import annotations

import functools
import threading
from typing import Any, Callable, TypeVar

F = TypeVar("F", bound=Callable[..., Any])

_lock = threading.Lock()
_controller: Any = None


def one_blas_thread() -> Any:
    """A context manager: BLAS (and OpenMP) pools limited to one thread inside, restored after."""
    global _controller
    if _controller is None:
        with _lock:
            if _controller is None:
                import numpy.linalg  # noqa: F401  (numpy's and scipy's BLAS loaded before the one scan)
                import scipy.linalg  # noqa: F401
                from threadpoolctl import ThreadpoolController
                _controller = ThreadpoolController()
    return _controller.limit(limits=1)


def on_one_blas_thread(fn: F) -> F:
    """Decorator: ``fn`` runs inside :func:`one_blas_thread`.

    For whole stages (tune, validate) whose parallel work is the compiled closed loop on the
    executor's threads, and whose BLAS calls are all small (a 4 x 4 matrix exponential per
    gain set, a 17 x 17 eigenvalue problem per loop): with BLAS threads there, every such call
    wakes threads that then spin on the cores the simulations run on (a 4 x 4 ``expm`` took
    40 times longer with them).
    """
    @functools.wraps(fn)
    def wrapped(*args: Any, **kwargs: Any) -> Any:
        with one_blas_thread():
            return fn(*args, **kwargs)

    return wrapped  # type: ignore[return-value]


__all__ = ["on_one_blas_thread", "one_blas_thread"]
