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

import threading
from typing import Any

_lock = threading.Lock()
_controller: Any = None


def one_blas_thread() -> Any:
    """A context manager: BLAS (and OpenMP) pools limited to one thread inside, restored after."""
    global _controller
    if _controller is None:
        with _lock:
            if _controller is None:
                from threadpoolctl import ThreadpoolController
                _controller = ThreadpoolController()
    return _controller.limit(limits=1)


__all__ = ["one_blas_thread"]
