"""The figures of ``qsma run`` drawn by a forked process beside the analysis.

Importing matplotlib and drawing the four PNG figures took more than half of a
sandwich-2d run's wall time on one core while the second core sat idle
(docs/performance.md, "Figures beside the analysis"). A
:class:`PlotWorker` is forked when the command starts, before the result folder is
locked and before the analysis has run a single BLAS call; it imports matplotlib and
:mod:`qsma.output.plots` while the parent computes, then waits. The parent hands it the
:class:`qsma.output.plots.PlotData` of the result (a pipe, pickled) and writes the tables and
the VTU file meanwhile; the worker draws the figures, splitting them with a second
forked process where two cores are usable, and sends back their PNG bytes.

The worker never touches the result folder: the parent writes the PNG bytes it
receives into the staging folder (atomically, as every other file), so the manifest
lists them only once they are complete. Whatever goes wrong in the worker (an
exception while drawing, a crash, a kill, a message that is not the answer), the
parent draws every figure itself, as it does without a worker, and logs why: the
files are the same either way (tests/test_plot_worker.py), only the time differs.

The worker runs only where forking is possible and safe (:func:`why_not_fork`, the
rules of every fork of qsma, :func:`qsma._infra.forked.fork_refusal`): the ``fork`` start
method exists (not on Windows), this is not a daemonic process, this is the main
thread and no other thread runs; and only when :data:`ENV` is ``1`` (off by default:
measured slower on an idle 2-core machine, see :data:`ENV`).
"""
from __future__ import annotations

import logging
import multiprocessing
import os
import pickle
import threading
import traceback
import warnings

from .._infra.forked import (default_signals, fork_refusal, quiet_fork, raise_again,
                             recorded_warnings)
from .._infra.threads import usable_cores
from ..errors import InputError

log = logging.getLogger(__name__)

#: Environment variable that switches the worker on (``1``, where the ``fork`` start
#: method exists) or off (``0`` or unset, the default). Off by default: on an idle
#: 2-core machine ``make run`` took 1.08-1.11 times the wall time with the worker
#: (``python benchmarks/bench_process.py --repeat 7``, docs/performance.md): the fork,
#: the hand-over and the second drawing process cost more than the overlap gains while
#: the -alpha ramp already takes the second core.
ENV = "QSMA_PLOT_WORKER"


def why_not_fork():
    """``None`` if a plot worker may be forked here, else the reason why not.

    Raises
    ------
    InputError
        :data:`ENV` is set to something other than ``0``, ``1`` or nothing.
    """
    value = os.environ.get(ENV, "").strip()
    if value not in ("", "0", "1"):
        raise InputError(f"environment variable {ENV} must be 0 (figures drawn in the "
                         f"qsma process) or 1 (in a forked process), got {value!r}; "
                         f"unset it or set e.g. {ENV}=0")
    if value != "1":
        return f"{ENV}={value or 'unset'} (the worker is off unless {ENV}=1)"
    return fork_refusal()


class PlotWorkerFailed(Exception):
    """The worker did not deliver the figures (internal: the parent draws them)."""


class PlotWorker:
    """A forked process that draws the figures of one result.

    Use :meth:`start` (``None`` where no worker may be forked), then :meth:`submit` the
    result once, :meth:`collect` its figures and :meth:`close` (also on errors; it
    kills a worker still running and reaps it)::

        worker = PlotWorker.start()
        try:
            ...                                  # analysis
            worker.submit(res)
            ...                                  # other files
            pngs = worker.collect()              # name -> PNG bytes
        finally:
            worker.close()
    """

    def __init__(self, process, conn):
        self._process = process
        self._conn = conn
        self._sender = None

    @classmethod
    def start(cls):
        """Fork the worker; ``None`` (and the reason logged) where it may not run."""
        why_not = why_not_fork()
        if why_not is not None:
            log.info("figures drawn in this process: %s", why_not)
            return None
        ctx = multiprocessing.get_context("fork")
        ours, theirs = ctx.Pipe()
        process = ctx.Process(target=_serve, args=(theirs, ours), daemon=True,
                              name="qsma-plots")
        with quiet_fork():
            process.start()
        theirs.close()              # the worker's end: EOF here once it is gone
        return cls(process, ours)

    def submit(self, res, amplitude=None):
        """Hand the worker the :class:`qsma.output.plots.PlotData` of ``res`` (drawn against
        ``amplitude``, :func:`qsma.output.plots.plot_data`). The data are
        sent by a thread, so that a worker still importing matplotlib (not reading
        yet) does not hold this process up once the pipe's buffer is full."""
        from .plots import plot_data
        try:
            payload = pickle.dumps(plot_data(res, amplitude),
                                   protocol=pickle.HIGHEST_PROTOCOL)
        except Exception as exc:            # collect() finds nothing submitted
            log.debug("the figures' data cannot be sent: %s", exc)
            return
        self._sender = threading.Thread(target=self._send, args=(payload,), daemon=True,
                                        name="qsma-plots-send")
        self._sender.start()

    def _send(self, payload):
        try:
            self._conn.send_bytes(payload)
        except (OSError, ValueError):       # the worker died: collect() says so
            pass

    def collect(self) -> dict:
        """The figures' PNG bytes (name -> bytes), the worker's warnings raised again
        here.

        Raises
        ------
        PlotWorkerFailed
            the worker raised (its traceback in the message), ended without answering
            (its exit code in the message) or answered something else.
        """
        if self._sender is None:
            raise PlotWorkerFailed("the figures' data were not handed to it")
        self._sender.join()
        try:
            answer = self._conn.recv()
        except (EOFError, OSError):
            self._process.join()
            raise PlotWorkerFailed(f"the figure process ended without answering "
                                   f"(exit code {self._process.exitcode})") from None
        except Exception as exc:            # an answer that cannot be read back
            raise PlotWorkerFailed(f"the figure process's answer cannot be read "
                                   f"({type(exc).__name__}: {exc})") from None
        kind, value, raised = _checked(answer)
        raise_again(raised)
        if kind == "error":
            log.debug("the figure process raised:\n%s", value)
            last = value.strip().splitlines()[-1] if value.strip() else "an error"
            raise PlotWorkerFailed(f"the figure process raised {last}")
        return value

    def close(self):
        """End the worker (killed if it still runs) and reap it; idempotent."""
        if self._process is None:
            return
        if self._process.is_alive():
            self._process.kill()
        self._process.join()
        self._conn.close()
        self._process = None


