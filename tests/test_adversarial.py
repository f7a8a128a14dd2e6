"""An adversarial user: kills, concurrent runs and a full disk on one result folder;
broken encodings, NUL characters and absurd sizes in the input.

Every result-folder test ends with :func:`qsma.output.folders.verify_run_folder`: the folder
holds one complete run (manifest, sizes, SHA-256), the previous one or the new one.
"""
import csv
import errno
import json
import os
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

import qsma
import qsma.output.files as files
import qsma.output.folders as folders
from qsma.cli import main
from qsma.errors import InputError, OutputFolderBusy
from qsma.examples import sandwich_2d
from qsma.analysis.levels import Levels
from qsma.output.folders import RunFolder, verify_run_folder
from qsma.examples import example_dir

EXAMPLES = example_dir()        # the example files shipped with qsma
SRC = str(Path(qsma.__file__).resolve().parents[1])
#: a short run (--no-vtu, 5 levels): about 1.5 s per subprocess on an idle machine
QUICK = ["--example", "sandwich-2d", "--levels", "tip:log:1e-6:1e-3:5", "--no-vtu",
         "--quiet"]


def _cli(out, *extra, **popen):
    env = dict(os.environ, PYTHONPATH=SRC + os.pathsep + os.environ.get("PYTHONPATH", ""))
    return subprocess.Popen([sys.executable, "-m", "qsma", "run", *QUICK, "--out", str(out),
                             *extra], env=env, stdout=subprocess.DEVNULL,
                            stderr=subprocess.PIPE, **popen)


def _wait_for(predicate, proc, timeout=120):
    """Poll until ``predicate()`` or the process ends; True if the predicate held."""
    t0 = time.monotonic()
    while time.monotonic() - t0 < timeout:
        if predicate():
            return True
        if proc.poll() is not None:
            return False
        time.sleep(0.005)
    return False


def _run_ids(out):
    return verify_run_folder(out)["run_id"]


def _only_the_folder(out):
    """Nothing of qsma is left beside the result folder (staging, lock, old runs)."""
    return sorted(p.name for p in out.parent.iterdir()) == [out.name]


@pytest.fixture(scope="module")
def result():
    return qsma.run(sandwich_2d(1), levels=Levels.log("tip", 1e-6, 1e-3, 3))


@pytest.fixture
def previous(tmp_path, result):
    """A result folder holding one complete run; returns (folder, its run id)."""
    out = tmp_path / "out"
    files.write_all(result, out, plots=False, vtu=False)
    return out, _run_ids(out)


# ---- kills ---------------------------------------------------------------------------

CHECKPOINTS = [(folders, "_digest"), (folders, "_fsync_dir"), (folders, "_exchange"),
               (folders.os, "rename"), (folders.os, "chmod"), (folders.os, "mkdir"),
               (folders.shutil, "rmtree"), (files, "write_csv"), (files, "write_json")]


def _write_killed_at(result, out, k, exchange=True):
    """Fork; the child writes a run into ``out`` and SIGKILLs itself at its k-th pass
    through a step of the folder protocol. Returns True if it was killed."""
    pid = os.fork()
    if pid == 0:                                        # child: never returns
        try:
            count = [0]
            for mod, name in CHECKPOINTS:
                real = getattr(mod, name)

                def step(*a, _real=real, **kw):
                    if count[0] == k:
                        os.kill(os.getpid(), signal.SIGKILL)
                    count[0] += 1
                    return _real(*a, **kw)
                setattr(mod, name, step)
            if not exchange:
                folders._exchange = lambda a, b: False
            files.write_all(result, out, plots=False, vtu=False)
            os._exit(0)
        except BaseException:
            os._exit(3)
    _, status = os.waitpid(pid, 0)
    if os.WIFEXITED(status):
        assert os.WEXITSTATUS(status) == 0
        return False
    assert os.WTERMSIG(status) == signal.SIGKILL
    return True


@pytest.mark.parametrize("exchange", [True, False], ids=["renameat2", "two-renames"])
def test_kill_at_every_step_of_the_protocol(previous, result, exchange):
    """SIGKILL at each step of writing a second run: the folder holds the previous
    complete run or the new one; where the two-rename fallback was cut between its
    renames, the next run puts the newest complete run back first."""
    out, old_id = previous
    seen, recovered = set(), 0
    for k in range(60):
        killed = _write_killed_at(result, out, k, exchange)
        if not out.exists():
            assert not exchange                         # only between the two renames
            with RunFolder(out):                        # the next run recovers first
                pass
            recovered += 1
        seen.add(_run_ids(out) == old_id)
        if not killed:
            break
    assert not killed, "the write never finished: more steps than the loop covers"
    assert seen == {True, False}                        # both outcomes were reached
    assert recovered == (0 if exchange else 1)          # the gap between the renames
    files.write_all(result, out, plots=False, vtu=False)
    assert _only_the_folder(out)


