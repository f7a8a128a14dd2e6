"""TOML configuration: the example file, strict keys, random mutations."""
import copy
import shutil
import subprocess
import sys
from qsma.analysis.config import tomllib
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings, strategies as st

import qsma
from qsma.analysis.config import load_config, parse_config
from qsma.errors import InputError, QSMAError
from qsma.examples import sandwich_2d
from qsma.analysis.levels import Levels
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
    (lambda c: c["interface"].update(muu=0.6),
     r"unknown key 'muu' \(did you mean 'mu'\?\); allowed keys"),
    (lambda c: c.update(method="basket"), r"unknown key 'method' \(it belongs in \[analysis\]\)"),
    (lambda c: c["tip"].update(mu=0.3), r"'mu' \(it belongs in \[interface\] or \[\[interfaces\]\]\)"),
    (lambda c: c["bodies"][0]["pressures"][0].update(set="tip"),
     r"pressure on 'tip', which is a node set.*\*CLOAD.*\*SURFACE, TYPE=ELEMENT.*facet sets: \["),
    (lambda c: c["bodies"][0].update(E="steel"), "key 'E' must be a number"),
    (lambda c: c["analysis"].update(mode=1.5), "mode must be an integer"),
    (lambda c: c["levels"].update(spacing="cubic"), "spacing must be"),
    (lambda c: c["bodies"][0].update(mesh="missing.inp"), "missing.inp"),
    (lambda c: c["bodies"][0]["clamps"][0].update(set="nope"), "unknown set 'nope'"),
    (lambda c: c["interface"].update(body2="middle"), "body 'middle'"),
    (lambda c: c["bodies"][0].update(nu=0.7), "nu must lie"),
    (lambda c: c["interface"].update(mu=-1.0), "mu must be >= 0"),
    (lambda c: c.update(levels=dict(kind="tip", spacing="list", values=[1e-5, 1e-6])),
     "increase"),
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


# --- everything the Python model has -----------------------------------------------

def _bolted(base):
    """The sandwich-2d file with the bolt of sandwich_2d_bolted instead of the pressures."""
    from qsma.examples.sandwich import SANDWICH_2D as s
    cfg = copy.deepcopy(base)
    for b in cfg["bodies"]:
        b.pop("pressures")
    cfg["bolts"] = [dict(name="bolt", body_a="bottom", set_a="bolt", body_b="top",
                         set_b="bolt", pretension=s["p_bolt"] * s["w_bolt"],
                         stiffness=s["E"] * s["w_bolt"] / (2 * s["h"]))]
    return cfg


def test_bolts_in_toml_give_the_python_bolted_model(base):
    """[[bolts]] builds the bolts of qsma.model.Bolt: the sandwich file with a bolt runs
    as sandwich_2d_bolted (same meshes, 1e-14 apart)."""
    from qsma.examples import sandwich_2d_bolted
    cfg = parse_config(_bolted(base), base=EXAMPLES)
    ref = sandwich_2d_bolted(1)
    assert cfg.model.bolts == ref.bolts
    levels = Levels.log("tip", 1e-5, 1e-3, 5)
    a = qsma.run(cfg.model, levels=levels, method="basket")
    b = qsma.run(ref, levels=levels, method="basket")
    assert a.success and a.f0_hz == pytest.approx(b.f0_hz, rel=1e-8)
    assert np.allclose(a.zeta, b.zeta, rtol=1e-6, atol=1e-12)


@pytest.mark.parametrize("mutate, match", [
    (lambda c: c["bolts"][0].update(pretension=-1.0), "pretension must be > 0"),
    (lambda c: c["bolts"][0].update(body_b="lid"), "bolt 'bolt' names body 'lid'"),
    (lambda c: c["bolts"][0].pop("stiffness"), r"bolts\[0\]: missing required key 'stiffness'"),
    (lambda c: c["bolts"][0].update(diameter=8e-3), r"bolts\[0\]: unknown key 'diameter'"),
])
def test_bad_bolts_are_named(base, mutate, match):
    cfg = _bolted(base)
    mutate(cfg)
    with pytest.raises(InputError, match=match):
        parse_config(cfg, base=EXAMPLES)


