"""Mortar surfaces apart in the mesh by a real gap (a punch on a block): the gap, up to
half an element, is the initial gap of the contact problem, which the preload closes
or leaves open (small displacements: the points of the two sides are matched once, in
the undeformed mesh)."""
from __future__ import annotations

import numpy as np
import pytest

import qsma
from qsma.analysis.levels import Levels
from qsma.errors import AnalysisError, InputError, InterfaceGapWarning
from qsma.mesh.generate import structured_mesh
from qsma.model import Body, Clamp, Interface, Material, Model, Probe

#: E (Pa) with nu = 0: a block pressed along y stays in uniaxial stress, whatever its
#: lateral clamps, so the force through the two blocks in series is E A (delta - g) / H
E = 200e9
H_LOWER, H_UPPER = 0.25, 0.5


def _blocks(gap, push):
    """Lower block [0, 1] x [0, 0.25] x [0, 1] (4 x 2 x 4 cells) clamped at y = 0; upper
    block (3 x 2 x 3 cells, meshed apart) from y = 0.25 + gap, its top face moved by
    ``-push`` along y (x and z held); hard contact, frictionless."""
    steel = Material(E, 0.0, 7800.0)
    lower = structured_mesh(np.linspace(0, 1, 5), np.linspace(0, H_LOWER, 3),
                            np.linspace(0, 1, 5))
    y0 = H_LOWER + gap
    upper = structured_mesh(np.linspace(0, 1, 4), np.linspace(y0, y0 + H_UPPER, 3),
                            np.linspace(0, 1, 4))

    def sets(m, y_face, y_held):
        y = m.points[:, 1]
        return m.with_sets(
            node_sets={"held": np.flatnonzero(np.isclose(y, y_held))},
            facet_sets={"face": m.boundary_facets_where(
                lambda p: np.isclose(p[:, 1], y_face))})

    return Model((Body("lower", sets(lower, H_LOWER, 0.0), steel, clamps=(Clamp("held"),)),
                  Body("upper", sets(upper, y0, y0 + H_UPPER), steel,
                       clamps=(Clamp("held", displacement=(0.0, -push, 0.0)),))),
                 Interface("lower", "face", "upper", "face", coupling="mortar", mu=0.0),
                 tip=Probe((("upper", "face"),), (1.0, 0.0, 0.0)), mu=0.0)


GAP = 0.075     # 0.3 of the slave's (the lower block's) elements, 0.25


def test_a_gap_of_0p3_element_is_closed_by_the_preload():
    """The upper block lies 0.075 = 0.3 of an element above the slave (the finer lower
    block, elements 0.25); its top moved down by 0.1 closes the gap, and the contact
    force is E A (0.1 - 0.075) / (H_lower + H_upper) to the solver's tolerance, every
    pair closed (the gap is uniform)."""
    with pytest.warns(InterfaceGapWarning, match=r"7\.500e-02 apart.*initial gaps"):
        res = qsma.run(_blocks(GAP, 0.1), levels=Levels("alpha", (1.0, 10.0)),
                       method="basket")
    lam = res.preload.lam[:, -1]
    assert lam.sum() == pytest.approx(E * 1.0 * (0.1 - GAP) / (H_LOWER + H_UPPER),
                                      rel=1e-8)
    assert (lam > 0).all()


def test_a_gap_the_preload_does_not_close_leaves_every_pair_open():
    """Moved down by 0.05 < 0.075 the blocks never touch: the preload leaves every pair
    open with no force, and the run refuses to compute modes of the separate bodies."""
    with pytest.warns(InterfaceGapWarning), \
            pytest.raises(AnalysisError, match="leaves no interface pair in contact") as err:
        qsma.run(_blocks(GAP, 0.05), levels=Levels("alpha", (1.0,)), method="basket")
    pre = err.value.partial
    assert pre.n_open == len(pre.status) == 25
    assert np.abs(pre.lam).max() < 1e-12 * E * 0.05


def test_adjust_closes_the_meshed_gap_as_a_deck_adjust_does():
    """``Interface.adjust`` (a deck's ADJUST=): the gap of 0.075 within it is zero, so
    the same push of 0.1 carries E A 0.1 / H, the blocks as if meshed touching (no gap
    warning); an adjust below the gap leaves it, E A (0.1 - 0.075) / H."""
    import dataclasses
    import warnings
    levels = Levels("alpha", (1.0, 10.0))
    model = _blocks(GAP, 0.1)
    closed = dataclasses.replace(model, interface=dataclasses.replace(model.interface,
                                                                      adjust=0.08))
    with warnings.catch_warnings():
        warnings.simplefilter("error", InterfaceGapWarning)
        res = qsma.run(closed, levels=levels, method="basket")
    assert res.preload.lam[:, -1].sum() == pytest.approx(
        E * 1.0 * 0.1 / (H_LOWER + H_UPPER), rel=1e-8)
    short = dataclasses.replace(model, interface=dataclasses.replace(model.interface,
                                                                     adjust=0.07))
    with pytest.warns(InterfaceGapWarning):
        res = qsma.run(short, levels=levels, method="basket")
    assert res.preload.lam[:, -1].sum() == pytest.approx(
        E * 1.0 * (0.1 - GAP) / (H_LOWER + H_UPPER), rel=1e-8)
    with pytest.raises(InputError, match="adjust must be a finite distance"):
        Interface("lower", "face", "upper", "face", adjust=-1.0)


def test_adjust_by_node_set_closes_the_gaps_at_its_slave_nodes():
    """``adjust`` naming a set of the slave (the lower block, finer): the gaps at its
    nodes are zero, so the push of 0.1 carries E A 0.1 / H as with a distance; a name
    the slave does not hold is refused naming its sets."""
    import dataclasses
    model = _blocks(GAP, 0.1)
    by_set = dataclasses.replace(model, interface=dataclasses.replace(model.interface,
                                                                      adjust="face"))
    res = qsma.run(by_set, levels=Levels("alpha", (1.0, 10.0)), method="basket")
    assert res.preload.lam[:, -1].sum() == pytest.approx(
        E * 1.0 * 0.1 / (H_LOWER + H_UPPER), rel=1e-8)
    wrong = dataclasses.replace(model, interface=dataclasses.replace(model.interface,
                                                                     adjust="nowhere"))
    with pytest.raises(InputError, match="'nowhere' is no node set of its slave body "
                                         "'lower'"):
        qsma.run(wrong, levels=Levels("alpha", (1.0,)), method="basket")