@pytest.mark.parametrize("sig, moment", [(signal.SIGKILL, "computing"),
                                         (signal.SIGTERM, "computing"),
                                         (signal.SIGKILL, "writing"),
                                         (signal.SIGTERM, "writing")])
def test_cli_killed_over_a_previous_run(previous, sig, moment):
    """A real run killed while computing (its lock taken) or while writing (a file in
    its staging folder): previous run intact or new run complete; SIGTERM exits 130."""
    out, old_id = previous
    lock = out.parent / ".out.qsma-lock"
    proc = _cli(out)                                   # with plots: writing takes ~1 s
    reached = _wait_for(lock.exists if moment == "computing" else
                        lambda: _staging_has_files(out), proc)
    proc.send_signal(sig)
    _, err = proc.communicate(timeout=120)
    if sig == signal.SIGTERM and reached:
        assert proc.returncode == 130 and b"interrupted" in err, err
        assert b"internal error" not in err
        assert _only_the_folder(out)                    # staging folder and lock removed
    assert proc.returncode in (0, 130, -signal.SIGKILL), err
    _run_ids(out)                                       # the old run or the new one
    assert main(["run", *QUICK, "--no-plots", "--out", str(out)]) == 0
    assert _only_the_folder(out) and _run_ids(out) != old_id


def _staging_has_files(out):
    try:
        return any(p.name.startswith(f".{out.name}.qsma-new-") and any(p.iterdir())
                   for p in out.parent.iterdir())
    except FileNotFoundError:                           # removed while we looked
        return False


@pytest.mark.parametrize("tamper, match", [
    (lambda out: (out / "results.csv").write_text("level\n"), "differs from the SHA-256"),
    (lambda out: (out / "backbone.png").write_bytes(b"old"), "differ from those of run"),
    (lambda out: (out / "results.json").unlink(), "differ from those of run"),
    (lambda out: (out / "manifest.json").unlink(), "holds no manifest.json")])
def test_a_mixed_folder_is_detected(previous, tamper, match):
    out, _ = previous
    tamper(out)
    with pytest.raises(InputError, match=match):
        verify_run_folder(out)


def test_rerun_replaces_every_file(tmp_path):
    """A run without plots into a folder that held plots leaves no old PNG behind."""
    out = tmp_path / "out"
    assert main(["run", *QUICK, "--out", str(out)]) == 0
    assert (out / "backbone.png").exists()
    assert main(["run", *QUICK, "--no-plots", "--out", str(out)]) == 0
    assert sorted(p.name for p in out.iterdir()) == ["manifest.json", "qsma.log",
                                                      "results.csv", "results.json"]
    verify_run_folder(out)


# ---- concurrent runs -----------------------------------------------------------------

@pytest.mark.parametrize("start", ["together", "staggered"])
def test_two_runs_on_one_folder(previous, start):
    """Two runs on one folder, started together or the second once the first holds
    the folder: one is refused with exit 2 and a message naming the other, or (if the
    first ended before the second looked) both complete; never a mixed folder."""
    out, _ = previous
    procs = [_cli(out, "--no-plots")]
    if start == "staggered":
        _wait_for((out.parent / ".out.qsma-lock").exists, procs[0])
    procs.append(_cli(out, "--no-plots"))
    outcomes = [(p.wait(timeout=300), p.communicate()[1].decode()) for p in procs]
    codes = sorted(c for c, _ in outcomes)
    assert codes in ([0, 0], [0, 2]), outcomes
    for code, err in outcomes:
        if code == 2:
            assert "in use by another qsma run" in err and "pid" in err
    verify_run_folder(out)
    data = json.loads((out / "results.json").read_text())
    with open(out / "results.csv") as f:
        csv_f = [float(row["f_hz [Hz]"]) for row in csv.DictReader(f)]
    assert np.allclose(csv_f, data["levels"]["f_hz"], rtol=1e-9)
    assert _only_the_folder(out)