def _checked(answer):
    """``(kind, value, warnings)`` of the worker's answer; anything else is a failure."""
    if not (isinstance(answer, tuple) and len(answer) == 3 and answer[0] in ("ok", "error")
            and isinstance(answer[2], list)):
        raise PlotWorkerFailed(f"the figure process answered {type(answer).__name__}")
    kind, value, raised = answer
    if kind == "error" and not isinstance(value, str):
        raise PlotWorkerFailed("the figure process failed without saying why")
    if kind == "ok" and not (isinstance(value, dict) and all(
            isinstance(k, str) and isinstance(v, bytes) for k, v in value.items())):
        raise PlotWorkerFailed("the figure process answered without PNG bytes")
    return kind, value, raised


# -- In the worker ----------------------------------------------------------------------

def _serve(conn, parents_end):
    """The worker: import the plotting code, wait for one job, answer, leave."""
    parents_end.close()             # else our own copy would hide the parent's death
    default_signals()               # a kill ends the worker at once; Ctrl-C: the parent
    try:
        from . import plots  # noqa: F401  (matplotlib's import, beside the analysis)
        import matplotlib.backends.backend_agg  # noqa: F401
        import matplotlib.figure  # noqa: F401
    except Exception:               # reported with the job (the parent draws instead)
        pass
    try:
        payload = conn.recv_bytes()
    except (EOFError, OSError):     # the parent ended or gave up: nothing to draw
        return
    with warnings.catch_warnings(record=True) as seen:
        warnings.simplefilter("always")
        try:
            answer = ("ok", _draw(pickle.loads(payload), conn))
        except Exception:
            answer = ("error", traceback.format_exc())
    try:
        conn.send(answer + (recorded_warnings(seen),))
    except (OSError, pickle.PicklingError, TypeError):
        conn.send(("error", "the figures' answer could not be sent", []))


def _draw(data, conn) -> dict:
    """PNG bytes of every figure of ``data``: on two processes where two cores are
    usable (the other half by a second fork, :func:`_draw_split`), else here."""
    from .plots import figure_files, figure_pngs
    names = list(figure_files(data.model.dim))
    if usable_cores() < 2 or len(names) < 2:
        return figure_pngs(data, names)
    return _draw_split(data, names, conn)


#: The figures the second drawing process takes (about half of the drawing time: the
#: frequency-damping and interface figures each take as long as the other two).
SECOND_HALF = ("damping", "backbone")


def _draw_split(data, names, conn) -> dict:
    """Draw :data:`SECOND_HALF` in a forked child and the rest here; a child that
    fails leaves its figures to be drawn here (same bytes, more time). The child
    closes its copy of ``conn`` (the pipe to the qsma process), so that the parent
    sees at once when this process is gone."""
    from .plots import figure_pngs
    theirs = [n for n in names if n in SECOND_HALF]
    ours = [n for n in names if n not in theirs]
    read_end, write_end = os.pipe()
    pid = os.fork()
    if pid == 0:                                        # the second drawing process
        code = 1
        try:
            os.close(read_end)
            conn.close()
            with os.fdopen(write_end, "wb") as out:
                pickle.dump(figure_pngs(data, theirs), out,
                            protocol=pickle.HIGHEST_PROTOCOL)
            code = 0
        finally:
            os._exit(code)
    os.close(write_end)
    pngs = figure_pngs(data, ours)
    with os.fdopen(read_end, "rb") as inp:
        raw = inp.read()
    _, status = os.waitpid(pid, 0)
    theirs_pngs = {}
    if os.waitstatus_to_exitcode(status) == 0:
        try:
            theirs_pngs = pickle.loads(raw)
        except Exception:               # a torn answer: drawn again below
            theirs_pngs = {}
    missing = [n for n in theirs if not isinstance(theirs_pngs.get(n), bytes)]
    theirs_pngs.update(figure_pngs(data, missing) if missing else {})
    return {n: (pngs[n] if n in pngs else theirs_pngs[n]) for n in names}
