"""What an installed qsma brings: its example files (package data), a sweep without the
optional Dask extra, and (slow: it builds and installs) a wheel and an sdist that work
in a fresh environment."""
import json
import os
from pathlib import Path
import subprocess
import sys
import tarfile
import venv
import warnings

import pytest

import qsma
from qsma.cli import main
from qsma.errors import InputError, SerialSweepWarning
from qsma.examples import copy_examples, example_dir, example_file, example_files

ROOT = Path(__file__).resolve().parents[1]
#: The example files the package must ship (the configuration reads the two meshes).
SHIPPED = {"sandwich-2d.toml", "sandwich-2d-bottom.inp", "sandwich-2d-top.msh"}


def test_example_files_are_package_data():
    """The files sit inside the installed package (found through importlib.resources,
    not beside a source checkout), and the configuration runs from there."""
    assert SHIPPED <= set(example_files())
    assert Path(qsma.__file__).parent in example_dir().parents
    with pytest.raises(InputError, match="no example file 'nope.toml'"):
        example_file("nope.toml")
    from qsma.analysis.config import load_config
    cfg = load_config(example_file("sandwich-2d.toml"))
    assert cfg.model.n_nodes == 2250


def test_qsma_examples_lists_and_copies(tmp_path, capsys):
    assert main(["examples"]) == 0
    listed = capsys.readouterr().out
    assert all(name in listed for name in SHIPPED)
    assert main(["examples", "--copy", str(tmp_path / "ex")]) == 0
    assert SHIPPED <= {p.name for p in (tmp_path / "ex").iterdir()}
    assert main(["examples", "--copy", str(tmp_path / "ex")]) == 2      # nothing overwritten
    assert "exists; copy the examples into an empty or new folder" in capsys.readouterr().err
    with pytest.raises(InputError):
        copy_examples(tmp_path / "ex")


def test_a_sweep_without_distributed_runs_its_cases(tmp_path, monkeypatch, capsys):
    """Without the 'sweep' extra a study still runs (it used to refuse): on processes
    forked from this one where it may fork, else one case after the other, saying so."""
    import qsma._infra.forked
    monkeypatch.setitem(sys.modules, "distributed", None)      # import fails
    opts = qsma.RunOptions(levels=qsma.Levels.log("tip", 1e-6, 1e-4, 3))
    if qsma._infra.forked.fork_refusal() is None:
        with warnings.catch_warnings():
            warnings.simplefilter("error", SerialSweepWarning)
            res = qsma.sweep(qsma.examples.sandwich_2d(1), {"mu": [0.4, 0.6]}, opts,
                             out=tmp_path / "forked", workers=2, plots=False)
        assert res.success and len(res.cases) == 2
    monkeypatch.setattr(qsma._infra.forked, "fork_refusal", lambda: "no fork here")
    with pytest.warns(SerialSweepWarning, match="pip install 'qsma\\[sweep\\]'"):
        res = qsma.sweep(qsma.examples.sandwich_2d(1), {"mu": [0.4, 0.6]}, opts,
                         out=tmp_path / "api", workers=2, plots=False)
    assert res.success and len(res.cases) == 2
    code = main(["sweep", "--example", "sandwich-2d", "--vary", "mu=0.4,0.6", "--levels",
                 "tip:log:1e-6:1e-4:3", "--no-plots", "--out", str(tmp_path / "cli"), "-q"])
    err = capsys.readouterr().err
    assert code == 0, err
    assert "qsma: warning: the 2 case(s) run one after the other" in err
    assert "the 'distributed' package is not installed" in err


def _venv(path):
    venv.EnvBuilder(with_pip=True, clear=True).create(path)
    return path / ("Scripts" if os.name == "nt" else "bin")


def _run(cmd, **kw):
    proc = subprocess.run(cmd, capture_output=True, text=True, **kw)
    assert proc.returncode == 0, f"{cmd}\n{proc.stdout[-3000:]}\n{proc.stderr[-3000:]}"
    return proc.stdout


@pytest.mark.slow
def test_wheel_and_sdist_install_and_run_in_a_fresh_environment(tmp_path):
    """Build the sdist and the wheel, install the wheel into a new virtual environment
    (its dependencies from the package index: needs the network), run the examples
    there (a built-in one and the shipped TOML configuration, from a folder without the
    sources), and run a test module from the unpacked sdist against it."""
    import shutil
    clean = {k: v for k, v in os.environ.items() if k != "PYTHONPATH"}
    tree = tmp_path / "tree"                   # a copy: the build writes egg-info there
    shutil.copytree(ROOT, tree, ignore=shutil.ignore_patterns(
        ".git", ".venv", "out", "build", "dist", "*.egg-info", "__pycache__",
        ".pytest_cache", ".hypothesis"))
    tools = _venv(tmp_path / "build-env")
    _run([str(tools / "python"), "-m", "pip", "install", "-q", "build"], env=clean)
    dist = tmp_path / "dist"
    _run([str(tools / "python"), "-m", "build", "--sdist", "--wheel", "--outdir", str(dist),
          str(tree)], env=clean)
    wheel = next(dist.glob("qsma-*.whl"))
    sdist = next(dist.glob("qsma-*.tar.gz"))
    env = _venv(tmp_path / "fresh")
    _run([str(env / "python"), "-m", "pip", "install", "-q", f"{wheel}[test]"], env=clean)
    work = tmp_path / "work"
    work.mkdir()
    _run([str(env / "qsma"), "run", "--example", "sandwich-2d", "--levels",
          "tip:log:1e-6:1e-3:6", "--out", "ex", "-q"], cwd=work, env=clean)
    _run([str(env / "qsma"), "examples", "--copy", "cfg"], cwd=work, env=clean)
    _run([str(env / "qsma"), "run", "cfg/sandwich-2d.toml", "--levels",
          "tip:log:1e-6:1e-3:6", "--out", "toml", "-q"], cwd=work, env=clean)
    for out in ("ex", "toml"):
        data = json.loads((work / out / "results.json").read_text())
        assert data["success"] and data["units"]["system"] == "SI"
    where = _run([str(env / "python"), "-c", "import qsma; print(qsma.__file__)"],
                 cwd=work, env=clean)
    assert str(ROOT) not in where                      # the installed copy ran
    with tarfile.open(sdist) as tar:
        names = tar.getnames()
        tar.extractall(tmp_path / "sdist")
    top = tmp_path / "sdist" / names[0].split("/")[0]
    for part in ("tests/test_config.py", "tests/data", "docs/results.md",
                 "benchmarks/bench_bolt_calculix.py", "src/qsma/examples/data/sandwich-2d.toml"):
        assert (top / part).exists(), part
    _run([str(env / "python"), "-m", "pytest", "-q", "-p", "no:cacheprovider",
          "tests/test_config.py", "tests/test_install.py", "-m", "not slow"],
         cwd=top, env=clean)
