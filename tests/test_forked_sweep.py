"""A study's cases on processes forked from the calling one (the default on Linux and
macOS): the same results as in one process, no preparation pickled, and a worker
that dies costs its case a second try, not the study."""
import os
import signal
import threading

import numpy as np
import pytest

import qsma
from qsma._infra.forked import fork_refusal, parallel_available
from qsma.examples import sandwich_2d
from qsma.study import runners


@pytest.fixture(autouse=True)
def may_fork():
    """Forked workers need the fork start method (skipped where the platform has none,
    Windows) and a process that may fork now: a thread an earlier test left running
    (a Dask client's IO loop) is that test's fault, and fails here by name."""
    if not parallel_available():
        pytest.skip("the fork start method is not available on this platform")
    why_not = fork_refusal()
    assert why_not is None, (f"this process may not fork: {why_not} "
                             f"({[t.name for t in threading.enumerate()]})")


OPTIONS = qsma.RunOptions(levels=qsma.Levels.log("tip", 1e-6, 1e-3, 11))
VARY = {"mu": [0.3, 0.5, 0.7]}


@pytest.fixture(scope="module")
def serial(tmp_path_factory):
    out = tmp_path_factory.mktemp("serial")
    return qsma.sweep(sandwich_2d(1), VARY, OPTIONS, out=out, scheduler="serial",
                      plots=False)


def test_forked_cases_give_the_serial_results(serial, tmp_path, monkeypatch):
    """Forked workers inherit the preparation: nothing is pickled (pickling a
    preparation fails here) and every table column equals the serial sweep's."""
    import qsma.analysis

    def no_pickle(self):
        raise AssertionError("the preparation was pickled")

    monkeypatch.setattr(qsma.analysis.Prepared, "__reduce__", no_pickle)
    assert runners.choose_runner(None, 2, 3) is runners.run_forked
    res = qsma.sweep(sandwich_2d(1), VARY, OPTIONS, out=tmp_path, workers=2, plots=False)
    assert res.success and [o.status for o in res.cases] == ["ok"] * 3
    for name in ("f_hz", "zeta", "dissipation", "q", "tip"):
        np.testing.assert_array_equal(np.array(res.table[name], float),
                                      np.array(serial.table[name], float))


def test_a_worker_that_dies_costs_its_case_a_second_try(serial, tmp_path, monkeypatch):
    """The first try of case 1 kills its worker (as the kernel's OOM killer would): the
    pool breaks, the unfinished cases run in a new pool, the study completes with the
    serial results."""
    marker = tmp_path / "killed-once"
    real = runners.run_case

    def dies_once(prepared, case, options, folder, files=()):
        if case.index == 1 and not marker.exists():
            marker.write_text("x")
            os.kill(os.getpid(), signal.SIGKILL)
        return real(prepared, case, options, folder, files)

    monkeypatch.setattr(runners, "run_case", dies_once)
    res = qsma.sweep(sandwich_2d(1), VARY, OPTIONS, out=tmp_path / "s", workers=2,
                     plots=False)
    assert marker.exists()
    assert res.success and [o.status for o in res.cases] == ["ok"] * 3
    np.testing.assert_array_equal(np.array(res.table["zeta"], float),
                                  np.array(serial.table["zeta"], float))
