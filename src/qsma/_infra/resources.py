"""Resources used by this process: peak resident memory and CPU time.

The peak resident set size (RSS) counts every allocation that touched physical
memory, including those of the C and Fortran libraries (SuperLU, BLAS, METIS), which
:mod:`tracemalloc` does not see. Sources, by platform:

* Linux: ``VmHWM`` of ``/proc/self/status`` (kB), which :func:`reset_peak` can lower
  to the current RSS (``/proc/self/clear_refs``), so a stage can be measured alone;
* other POSIX systems: ``resource.getrusage(RUSAGE_SELF).ru_maxrss`` (bytes on macOS,
  kB elsewhere); it never decreases;
* Windows: ``None`` (not measured).
"""
from __future__ import annotations

import os
import sys
import time

_MB = 2.0**20


def _status_kb(key):
    """A ``kB`` field of ``/proc/self/status`` (``None`` if unreadable)."""
    try:
        with open("/proc/self/status") as f:
            for line in f:
                if line.startswith(key + ":"):
                    return int(line.split()[1])
    except (OSError, ValueError, IndexError):
        pass
    return None


def free_memory() -> int | None:
    """Available physical memory in bytes (Linux ``MemAvailable``, which counts the
    reclaimable page cache; else the free pages), ``None`` where the system does not say.
    The limits that refuse a model or a study too large to hold are derived from it."""
    try:
        with open("/proc/meminfo") as f:
            for line in f:
                if line.startswith("MemAvailable:"):
                    return int(line.split()[1]) * 1024
    except (OSError, ValueError, IndexError):
        pass
    try:
        return os.sysconf("SC_AVPHYS_PAGES") * os.sysconf("SC_PAGE_SIZE")
    except (AttributeError, ValueError, OSError):
        return None


def peak_memory_mb() -> float | None:
    """Peak resident memory of this process in MiB since its start (or since the last
    :func:`reset_peak`), ``None`` where the platform does not report it."""
    kb = _status_kb("VmHWM")
    if kb is not None:
        return kb / 1024.0
    try:
        import resource
    except ImportError:                     # Windows
        return None
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    return peak / _MB if sys.platform == "darwin" else peak / 1024.0


def current_memory_mb() -> float | None:
    """Current resident memory in MiB (Linux only, else ``None``)."""
    kb = _status_kb("VmRSS")
    return None if kb is None else kb / 1024.0


def reset_peak() -> bool:
    """Lower the peak (Linux ``VmHWM``) to the current resident memory, so that the
    next :func:`peak_memory_mb` covers what follows. Returns whether it worked."""
    try:
        with open("/proc/self/clear_refs", "w") as f:
            f.write("5")
        return True
    except OSError:
        return False


def children_peak_memory_mb() -> float | None:
    """The largest peak resident memory of a child process that has ended (the -alpha
    ramp beside the +alpha one, loop workers), MiB; ``None`` on Windows. A forked
    child counts the pages it shares with this process and touched."""
    try:
        import resource
    except ImportError:                     # Windows
        return None
    peak = resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss
    return peak / _MB if sys.platform == "darwin" else peak / 1024.0


def cpu_with_children_s() -> float:
    """CPU seconds of this process (all threads) and of its child processes that have
    ended (the forked -alpha ramp, loop workers): the CPU a run cost."""
    times = os.times()
    return time.process_time() + times.children_user + times.children_system


def snapshot() -> dict:
    """``{"peak_memory_mb", "cpu_s", "children_peak_memory_mb", "children_cpu_s"}``:
    peak resident memory (MiB, rounded to 0.1, or ``None``) and the CPU time of the
    process so far (user + system, all threads, in seconds); the same for the child
    processes that have ended (:func:`children_peak_memory_mb`; their CPU seconds)."""
    peak = peak_memory_mb()
    child = children_peak_memory_mb()
    times = os.times()
    return {"peak_memory_mb": None if peak is None else round(peak, 1),
            "cpu_s": round(time.process_time(), 3),
            "children_peak_memory_mb": None if child is None else round(child, 1),
            "children_cpu_s": round(times.children_user + times.children_system, 3)}


__all__ = ["peak_memory_mb", "current_memory_mb", "reset_peak", "snapshot",
           "children_peak_memory_mb", "cpu_with_children_s"]