def test_a_live_run_is_never_disturbed(previous, result, capsys):
    """While a run holds the folder, another is refused before computing, and a run
    on a neighbouring folder touches none of its files."""
    out, old_id = previous
    with RunFolder(out) as live:
        (live.staging / "results.csv").write_text("in progress\n")
        assert main(["run", *QUICK, "--out", str(out)]) == 2
        err = capsys.readouterr().err
        assert "in use by another qsma run" in err and f"pid {os.getpid()}" in err
        with pytest.raises(OutputFolderBusy):
            files.write_all(result, out)
        files.write_all(result, out.parent / "other", plots=False, vtu=False)
        assert (live.staging / "results.csv").read_text() == "in progress\n"
    assert _run_ids(out) == old_id                      # never committed: unchanged
    assert sorted(p.name for p in out.parent.iterdir()) == ["other", "out"]


def test_a_folder_with_foreign_files_is_not_replaced(tmp_path, capsys):
    out = tmp_path / "mine"
    out.mkdir()
    (out / "notes.txt").write_text("keep me")
    assert main(["run", *QUICK, "--out", str(out)]) == 2
    assert "not from a qsma run" in capsys.readouterr().err
    assert (out / "notes.txt").read_text() == "keep me"


# ---- full disk -----------------------------------------------------------------------

def test_full_disk_is_a_plain_error(previous, monkeypatch, capsys):
    """ENOSPC while writing (injected): exit 1 with a plain message, the previous run
    intact, no staging folder left."""
    out, old_id = previous

    def full(*a, **k):
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC), str(out / "results.csv"))
    monkeypatch.setattr(files, "write_csv", full)
    assert main(["run", *QUICK, "--no-plots", "--out", str(out)]) == 1
    err = capsys.readouterr().err
    assert "device is full" in err and "internal error" not in err and "--out" in err
    assert _run_ids(out) == old_id and _only_the_folder(out)


@pytest.fixture
def small_tmpfs(tmp_path):
    """A 256 KiB tmpfs: room for a run without figures (about 4 KB) but not for one
    with its four PNGs (about 200 KB) beside it."""
    if os.geteuid() != 0:
        pytest.skip("mounting a tmpfs needs root")
    mnt = tmp_path / "disk"
    mnt.mkdir()
    proc = subprocess.run(["mount", "-t", "tmpfs", "-o", "size=256k", "tmpfs", str(mnt)],
                          capture_output=True, text=True)
    if proc.returncode != 0:
        pytest.skip(f"cannot mount a tmpfs here: {proc.stderr.strip()}")
    yield mnt
    subprocess.run(["umount", str(mnt)], check=True)


def test_real_full_disk(small_tmpfs, capsys):
    out = small_tmpfs / "out"
    assert main(["run", *QUICK, "--no-plots", "--out", str(out)]) == 0
    old_id = _run_ids(out)
    filler = small_tmpfs / "filler"
    free = shutil.disk_usage(small_tmpfs).free
    filler.write_bytes(b"\0" * max(free - 64 * 1024, 0))  # leave 64 KB: not enough for PNGs
    assert main(["run", *QUICK, "--out", str(out)]) == 1
    err = capsys.readouterr().err
    assert "device is full" in err and "internal error" not in err
    assert _run_ids(out) == old_id
    assert sorted(p.name for p in small_tmpfs.iterdir()) == ["filler", "out"]


# ---- bad input: exit 2 with a message ------------------------------------------------

def _toml(tmp_path, text=None, **replace):
    text = (EXAMPLES / "sandwich-2d.toml").read_text() if text is None else text
    for old, new in replace.items():
        text = text.replace(old, new)
    for mesh in ("sandwich-2d-bottom.inp", "sandwich-2d-top.msh"):
        if not (tmp_path / mesh).exists():
            shutil.copy(EXAMPLES / mesh, tmp_path / mesh)
    return text


@pytest.mark.parametrize("encoding, match", [("latin-1", "line 1: byte 0xe8 is not UTF-8"),
                                             ("utf-16", "UTF-16"),
                                             ("utf-32", "UTF-16 or UTF-32")])
