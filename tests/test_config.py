"""TOML configuration: the example file, strict keys, random mutations."""
import copy
import shutil
import subprocess
import sys
from qsma.config import tomllib
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings, strategies as st

import qsma
from qsma.config import load_config, parse_config
from qsma.errors import InputError, QSMAError
from qsma.examples import sandwich_2d
from qsma.levels import Levels
from qsma.examples import example_dir

EXAMPLES = example_dir()        # the example files shipped with qsma
TOML = EXAMPLES / "sandwich-2d.toml"


@pytest.fixture(scope="module")
def base():
    return tomllib.loads(TOML.read_text())


def test_example_config_builds_the_benchmark_model():
    cfg = load_config(TOML)
    ref = sandwich_2d(1)
    assert cfg.model.n_nodes == ref.n_nodes and cfg.model.mu == ref.mu
    for b, r in zip(cfg.model.bodies, ref.bodies):
        assert np.allclose(b.mesh.points, r.mesh.points)
        assert set(b.mesh.facet_sets) >= {"interface", "bolt"}
    assert cfg.options.direct_loop is True and cfg.options.levels == Levels.log(
        "tip", 1e-6, 1e-3, 51)


def test_config_run_equals_example_run():
    cfg = load_config(TOML)
    levels = Levels.log("tip", 1e-5, 1e-3, 6)
    a = qsma.run(cfg.model, levels=levels)
    b = qsma.run(sandwich_2d(1), levels=levels)
    assert a.f0_hz == pytest.approx(b.f0_hz, rel=1e-10)
    assert np.allclose(a.q, b.q, rtol=1e-8) and np.allclose(a.zeta, b.zeta, rtol=1e-6,
                                                            atol=1e-12)


@pytest.mark.parametrize("mutate, match", [
    (lambda c: c["interface"].pop("mu"), "missing required key 'mu'"),
    (lambda c: c["interface"].update(muu=0.6), "unknown key 'muu'.*allowed keys"),
    (lambda c: c["bodies"][0].update(E="steel"), "key 'E' must be a number"),
    (lambda c: c["analysis"].update(mode=1.5), "mode must be an integer"),
    (lambda c: c["levels"].update(spacing="cubic"), "spacing must be"),
    (lambda c: c["bodies"][0].update(mesh="missing.inp"), "missing.inp"),
    (lambda c: c["bodies"][0]["clamps"][0].update(set="nope"), "unknown set 'nope'"),
    (lambda c: c["interface"].update(body2="middle"), "body 'middle'"),
    (lambda c: c["bodies"][0].update(nu=0.7), "nu must lie"),
    (lambda c: c["interface"].update(mu=-1.0), "mu must be >= 0"),
    (lambda c: c["levels"].update(spacing="list", values=[1e-5, 1e-6]), "increase"),
])
def test_bad_config_names_the_problem(base, mutate, match):
    cfg = copy.deepcopy(base)
    mutate(cfg)
    with pytest.raises(InputError, match=match):
        parse_config(cfg, base=EXAMPLES)


_VALUES = st.recursive(
    st.one_of(st.none(), st.booleans(), st.integers(-3, 3), st.floats(allow_nan=True),
              st.text(max_size=5)),
    lambda inner: st.one_of(st.lists(inner, max_size=3),
                            st.dictionaries(st.text(max_size=4), inner, max_size=2)),
    max_leaves=4)


def _containers(node, path=()):
    """Every (path, container) in the config tree, nested tables and lists included."""
    out = [(path, node)]
    items = node.items() if isinstance(node, dict) else enumerate(node)
    for k, v in items:
        if isinstance(v, (dict, list)):
            out += _containers(v, path + (k,))
    return out


@settings(max_examples=80, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(st.lists(st.tuples(st.integers(0, 10 ** 6), st.integers(0, 10 ** 6),
                          st.text(max_size=6), _VALUES, st.booleans()),
                min_size=1, max_size=3))
def test_random_mutations_raise_only_input_errors(base, muts):
    """Replace, add or delete a key or an item anywhere in the example file: the reader
    either builds a model or raises InputError, never another exception."""
    cfg = copy.deepcopy(base)
    for which, pick, newkey, value, delete in muts:
        targets = _containers(cfg)
        _, node = targets[which % len(targets)]
        if isinstance(node, dict):
            keys = sorted(node)
            key = keys[pick % len(keys)] if keys and pick % 3 else newkey
            if delete and key in node:
                del node[key]
            else:
                node[key] = value
        elif node:
            i = pick % len(node)
            if delete:
                del node[i]
            else:
                node[i] = value
    try:
        parse_config(cfg, base=EXAMPLES)
    except InputError:
        pass                       # the expected outcome of a bad file


def test_cli_runs_the_toml_example(tmp_path):
    shutil.copytree(EXAMPLES, tmp_path / "ex", ignore=shutil.ignore_patterns("*.py"))
    from qsma.cli import main
    assert main(["run", str(tmp_path / "ex" / "sandwich-2d.toml"), "--out",
                 str(tmp_path / "out"), "--quiet", "--no-plots", "--no-vtu"]) == 0
    assert (tmp_path / "out" / "results.json").exists()


def test_example_script_runs(tmp_path):
    script = Path(__file__).resolve().parents[1] / "examples" / "run_sandwich.py"
    proc = subprocess.run([sys.executable, str(script),
                           str(tmp_path / "api")], capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stderr
    assert "f0 =" in proc.stdout and (tmp_path / "api" / "results.json").exists()


def test_malformed_toml(tmp_path):
    bad = tmp_path / "bad.toml"
    bad.write_text("[interface\nmu = ")
    with pytest.raises(InputError, match="not valid TOML"):
        load_config(bad)
