"""Contact faces found, not named: the boundary facets where two bodies touch
(``qsma.mesh.touching``), for a TOML interface with ``touching = true`` and a deck's
general contact."""
from __future__ import annotations

import copy
import warnings

import numpy as np
import pytest

import qsma
from qsma.analysis.config import parse_config
from qsma.analysis.levels import Levels
from qsma.deck import export_calculix, read_deck
from qsma.errors import InputError
from qsma.examples import brb, lap_3d
from qsma.mesh.generate import structured_mesh
from qsma.mesh.touching import touching_facets
from qsma.model import Body, Material
from qsma.model.touching import touching_sets


def _rows(facets):
    return sorted(map(tuple, np.sort(facets, axis=1).tolist()))


@pytest.mark.parametrize("model", [lap_3d(1), brb(1, surfaces="flat", element="hexahedron")],
                         ids=["lap-3d", "brb"])
def test_the_touching_faces_hold_the_named_interface(model):
    """lap-3d's interface is exactly where its plates touch: found facet for facet on
    both sides. The Brake-Reuss beam's named interface is the lap's face; where the
    beams touch also holds the lap's two end faces (coincident in its mesh), 16 more
    facets a side, normal to x."""
    itf = model.interface_list[0]
    a, b = model.body(itf.body1).mesh, model.body(itf.body2).mesh
    fa, fb = touching_facets(a, b)
    for found, mesh, name in ((fa, a, itf.set1), (fb, b, itf.set2)):
        named = set(_rows(mesh.facet_sets[name]))
        assert named <= set(_rows(found))
        extra = np.array(sorted(set(_rows(found)) - named), dtype=int)
        if model.name.startswith("lap"):
            assert len(extra) == 0
        else:
            assert len(extra) == 16
            x = mesh.points[extra][..., 0]
            assert np.allclose(np.ptp(x, axis=1), 0) and np.allclose(np.abs(x), 0.06)


def _blocks(dx=0.0, gap=0.0):
    """Lower block [0, 1] x [0, 0.25] x [0, 1] (4 x 2 x 4 cells); upper block meshed
    apart (3 x 2 x 3 cells) from y = 0.25 + gap, moved by ``dx`` along x."""
    steel = Material(200e9, 0.3, 7800.0)
    lower = structured_mesh(np.linspace(0, 1, 5), np.linspace(0, 0.25, 3),
                            np.linspace(0, 1, 5))
    upper = structured_mesh(np.linspace(dx, 1 + dx, 4), np.linspace(0.25 + gap, 0.75, 3),
                            np.linspace(0, 1, 4))
    return Body("lower", lower, steel), Body("upper", upper, steel)


def test_faces_meshed_apart_touch_where_their_centroids_lie_on_the_other():
    """Blocks meshed apart (4 x 4 and 3 x 3 faces): every facet of both faces. Moved by
    a quarter along x, the upper block overhangs: the facets whose centroid
    lies over the other block touch, the others not; a clearance of 0.3 of an element
    is no touch, and touching_sets says so with the fix."""
    lower, upper = _blocks()
    fl, fu = touching_facets(lower.mesh, upper.mesh)
    assert len(fl) == 16 and len(fu) == 9
    assert np.allclose(lower.mesh.points[fl][..., 1], 0.25)
    assert np.allclose(upper.mesh.points[fu][..., 1], 0.25)
    lower, upper = _blocks(dx=0.25)
    fl, fu = touching_facets(lower.mesh, upper.mesh)
    cl = lower.mesh.points[fl].mean(axis=1)[:, 0]
    cu = upper.mesh.points[fu].mean(axis=1)[:, 0]
    assert len(fl) == 12 and cl.min() > 0.25               # lower: the columns x > 0.25
    assert len(fu) == 6 and cu.max() < 1.0                  # upper: the columns x < 1
    lower, upper = _blocks(gap=0.075)
    assert [len(f) for f in touching_facets(lower.mesh, upper.mesh)] == [0, 0]
    with pytest.raises(InputError, match="'lower' and 'upper' do not touch.*Name the "
                                         "contact faces"):
        touching_sets(lower, upper)


@pytest.fixture(scope="module")
def lap_deck(tmp_path_factory):
    path = tmp_path_factory.mktemp("touching") / "lap.inp"
    export_calculix(lap_3d(1), path)
    return path, read_deck(path).config