def test_toml_not_utf8(tmp_path, capsys, encoding, match):
    text = "# modèle\n" + _toml(tmp_path)
    cfg = tmp_path / "c.toml"
    cfg.write_bytes(text.encode(encoding))
    assert main(["run", str(cfg), "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err
    assert match in err and "must be UTF-8" in err and "internal error" not in err


def test_toml_utf8_with_bom_is_read(tmp_path):
    from qsma.analysis.config import load_config
    cfg = tmp_path / "c.toml"
    cfg.write_bytes(b"\xef\xbb\xbf" + _toml(tmp_path).encode())
    assert load_config(cfg).model.mu == 0.6


@pytest.mark.parametrize("mesh", ["sandwich-2d-top.msh\\u0000x", ""])
def test_nul_or_empty_mesh_path(tmp_path, capsys, mesh):
    cfg = tmp_path / "c.toml"
    cfg.write_text(_toml(tmp_path, **{'"sandwich-2d-top.msh"': f'"{mesh}"'}))
    assert main(["run", str(cfg), "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err
    assert "NUL character" in err and "bodies[1]" in err


@pytest.mark.parametrize("tol, match", [("nan", "must be finite"), ("inf", "must be finite"),
                                        ("-1e-9", "must be > 0"),
                                        ("1.0", "below half the smallest node spacing")])
def test_nonsense_pairing_tolerance(tmp_path, capsys, tol, match):
    cfg = tmp_path / "c.toml"
    cfg.write_text(_toml(tmp_path, **{"# tol = 1e-9": f"tol = {tol}"}))
    assert main(["run", str(cfg), "--out", str(tmp_path / "o")]) == 2
    assert match in capsys.readouterr().err


def test_sensible_pairing_tolerance_is_accepted(tmp_path):
    from qsma.analysis.config import load_config
    cfg = tmp_path / "c.toml"
    cfg.write_text(_toml(tmp_path, **{"# tol = 1e-9": "tol = 1e-9"}))
    assert load_config(cfg).model.interface.tol == 1e-9


@pytest.mark.parametrize("argv, match", [
    (["run", *QUICK, "--levels", "tip:log:1e-6:1e-3:10000000000"], "at most 10000"),
    (["run", *QUICK, "--levels", "alpha:linear:1:2:10001"], "at most 10000"),
    (["modes", "--example", "sandwich-2d", "-n", "100000"], "at most 200"),
    (["run", "--example", "sandwich-2d", "--out", ""], "output folder is empty"),
    (["run", "--example", "sandwich-2d", "--out", "  "], "output folder is empty")])
def test_absurd_sizes_and_empty_out(tmp_path, capsys, monkeypatch, argv, match):
    monkeypatch.chdir(tmp_path)
    if "--out" not in argv:
        argv = argv + (["--out", str(tmp_path / "o")] if argv[0] == "run" else [])
    assert main(argv) == 2
    assert match in capsys.readouterr().err
    assert list(tmp_path.iterdir()) == []              # nothing written, not even in .


def test_huge_level_count_in_toml(tmp_path, capsys):
    cfg = tmp_path / "c.toml"
    cfg.write_text(_toml(tmp_path, **{"n = 51": "n = 10000000000"}))
    assert main(["run", str(cfg), "--out", str(tmp_path / "o")]) == 2
    assert "at most 10000" in capsys.readouterr().err


def test_out_path_checks():
    with pytest.raises(InputError, match="NUL"):
        RunFolder("a\x00b")
    with pytest.raises(InputError, match="root"):
        RunFolder("/")


def test_a_forked_child_does_not_hold_the_folder_of_a_killed_run(tmp_path):
    """A run forks helpers (the -alpha ramp, loop workers, the plot worker) while it
    holds its output folder. Killed, the run must release the folder even if a helper
    still runs: the helpers close their copies of the lock (a flock belongs to the
    open file, which a helper's copy would keep locked until it ends). Here a forked
    process plays the run: it takes the folder, forks a helper that sleeps, and kills
    itself; a new run takes the folder while the helper still sleeps."""
    import signal
    import time
    out = tmp_path / "out"
    read_end, write_end = os.pipe()
    run = os.fork()
    if run == 0:                                        # the run
        try:
            with RunFolder(out):
                helper = os.fork()
                if helper == 0:
                    time.sleep(30)
                    os._exit(0)
                os.write(write_end, str(helper).encode())
                os.kill(os.getpid(), signal.SIGKILL)
        finally:
            os._exit(1)
    os.close(write_end)
    helper = int(os.read(read_end, 64))
    os.close(read_end)
    os.waitpid(run, 0)
    try:
        with RunFolder(out) as again:                   # not "in use by another run"
            assert again.staging.exists()
        os.kill(helper, 0)                              # the helper still runs
    finally:
        os.kill(helper, signal.SIGKILL)