def test_point_masses_in_toml(base):
    """masses = [{ set, mass }] puts qsma.model.PointMass on the body; the tied modes
    come out as those of the same model built in Python, and lower than without."""
    from dataclasses import replace
    from qsma.fe import assemble_body
    from qsma.modal import linear_modes
    from qsma.model import PointMass, make_pairing
    cfg = copy.deepcopy(base)
    cfg["bodies"][1]["masses"] = [{"set": "tip", "mass": 0.2}]
    model = parse_config(cfg, base=EXAMPLES).model
    assert model.bodies[1].masses == (PointMass("tip", 0.2),)
    plain = parse_config(base, base=EXAMPLES).model
    by_hand = replace(plain, bodies=(plain.bodies[0],
                                     replace(plain.bodies[1], masses=(PointMass("tip", 0.2),))))

    def f(m):
        return linear_modes(m, [assemble_body(b) for b in m.bodies], make_pairing(m),
                            n_modes=2).f_hz
    np.testing.assert_allclose(f(model), f(by_hand), rtol=1e-10)
    assert np.all(f(model) < f(plain))


def test_clamp_dofs_count_from_one(base):
    """dofs = [2] (Abaqus numbering, 1 = x) holds what components = [1] holds; both at
    once, 0 or 4 are refused."""
    a, b = copy.deepcopy(base), copy.deepcopy(base)
    a["bodies"][0]["clamps"] = [{"set": "clamp", "dofs": [2]}]
    b["bodies"][0]["clamps"] = [{"set": "clamp", "components": [1]}]
    ca = parse_config(a, base=EXAMPLES).model.bodies[0]
    cb = parse_config(b, base=EXAMPLES).model.bodies[0]
    assert ca.clamps == cb.clamps
    np.testing.assert_array_equal(ca.clamped_dofs(), cb.clamped_dofs())
    assert np.all(ca.clamped_dofs() % 2 == 1)                       # y only
    for clamp, match in [({"dofs": [0]}, "dofs must be a list of degrees of freedom 1, 2 "
                          "or 3"), ({"dofs": [1], "components": [0]}, "either components"),
                         ({"dofs": []}, "dofs must be")]:
        a["bodies"][0]["clamps"] = [dict(set="clamp", **clamp)]
        with pytest.raises(InputError, match=match):
            parse_config(a, base=EXAMPLES)


def test_several_modes_in_toml(base, tmp_path):
    """[analysis] modes = [0, 1]: the configuration keeps them, qsma run writes one folder
    per mode as with --modes; mode and modes together are refused."""
    from qsma.cli import main
    from qsma.analysis.config import config_modes
    cfg = copy.deepcopy(base)
    cfg["analysis"]["modes"] = [0, 1]
    with pytest.raises(InputError, match="either mode = K"):
        parse_config(cfg, base=EXAMPLES)
    cfg["analysis"].pop("mode")
    assert parse_config(cfg, base=EXAMPLES).modes == (0, 1)
    for bad in ([], [0, 0], [-1], [1.5]):
        with pytest.raises(InputError, match="modes must be a list of distinct"):
            parse_config(dict(cfg, analysis=dict(cfg["analysis"], modes=bad)), base=EXAMPLES)
    shutil.copytree(EXAMPLES, tmp_path / "ex", ignore=shutil.ignore_patterns("*.py"))
    text = TOML.read_text().replace("mode = 0 ", "modes = [0, 1] ").replace(
        "n = 51", "n = 4").replace("direct_loop = true", "direct_loop = false")
    (tmp_path / "ex" / "two.toml").write_text(text)
    assert config_modes(tmp_path / "ex" / "two.toml") == (0, 1)
    assert main(["run", str(tmp_path / "ex" / "two.toml"), "--out", str(tmp_path / "out"),
                 "--quiet", "--no-plots", "--no-vtu"]) == 0
    assert (tmp_path / "out" / "mode-0" / "results.json").exists()
    assert (tmp_path / "out" / "mode-1" / "results.json").exists()
