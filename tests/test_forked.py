"""The -alpha ramp on a forked process beside the last refinement round
(qsma.analysis._NegativeRamp), the tied modes beyond the loaded one finished on a
forked process while the ramps run (qsma.modal.leading), and the forked call both use
(qsma._infra.forked)."""
import os
import threading
import warnings

import numpy as np
import pytest

import qsma
from qsma import analysis
from qsma._infra import forked as _forked
from qsma.errors import ContactConvergenceWarning, InputError
from qsma.examples import sandwich_2d
from qsma.analysis.options import RunOptions

pytestmark = pytest.mark.skipif(not _forked.parallel_available(),
                                reason="no fork start method (Windows)")

FIELDS = ("q", "q_neg", "asymmetry", "tip", "f_hz", "zeta", "dissipation",
          "dissipation_error", "zeta_masing", "n_stuck", "n_slip", "n_open")


def _same_bits(a, b):
    for name in FIELDS:
        x, y = np.asarray(getattr(a, name), float), np.asarray(getattr(b, name), float)
        assert np.array_equal(x, y, equal_nan=True), name
    assert np.array_equal(a.backbone_alpha, b.backbone_alpha)
    assert a.flags == b.flags


class _Counted(_forked.ForkedCall):
    made = []

    def __init__(self, job):
        _Counted.made.append(os.getpid())
        super().__init__(job)


@pytest.fixture(scope="module")
def serial():
    return qsma.run(sandwich_2d(1), parallel_ramps=False)


@pytest.fixture
def forks_by_default(monkeypatch):
    """The -alpha ramp forked as on Linux with two usable cores, whatever the machine
    running the tests (macOS, one core): what is tested is the forked path."""
    monkeypatch.setattr(analysis.ramps, "second_core_refusal", lambda: None)


def test_forked_negative_ramp_gives_the_serial_bits(serial, monkeypatch, forks_by_default):
    """sandwich-2d refines its backbone three times; the -alpha ramp of the final grid
    is solved by a child while the third round runs, and every result is the serial
    one bit for bit (q_neg and the asymmetry come from the child)."""
    monkeypatch.setattr(analysis.ramps, "ForkedCall", _Counted)
    _Counted.made.clear()
    here = []                            # -alpha ramps solved in this process
    solved = analysis._NegativeRamp._solved

    def counted(self, grid):
        if os.getpid() == parent:
            here.append(len(grid))
        return solved(self, grid)
    parent = os.getpid()
    monkeypatch.setattr(analysis._NegativeRamp, "_solved", counted)
    forked = qsma.run(sandwich_2d(1))
    assert _Counted.made == [parent]
    assert here == []                    # the child's ramp was used
    assert forked.success and serial.success
    # the child's CPU time and memory are reported beside the process's own
    assert forked.resources["children_cpu_s"] > serial.resources["children_cpu_s"] >= 0
    assert forked.resources["children_peak_memory_mb"] > 0
    assert len(forked.backbone_alpha) > 51          # the grid was refined
    _same_bits(forked, serial)


class _Dying(_forked.ForkedCall):
    def __init__(self, job):
        super().__init__(lambda: os._exit(3))


class _Raising(_forked.ForkedCall):
    def __init__(self, job):
        def job_that_fails():
            raise MemoryError("no room in the child")
        super().__init__(job_that_fails)


@pytest.mark.parametrize("child", [_Dying, _Raising])
def test_a_failed_child_is_replaced_by_the_serial_ramp(serial, monkeypatch, caplog, child,
                                                       forks_by_default):
    monkeypatch.setattr(analysis.ramps, "ForkedCall", child)
    with caplog.at_level("WARNING", logger="qsma"):
        res = qsma.run(sandwich_2d(1))
    assert "negative ramp solved again in this process" in caplog.text
    _same_bits(res, serial)



@pytest.fixture
def modes_fork(monkeypatch):
    """The tied modes finished on a forked process as on Linux with two usable cores."""
    monkeypatch.setattr(analysis.stages, "second_core_refusal", lambda: None)


def _same_modes(a, b):
    assert np.array_equal(a.modes.omega, b.modes.omega)
    assert np.array_equal(a.modes.shapes, b.modes.shapes)
    assert a.omega0 == b.omega0


def test_forked_tied_modes_give_the_serial_bits(serial, monkeypatch, modes_fork):
    """sandwich-2d computes six tied modes and loads the first: the run goes on with
    it once it has converged, a child finishes the other five meanwhile, and every
    result and every mode is the serial one bit for bit (the serial run finishes the
    same iteration in its own process)."""
    from qsma.modal import eigen, leading
    made, finished_here = [], []
    parent = os.getpid()

    class Counted(_forked.ForkedCall):
        def __init__(self, job):
            made.append(os.getpid())
            super().__init__(job)

    finish = eigen.ShiftInvert.finish

    def counted_finish(self):
        if os.getpid() == parent:
            finished_here.append(1)
        return finish(self)
    monkeypatch.setattr(leading, "ForkedCall", Counted)
    monkeypatch.setattr(eigen.ShiftInvert, "finish", counted_finish)
    forked = qsma.run(sandwich_2d(1))
    assert made == [parent] and finished_here == []      # the child's modes were used
    assert len(forked.modes.omega) == 6
    _same_bits(forked, serial)
    _same_modes(forked, serial)


