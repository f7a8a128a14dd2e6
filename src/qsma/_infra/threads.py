"""BLAS thread control.

The contact solvers and the two-body combination work on many small dense
matrices. Multithreaded OpenBLAS on such matrices is slower than one thread, and
on a machine whose cores are busy it can be 20-40 times slower (spinning threads;
measured with benchmarks/bench_analysis.py: sandwich-2d contact ramp 1.1 s with
2 threads on a loaded 2-core machine, 0.03 s with 1). Below
:data:`SMALL_PROBLEM` interface unknowns qsma therefore runs BLAS single-threaded.

The sparse direct solves are parallel in another way: scipy's SuperLU releases the
GIL in its triangular solves, so the columns of a multi-RHS solve are split into
blocks solved by Python threads at once (:func:`qsma.reduction.schur.solved_by_columns`).
:func:`solve_threads` gives their number: the environment variable
:data:`SOLVE_THREADS_ENV` if set, else ``min(2, cores)``.
"""
from __future__ import annotations

from contextlib import contextmanager
import numbers
import os
import threading

from ..errors import InputError

#: Interface unknowns (pairs x dim) up to which BLAS is limited to one thread.
SMALL_PROBLEM = 2000


@contextmanager
def blas_threads(limit):
    """Limit BLAS threads to ``limit`` inside the block (``None``: leave as is)."""
    if limit is None:
        yield
        return
    from threadpoolctl import threadpool_limits
    with threadpool_limits(limits=limit, user_api="blas"):
        yield


_ONE_THREAD = {"depth": 0, "limit": None, "controller": None}
_ONE_THREAD_LOCK = threading.Lock()


@contextmanager
def one_blas_thread():
    """BLAS limited to one thread inside the block, for the sparse direct solves and
    factorisations (SuperLU calls BLAS on small supernode blocks, where the threads of
    a multithreaded OpenBLAS only spin: a 12-column solve of the sandwich-3d refine-1
    factor took 506 ms with two OpenBLAS threads and 66 ms with one, on a loaded
    2-core machine). The limit is process-wide (threadpoolctl); nested or concurrent
    blocks share it, the last one out restores the previous setting. A cached
    controller makes entering cheap (0.04 ms, where ``threadpool_limits`` rescans the
    loaded libraries: 2.7 ms). A caller's own ``threadpool_limits`` in another thread
    that is entered inside this block and left after it leaves BLAS at one thread
    (each restores what it found): the two must nest. Only the speed is affected."""
    with _ONE_THREAD_LOCK:
        if _ONE_THREAD["depth"] == 0:
            if _ONE_THREAD["controller"] is None:
                from threadpoolctl import ThreadpoolController
                _ONE_THREAD["controller"] = ThreadpoolController()
            limit = _ONE_THREAD["controller"].limit(limits=1, user_api="blas")
            _ONE_THREAD["limit"] = limit
        _ONE_THREAD["depth"] += 1
    try:
        yield
    finally:
        with _ONE_THREAD_LOCK:
            _ONE_THREAD["depth"] -= 1
            if _ONE_THREAD["depth"] == 0:
                _ONE_THREAD["limit"].restore_original_limits()
                _ONE_THREAD["limit"] = None


def threads_for(n_unknowns: int):
    """The BLAS thread limit for an interface problem of ``n_unknowns`` unknowns."""
    return 1 if n_unknowns <= SMALL_PROBLEM else None


#: BLAS threads of the contact ramps and loops under ``blas_threads="auto"``, whatever
#: the interface size. Their dense work is many small products and factorisations of
#: zone blocks plus the symmetric products of the checks (memory-bound: 10.3 against
#: 8.0-9.1 ms at 6,435 unknowns on two threads), on which a second OpenBLAS thread
#: mostly spins: sandwich-3d refine 2, quiet machine, contact stage 110.5 s wall /
#: 218.7 s CPU on two BLAS threads against 64.8 / 64.8 s on one (docs/performance.md,
#: "BLAS threads"). The condensation's dense products keep the
#: process's threads (50.4 against 64.0 s there).
CONTACT_BLAS_THREADS = 1


#: Environment variable with the number of threads of a multi-RHS sparse solve
#: (a positive integer; 1: serial).
SOLVE_THREADS_ENV = "QSMA_SOLVE_THREADS"
#: Default thread count of a multi-RHS solve at most (fewer on a machine with fewer
#: usable cores): two threads took 0.62 of the wall time on an idle 2-core machine. On a
#: machine whose other cores are busy, one thread is faster (docs/performance.md, "Solve
#: threads"): set the variable to 1 there.
DEFAULT_SOLVE_THREADS = 2


def usable_cores() -> int:
    """Cores this process may run on (its CPU affinity where the OS tells it)."""
    try:
        return len(os.sched_getaffinity(0))
    except (AttributeError, OSError):
        return os.cpu_count() or 1


def solve_threads(value=None) -> int:
    """The number of threads of a multi-RHS sparse solve: ``value`` if given, else the
    environment variable :data:`SOLVE_THREADS_ENV`, else
    ``min(DEFAULT_SOLVE_THREADS, usable cores)``.

    Raises
    ------
    InputError
        ``value`` (or the variable) is not a positive integer.
    """
    source = "solve threads"
    if value is None:
        value = os.environ.get(SOLVE_THREADS_ENV)
        source = f"environment variable {SOLVE_THREADS_ENV}"
        if value is None or value.strip() == "":
            return max(1, min(DEFAULT_SOLVE_THREADS, usable_cores()))
        try:
            value = int(value.strip())
        except ValueError:
            raise InputError(f"{source} must be a positive integer, got {value!r}; "
                             f"unset it or set e.g. {SOLVE_THREADS_ENV}=2") from None
    if isinstance(value, bool) or not isinstance(value, numbers.Integral) or value < 1:
        raise InputError(f"{source} must be a positive integer, got {value!r} (1 solves "
                         f"serially)")
    return int(value)
