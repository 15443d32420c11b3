"""One BLAS thread for the small dense solves of the fits.

The fits call dense linear algebra on small problems between parallel numba simulations: the
SVD of a 10,000 x 10 Jacobian in each step of :func:`scipy.optimize.least_squares`, the
exponential of a 5 x 5 matrix in each first-order hold. OpenBLAS runs them on its thread pool,
and on a loaded machine (other processes, or numba's workers still spinning after a parallel
region) each call then waits for its threads. Measured on the shared 2-core machine at a load
average of 5: that SVD 67 ms instead of about 2 ms, that exponential 3.5 ms instead of 30 us.
With one thread the library solvers run as fast as the hand-written ones they replaced
(``python -m fricbench.bench.solver_benchmark``).
"""

from __future__ import annotations

import contextlib
import functools
import threading
from collections.abc import Iterator
from typing import Any

import scipy.linalg  # noqa: F401  (loads scipy's BLAS before the controller looks for it)
from threadpoolctl import ThreadpoolController

__all__ = ["one_blas_thread"]


@functools.cache
def _controller() -> ThreadpoolController:
    # finding the loaded libraries takes milliseconds: once per process
    return ThreadpoolController()


# The limit is the process's (BLAS has one thread count): contexts entered from several
# threads share it, set by the first one in and lifted by the last one out. Each thread
# restoring what it found would lift it under another that is still inside.
class _Held:
    lock = threading.Lock()
    limiter: Any = None
    depth = 0


@contextlib.contextmanager
def one_blas_thread() -> Iterator[None]:
    """Context in which numpy's and scipy's BLAS and LAPACK calls use one thread (for
    every thread of the process while any thread is inside one)."""
    with _Held.lock:
        if _Held.depth == 0:
            _Held.limiter = _controller().limit(limits=1, user_api="blas")
        _Held.depth += 1
    try:
        yield
    finally:
        with _Held.lock:
            _Held.depth -= 1
            if _Held.depth == 0:
                _Held.limiter.restore_original_limits()
                _Held.limiter = None
