"""One line on stderr when numba compiles the simulation kernel (a cold on-disk cache).

The kernel (:mod:`fricbench.axis`, :mod:`fricbench.gym`, :mod:`fricbench.friction`) is compiled
by numba with ``cache=True``: the first run after an install or an edit compiles it (about 15 s
for ``simulate``, 20 s for the vector env), every later run loads it from disk in a fraction of
a second. numba announces a real compilation with its ``numba:compile`` event, which a load
from the cache does not raise: the listener here prints :data:`MESSAGE` at the first such event
of a kernel function, once per process, and nothing when the cache is warm.
"""

from __future__ import annotations

import sys

from numba.core import event

__all__ = ["MESSAGE", "announce_compiles"]

MESSAGE = "fricbench: compiling the simulation kernel (first run only, ~20 s)..."
"""What is printed to stderr when the kernel compiles."""

_KERNEL_MODULES = ("fricbench.axis.", "fricbench.gym.", "fricbench.friction.")


class _CompileNotice(event.Listener):
    """Prints :data:`MESSAGE` at the first compilation of a kernel function."""

    def __init__(self) -> None:
        self.announced = False

    def on_start(self, ev: event.Event) -> None:
        if self.announced:
            return
        data = ev.data if isinstance(ev.data, dict) else {}
        func = getattr(data.get("dispatcher"), "py_func", None)
        if str(getattr(func, "__module__", "")).startswith(_KERNEL_MODULES):
            self.announced = True
            print(MESSAGE, file=sys.stderr, flush=True)

    def on_end(self, ev: event.Event) -> None:
        pass


_notice = _CompileNotice()
_installed = False


def announce_compiles() -> None:
    """Listen for numba compiling the kernel (idempotent; done by ``import fricbench``)."""
    global _installed
    if not _installed:
        event.register("numba:compile", _notice)
        _installed = True
