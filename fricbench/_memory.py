"""Memory this process may still take, and a check that refuses a request before allocating it.

The figure is the machine's available memory (``MemAvailable`` of ``/proc/meminfo`` on Linux,
else ``os.sysconf`` free pages), lowered by the address-space limit (``ulimit -v``) and by a
cgroup memory limit when either is set. A size argument whose estimated need exceeds it
raises ``ValueError`` at once, naming the argument, the bytes needed and the bytes available,
instead of failing with ``MemoryError`` (or the OOM killer) after minutes of work.
"""

from __future__ import annotations

import os
from collections.abc import Callable
from pathlib import Path

__all__ = ["available_memory", "check_memory", "format_bytes"]


def _read(path: str | Path) -> str | None:
    try:
        with open(path, encoding="ascii") as fh:
            return fh.read(4096)
    except (OSError, ValueError):
        return None


def _machine() -> tuple[int, str] | None:
    text = _read("/proc/meminfo")
    if text:
        for line in text.splitlines():
            if line.startswith("MemAvailable:"):
                return int(line.split()[1]) * 1024, "available memory"
    try:
        pages, size = os.sysconf("SC_AVPHYS_PAGES"), os.sysconf("SC_PAGE_SIZE")
    except (AttributeError, ValueError, OSError):
        return None
    return (pages * size, "free memory") if pages > 0 and size > 0 else None


def _address_space() -> int | None:
    """Room left under ``ulimit -v``, bytes (None when unlimited or unknown)."""
    try:
        import resource

        soft = resource.getrlimit(resource.RLIMIT_AS)[0]
        if soft == resource.RLIM_INFINITY:
            return None
        statm = _read("/proc/self/statm")
        used = int(statm.split()[0]) * os.sysconf("SC_PAGE_SIZE") if statm else 0
    except (ImportError, AttributeError, ValueError, OSError):
        return None
    return max(soft - used, 0)


def _cgroup() -> int | None:
    """Room left under the cgroup memory limit of this process or its parents, bytes (v2
    ``memory.max``, v1 ``memory.limit_in_bytes``; None when unlimited or unknown)."""
    text = _read("/proc/self/cgroup") or ""
    room = None
    for line in text.splitlines():
        _, controllers, path = line.split(":", 2) if line.count(":") >= 2 else ("", "", "")
        if controllers == "":  # v2: 0::/path
            root, files = Path("/sys/fs/cgroup"), ("memory.max", "memory.current")
        elif "memory" in controllers.split(","):
            root, files = Path("/sys/fs/cgroup/memory"), ("memory.limit_in_bytes",
                                                          "memory.usage_in_bytes")
        else:
            continue
        folder = root / path.strip().lstrip("/")
        for where in (folder, *folder.parents):
            if not where.is_relative_to(root):
                break
            limit, current = _read(where / files[0]), _read(where / files[1])
            if limit and current and limit.strip().isdigit() and current.strip().isdigit() \
                    and int(limit) < 2**60:  # v1 writes "unlimited" as about 2**63
                left = max(int(limit) - int(current), 0)
                room = left if room is None else min(room, left)
    return room


def available_memory() -> tuple[int, str] | None:
    """Bytes this process can still allocate and what limits them (None if unknown)."""
    best = _machine()
    for room, what in ((_address_space(), "address-space limit, ulimit -v"),
                       (_cgroup(), "cgroup memory.max")):
        if room is not None and (best is None or room < best[0]):
            best = (room, what)
    return best


def format_bytes(n: float) -> str:
    """``1.5 GB``-style (decimal units)."""
    for unit, size in (("TB", 1e12), ("GB", 1e9), ("MB", 1e6), ("kB", 1e3)):
        if n >= size:
            return f"{n / size:.3g} {unit}"
    return f"{n:.0f} B"


def check_memory(argument: str, needed: float, detail: str,
                 fix: Callable[[int], str]) -> None:
    """Raise ``ValueError`` if ``needed`` bytes exceed :func:`available_memory`.

    Parameters
    ----------
    argument : str
        The argument asking for the memory, with its value (``"num_envs=10000000"``).
    needed : float
        Estimated bytes.
    detail : str
        How the estimate is made (``"1.5 kB per sub-env"``).
    fix : callable
        ``fix(available_bytes)``: what to pass instead (``"num_envs <= 5000000"``).
    """
    avail = available_memory()
    if avail is None or needed <= avail[0]:
        return
    room, what = avail
    raise ValueError(f"{argument}: needs about {format_bytes(needed)} of memory ({detail}) but "
                     f"{format_bytes(room)} is available ({what}); expected {fix(room)}")
