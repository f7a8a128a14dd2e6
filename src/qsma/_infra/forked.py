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

from contextlib import contextmanager
import logging
import multiprocessing
import os
import signal
import sys
import threading
import warnings

from .threads import usable_cores

log = logging.getLogger("qsma")


def parallel_available() -> bool:
    """Whether worker processes can inherit a job (the ``fork`` start method)."""
    return "fork" in multiprocessing.get_all_start_methods()


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
    if threading.active_count() > 1:
        return "other threads are running in this process"
    return None


def second_core_refusal() -> str | None:
    """``None`` if qsma may fork without being asked to (the -alpha ramp beside the
    +alpha one, two loop workers), else why not: only on Linux, where the fork of a
    process with BLAS threads is what the loop workers have done from the start
    (macOS's Accelerate BLAS, numpy's wheels there, is not known to be safe after a
    fork; there qsma forks only for an explicit ``loop_workers``), and only where this
    process may use a second core."""
    if not sys.platform.startswith("linux"):
        return "not on Linux"
    if usable_cores() < 2:
        return "this process may use a single core"
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
        self._process = ctx.Process(target=_child, args=(job, send, self._receive),
                                    daemon=True)
        with quiet_fork():
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


@contextmanager
def quiet_fork():
    """Python 3.12 warns at every fork of a process with threads (BLAS keeps some);
    the forks of qsma are made knowingly (:func:`fork_refusal`), the warning would
    only reach the caller's warnings."""
    with warnings.catch_warnings():
        warnings.filterwarnings("ignore", category=DeprecationWarning,
                                message=r".*fork\(\) may lead to deadlocks")
        yield


def default_signals():
    """In a forked child: SIGTERM back to its default action (the parent stops its
    children with it; a handler inherited from the command line, which raises
    KeyboardInterrupt to unwind the run, left an idle pool worker alive and its parent
    waiting for it) and SIGINT ignored (Ctrl-C reaches the whole process group; the
    parent handles it and stops its children)."""
    signal.signal(signal.SIGTERM, signal.SIG_DFL)
    signal.signal(signal.SIGINT, signal.SIG_IGN)


def _child(job, send, receive):
    default_signals()
    receive.close()                    # the parent's end: a write to a dead parent fails
    threading.Thread(target=_exit_with_parent, daemon=True).start()
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


def _exit_with_parent():
    """End this child when its parent ends (killed, or gone without collecting the
    answer): it would otherwise compute on, and hold what it inherited, such as the
    lock of the result folder."""
    parent = multiprocessing.parent_process()
    if parent is not None:
        parent.join()
        os._exit(1)