def test_a_touching_interface_runs_as_the_named_one(lap_deck):
    """lap-3d read from its deck, its interface given as touching = true instead of its
    facet sets: the same model, the same f0, backbone and damping to the last digit."""
    path, config = lap_deck
    found = copy.deepcopy(config)
    itf = found["interface"]
    del itf["set1"], itf["set2"]
    itf["touching"] = True
    named = parse_config(config, base=path.parent).model
    model = parse_config(found, base=path.parent).model
    assert (model.interface.set1, model.interface.set2) == ("touching:top",
                                                           "touching:bottom")
    levels = Levels.log("tip", 1e-6, 1e-4, 4)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        a, b = qsma.run(named, levels=levels), qsma.run(model, levels=levels)
    assert a.success and b.success
    assert a.f0_hz == b.f0_hz
    np.testing.assert_array_equal(a.q, b.q)
    np.testing.assert_array_equal(a.zeta, b.zeta)


@pytest.mark.parametrize("edit, match", [
    (lambda t: t.update(touching=True), "touching = true finds the contact faces; leave "
                                        "out set1 and set2, or touching"),
    (lambda t: t.pop("set2"), "missing required key 'set2': name the facet sets in "
                              "contact.*touching = true"),
])
def test_a_touching_interface_and_named_sets_exclude_each_other(lap_deck, edit, match):
    path, config = lap_deck
    bad = copy.deepcopy(config)
    edit(bad["interface"])
    with pytest.raises(InputError, match=match):
        parse_config(bad, base=path.parent)


def test_three_bodies_touching_pairwise(tmp_path):
    """stack-2d (three beams) with both interfaces given as touching = true: each is the
    whole overlap of its two beams (wider than the bolted region the example names, up
    to the clamped ends, whose points, clamped on both sides in every direction, are
    inert), the run equals the example's with those overlaps as its named sets, and the
    bottom and top beams, which do not touch, are refused as an interface with the
    fix."""
    from helpers import STACK_INTERFACES, stack_toml
    from qsma.analysis.config import load_config
    import dataclasses
    touching = ('[[interfaces]]\nbody1 = "bottom"\nbody2 = "middle"\ntouching = true\n'
                'mu = 0.6\n[[interfaces]]\nbody1 = "middle"\nbody2 = "top"\n'
                'touching = true\nmu = 0.3\n')
    path, _ = stack_toml(tmp_path, touching)
    model = load_config(path).model
    found = [(i.body1, i.set1, i.body2, i.set2) for i in model.interface_list]
    assert found == [("bottom", "touching:middle", "middle", "touching:bottom"),
                     ("middle", "touching:top", "top", "touching:middle")]
    # the same file with its named interfaces, widened to the same facets by name
    ref = load_config(stack_toml(tmp_path, STACK_INTERFACES)[0]).model
    bodies = list(ref.bodies)
    for itf in ref.interface_list:
        for name, set_name, other in ((itf.body1, itf.set1, itf.body2),
                                      (itf.body2, itf.set2, itf.body1)):
            k = ref.body_index(name)
            mine = model.body(name).mesh.facet_sets[f"touching:{other}"]
            assert len(mine) > len(ref.body(name).mesh.facet_sets[set_name])
            bodies[k] = dataclasses.replace(bodies[k], mesh=bodies[k].mesh.with_sets(
                facet_sets={set_name: mine}))
    widened = dataclasses.replace(ref, bodies=tuple(bodies))
    levels = Levels.log("tip", 1e-6, 1e-4, 3)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        a, b = qsma.run(widened, levels=levels), qsma.run(model, levels=levels)
    assert a.success and b.success
    assert b.f0_hz == pytest.approx(a.f0_hz, rel=1e-12)
    np.testing.assert_allclose(b.q, a.q, rtol=1e-10)
    np.testing.assert_allclose(b.zeta, a.zeta, rtol=1e-8, atol=1e-14)
    path, _ = stack_toml(tmp_path, '[[interfaces]]\nbody1 = "bottom"\nbody2 = "top"\n'
                                   'touching = true\nmu = 0.6\n')
    with pytest.raises(InputError, match=r"interfaces\[0\]: bodies 'bottom' and 'top' do "
                                         r"not touch"):
        load_config(path)
