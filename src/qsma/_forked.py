"""Work on a second process that inherits this one: the ``fork`` start method.

Two parts of a run are independent given what came before them and are worth a second
core: the loops of the levels (:func:`qsma.hysteresis.map_loops`) and the -alpha ramp,
which can be solved while the last refinement round of the +alpha ramp runs
(:class:`qsma.analysis._NegativeRamp`). A forked child inherits the contact problem,
the reduced model and the states as they are (nothing of them is pickled); only its
answer comes back through a pipe, with the warnings it raised.

Forking is refused (:func:`fork_refusal`) where it is not available or not safe; the
callers then do the same work in this process, with the same results.
"""
from __future__ import annotations

import logging
import multiprocessing
import os
import threading
import warnings

log = logging.getLogger("qsma")


def parallel_available() -> bool:
    """Whether worker processes can inherit a job (the ``fork`` start method)."""
    return "fork" in multiprocessing.get_all_start_methods()


def usable_cores() -> int:
    """Cores this process may run on (its CPU affinity where the platform tells it)."""
    if hasattr(os, "sched_getaffinity"):
        return max(1, len(os.sched_getaffinity(0)))
    return max(1, os.cpu_count() or 1)


def fork_refusal() -> str | None:
    """``None`` if this call may fork, else why not: the ``fork`` start method must
    exist (not on Windows); a daemonic process (a Dask or multiprocessing worker) may
    not have children; and only the main thread forks, so that no other thread of this
    process is copied half-way through holding a lock."""
    if not parallel_available():
        return "the fork start method is not available"
    if multiprocessing.current_process().daemon:
        return "this is a daemonic process (e.g. a sweep worker), which may not fork"
    if threading.current_thread() is not threading.main_thread():
        return "this is not the main thread of the process"
    return None


def recorded_warnings(seen) -> list:
    """Warnings caught by ``warnings.catch_warnings(record=True)`` in a form that
    crosses a pipe: ``(text, category, filename, lineno)``."""
    return [(str(w.message), w.category, w.filename, w.lineno) for w in seen]


def raise_again(raised):
    """Raise in this process the warnings a child recorded (:func:`recorded_warnings`),
    through this process's filters."""
    for text, category, filename, lineno in raised:
        warnings.warn_explicit(text, category, filename, lineno)


class ChildFailed(RuntimeError):
    """A forked call that did not deliver its value (it raised, or its process died)."""


class ForkedCall:
    """``job()`` started now on a forked child process; :meth:`result` waits for it.

    The child runs ``job`` with every warning recorded and sends ``(value, warnings)``
    back; :meth:`result` raises the warnings again here and returns the value, or
    raises :class:`ChildFailed` if the child raised or died before answering (the
    caller can then do the work itself, where the real exception, if any, comes out
    with its traceback). :meth:`cancel` kills the child. Use only after
    :func:`fork_refusal` returned None.
    """

    def __init__(self, job):
        ctx = multiprocessing.get_context("fork")
        self._receive, send = ctx.Pipe(duplex=False)
        self._process = ctx.Process(target=_child, args=(job, send), daemon=True)
        self._process.start()
        send.close()                    # the child holds the only writing end now

    def result(self):
        try:
            try:
                kind, value, raised = self._receive.recv()
            except (EOFError, OSError) as exc:
                self._process.join(timeout=60)          # its exit code, once reaped
                raise ChildFailed(f"the child process ended without an answer "
                                  f"(exit code {self._process.exitcode})") from exc
            if kind != "ok":
                raise ChildFailed(f"the child process raised {value}")
            raise_again(raised)
            return value
        finally:
            self.cancel()

    def cancel(self):
        """Stop the child (if still running) and release it."""
        if self._process.is_alive():
            self._process.kill()
        self._process.join()
        self._receive.close()


def _child(job, send):
    try:
        with warnings.catch_warnings(record=True) as seen:
            warnings.simplefilter("always")
            value = job()
        message = ("ok", value, recorded_warnings(seen))
    except BaseException as exc:         # reported to the parent, which does the work
        message = ("error", repr(exc), [])
    try:
        send.send(message)
    finally:
        send.close()