@pytest.mark.parametrize("child", [_Dying, _Raising])
def test_a_failed_modes_child_is_replaced_by_the_serial_iteration(serial, monkeypatch,
                                                                  caplog, child, modes_fork):
    from qsma.modal import leading
    monkeypatch.setattr(leading, "ForkedCall", child)
    with caplog.at_level("WARNING", logger="qsma"):
        res = qsma.run(sandwich_2d(1))
    assert "tied modes finished again in this process" in caplog.text
    _same_bits(res, serial)
    _same_modes(res, serial)

def test_no_fork_outside_the_main_thread(serial, monkeypatch):
    monkeypatch.setattr(analysis.ramps, "ForkedCall", _Counted)
    _Counted.made.clear()
    out = {}
    t = threading.Thread(target=lambda: out.update(res=qsma.run(sandwich_2d(1))))
    t.start()
    t.join()
    assert _Counted.made == []
    _same_bits(out["res"], serial)


@pytest.mark.parametrize("bad", [1, "yes", None])
def test_parallel_ramps_must_be_true_or_false(bad):
    with pytest.raises(InputError, match="parallel_ramps must be true or false"):
        RunOptions(parallel_ramps=bad)


def test_forked_call_returns_the_value_and_raises_the_warnings_here():
    def job():
        warnings.warn("level 3 did not converge", ContactConvergenceWarning)
        return np.arange(5.0) * os.getpid()
    call = _forked.ForkedCall(job)
    with pytest.warns(ContactConvergenceWarning, match="level 3 did not converge"):
        value = call.result()
    child = value[1]
    assert child != os.getpid()
    assert np.array_equal(value, np.arange(5.0) * child)


def test_forked_call_reports_a_child_that_raises_or_dies():
    def raising():
        raise ValueError("bad level")
    with pytest.raises(_forked.ChildFailed, match="raised ValueError"):
        _forked.ForkedCall(raising).result()
    with pytest.raises(_forked.ChildFailed, match="exit code 7"):
        _forked.ForkedCall(lambda: os._exit(7)).result()


def test_cancel_stops_a_running_child():
    import time
    call = _forked.ForkedCall(lambda: time.sleep(60))
    t0 = time.monotonic()
    call.cancel()
    assert time.monotonic() - t0 < 10
    assert not call._process.is_alive()


def test_loops_use_every_usable_core_by_default(monkeypatch):
    import qsma._infra.threads as threads
    assert RunOptions(loop_workers=3).loop_worker_count == 3
    monkeypatch.setattr(_forked.sys, "platform", "darwin")
    monkeypatch.setattr(_forked, "usable_cores", lambda: 8)
    monkeypatch.setattr(threads, "usable_cores", lambda: 8)
    assert RunOptions().loop_worker_count == 1          # forks by default on Linux only
    monkeypatch.setattr(_forked.sys, "platform", "linux")
    for cores in (1, 2, 8):
        monkeypatch.setattr(_forked, "usable_cores", lambda: cores)
        monkeypatch.setattr(threads, "usable_cores", lambda: cores)
        assert RunOptions().loop_worker_count == cores


def test_a_child_ends_when_its_parent_is_killed(tmp_path):
    """A child whose parent died (killed, out of memory) exits instead of computing on
    and holding what it inherited (the result folder's lock)."""
    import signal
    import subprocess
    import sys
    import time
    script = tmp_path / "parent.py"
    pidfile = tmp_path / "child.pid"
    script.write_text(
        "import os, sys, time\n"
        "from qsma._infra import forked as _forked\n"
        "def job():\n"
        f"    open({str(pidfile)!r}, 'w').write(str(os.getpid()))\n"
        "    time.sleep(120)\n"
        "call = _forked.ForkedCall(job)\n"
        "time.sleep(120)\n")
    parent = subprocess.Popen([sys.executable, str(script)])
    try:
        for _ in range(300):
            if pidfile.exists() and pidfile.read_text():
                break
            time.sleep(0.1)
        child = int(pidfile.read_text())
    finally:
        parent.send_signal(signal.SIGKILL)
        parent.wait()
    for _ in range(100):
        try:
            os.kill(child, 0)
        except ProcessLookupError:
            return
        time.sleep(0.1)
    os.kill(child, signal.SIGKILL)
    raise AssertionError("the child outlived its killed parent by 10 s")


def test_runs_of_one_preparation_do_not_depend_on_earlier_runs():
    """A preparation keeps one contact problem for all its runs (sweeps, fits, several
    modes); the zones an earlier run grew, in this process or in forked ones, must not
    change the next: every run starts from the preload's elimination."""
    from qsma.analysis import prepare, run_prepared
    from qsma.examples import lap_2d
    levels = qsma.Levels.log("tip", 1e-4, 1e-3, 4)
    prep = prepare(lap_2d(1))
    first = run_prepared(prep, levels=levels, dissipation="loop", loop_workers=1,
                         parallel_ramps=False)
    again = [run_prepared(prep, levels=levels, dissipation="loop", loop_workers=w,
                          parallel_ramps=p) for w, p in ((2, True), (1, False))]
    for res in again:
        _same_bits(res, first)
        assert np.array_equal(res.backbone_states.d, first.backbone_states.d)
