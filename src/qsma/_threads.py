"""BLAS thread control.

The contact solvers and the two-body combination work on many small dense
matrices. Multithreaded OpenBLAS on such matrices is slower than one thread, and
on a machine whose cores are busy it can be 20-40 times slower (spinning threads;
measured with benchmarks/bench_analysis.py: sandwich-2d contact ramp 1.1 s with
2 threads on a loaded 2-core machine, 0.03 s with 1). Below
:data:`SMALL_PROBLEM` interface unknowns qsma therefore runs BLAS single-threaded.
"""
from __future__ import annotations

from contextlib import contextmanager

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


def threads_for(n_unknowns: int):
    """The BLAS thread limit for an interface problem of ``n_unknowns`` unknowns."""
    return 1 if n_unknowns <= SMALL_PROBLEM else None
