"""The loops of a run's levels on several processes: forked local workers or the
workers of a Dask scheduler, the same bits as in this process."""
from __future__ import annotations

import logging
import multiprocessing
import queue
import time
import warnings

from .._infra.shipping import InBand
from .._infra.forked import (default_signals, fork_refusal, quiet_fork, raise_again,
                             recorded_warnings)
from ..errors import InputError

log = logging.getLogger("qsma")

#: How long a run waits for its loop scheduler to answer (:func:`scheduler_client`),
#: as the sweep waits for its own.
SCHEDULER_TIMEOUT = "20s"
#: The job of the worker processes of :func:`map_loops` (inherited at the fork).
_JOB = None


def _call_job(i):
    """``_JOB(i)`` and the warnings it raised, for the parent to raise again."""
    return _call_shipped(_JOB, i)


def map_loops(job, indices, workers=1, done=None, scheduler=None) -> list:
    """``[job(i) for i in indices]``, on ``workers`` processes when ``workers > 1``, or
    on the workers of the Dask scheduler at the address ``scheduler``; ``done(j)``, if
    given, after ``j`` results are in (for progress).

    The levels' loops are independent given the backbone: each starts from the
    backbone state at its amplitude, on the ramps' contact zone, so the loop of a level
    is the same sequence of floating-point operations in whichever process solves it,
    and the results are those of the serial path bit for bit (``tests/test_lap.py``,
    ``tests/test_hysteresis.py``; on a Dask worker, as long as it runs the same numpy
    and BLAS). The largest amplitudes, whose loops take the most solves, are handed out
    first.

    Local workers are forked from this process, so ``job`` (a closure over the contact
    problem and the backbone states) is inherited, not pickled; only the level index
    goes to a worker and its :class:`Loop` comes back, with the warnings it raised
    (raised again here, in the order of ``indices``). The loops run in this process
    instead where forking is not possible or not safe
    (:func:`qsma._forked.fork_refusal`: Windows, a daemonic sweep worker, a thread
    other than the main one). An exception, or a signal handled here, stops the workers
    at once (their loops are abandoned).

    With ``scheduler``, ``job`` is pickled and sent once to every worker of the
    scheduler (:func:`_dask_map`), then each index as a task.
    """
    indices = [int(i) for i in indices]
    done = done or (lambda j: None)
    if scheduler is not None and indices:
        return _dask_map(job, indices, scheduler, done)
    workers = min(int(workers), len(indices))
    why_not = fork_refusal() if workers > 1 else None
    if why_not is not None:
        log.info("loops computed in this process, not on %d workers: %s", workers, why_not)
    if workers <= 1 or why_not is not None:
        out = []
        for i in indices:
            out.append(job(i))
            done(len(out))
        return out
    return _forked_map(job, indices, workers, done)


def _forked_map(job, indices, workers, done):
    """:func:`map_loops` on ``workers`` forked processes."""
    global _JOB
    _JOB = job
    with quiet_fork():
        pool = multiprocessing.get_context("fork").Pool(workers, initializer=default_signals)
    try:
        arrived = queue.SimpleQueue()        # (index, raised, result) as each one ends
        for i in indices[::-1]:
            pool.apply_async(_call_job, (i,),
                             callback=lambda out, i=i: arrived.put((i, False, out)),
                             error_callback=lambda exc, i=i: arrived.put((i, True, exc)))
        return _collected((arrived.get() for _ in indices), indices, done)
    finally:
        pool.terminate()        # idle workers at the end; running ones on an exception
        pool.join()
        _JOB = None


def _collected(arrivals, indices, done):
    """The results of ``indices`` from ``arrivals``, ``(index, raised, outcome)`` in
    the order the loops end (``outcome``: ``(Loop, warnings)``, or the exception it
    raised, raised here at once); ``done`` counts them as they come in, the warnings
    are raised again in the order of ``indices``."""
    got = {}
    for i, raised, outcome in arrivals:
        if raised:
            raise outcome
        got[i] = outcome
        done(len(got))
    for i in indices:
        raise_again(got[i][1])
    return [got[i][0] for i in indices]


def _dask_map(job, indices, scheduler, done):
    """:func:`map_loops` on the workers of the Dask scheduler at ``scheduler`` (an
    address such as ``tcp://host:8786``): ``job`` is scattered to every worker once
    (its contact problem and eliminations travel as they are: nothing is condensed
    there; its arrays arrive aligned, :class:`qsma._infra.shipping.InBand`), then one
    task per index, the largest amplitudes first."""
    from distributed import as_completed
    client = scheduler_client(scheduler)
    try:
        started = time.perf_counter()
        shipped = client.scatter(InBand(job), broadcast=True, hash=False)
        log.info("loops: the interface problem sent to %d Dask worker(s) in %.2f s",
                 len(client.scheduler_info()["workers"]), time.perf_counter() - started)
        order = indices[::-1]
        futures = {client.submit(_call_shipped, shipped, i, pure=False,
                                 priority=len(order) - n): i for n, i in enumerate(order)}
        arrivals = ((futures[f], False, f.result()) for f in as_completed(futures))
        return _collected(arrivals, indices, done)
    finally:
        client.close()


def scheduler_client(address):
    """A ``distributed.Client`` of the Dask scheduler at ``address``; an
    :class:`qsma.errors.InputError` naming the fix if ``distributed`` is missing or
    nothing answers there. A run checks its ``loop_scheduler`` so before its ramps."""
    try:
        from distributed import Client
    except ImportError as exc:      # dask is the optional extra 'sweep'
        raise InputError(f"loops on a Dask scheduler need the 'distributed' package "
                         f"({exc}): pip install 'qsma[sweep]', or drop the loop "
                         f"scheduler") from None
    try:
        return Client(address, timeout=SCHEDULER_TIMEOUT)
    except OSError as exc:
        raise InputError(f"cannot reach the Dask scheduler at {address!r}: {exc}; start "
                         f"one (dask scheduler) or drop --scheduler") from None


def _call_shipped(job, i):
    """``job(i)`` and the warnings it raised, for the caller to raise again (on a
    forked or a Dask worker)."""
    with warnings.catch_warnings(record=True) as seen:
        warnings.simplefilter("always")
        out = job(i)
    return out, recorded_warnings(seen)
