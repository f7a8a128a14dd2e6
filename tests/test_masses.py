"""Point masses (qsma.model.mass): lumped masses on node or facet sets, added to M."""
from __future__ import annotations

import numpy as np
import pytest
import scipy.sparse.linalg as spla

from qsma.errors import InputError
from qsma.fe import assemble_body
from qsma.model import Body, Clamp, Material, PointMass, Spring
from qsma.mesh.generate import structured_mesh
from qsma.model.mass import point_mass_matrix

#: So stiff that the block moves as a rigid body on its springs (its elastic stiffness
#: 10^8 times the springs': relative frequency errors measured 3e-7 at most, with the
#: mass on the end face in 3D), yet not so stiff that the eigen solve loses digits to
#: the stiffness ratio (E = 1e17 gave 2e-6).
RIGID = Material(1e14, 0.3, 7800.0)


def _block(dim, masses=(), k=1e6):
    """A 100 x 20 (x 20) mm block on springs of total stiffness k in y under its base,
    every other direction of every node held: it can only translate in y."""
    axes = [np.linspace(0, 0.1, 6), np.linspace(0, 0.02, 3)] + \
        ([np.linspace(0, 0.02, 3)] if dim == 3 else [])
    mesh = structured_mesh(*axes)
    eps = 1e-12
    mesh = mesh.with_sets(
        node_sets={"all": np.arange(mesh.n_nodes),
                   "end": np.flatnonzero(mesh.points[:, 0] > 0.1 - eps)},
        facet_sets={"base": mesh.boundary_facets_where(lambda p: p[:, 1] < eps),
                    "top": mesh.boundary_facets_where(lambda p: p[:, 1] > 0.02 - eps)})
    held = tuple(c for c in range(dim) if c != 1)
    stiffness = tuple(k if c == 1 else 0.0 for c in range(dim))
    return Body("block", mesh, RIGID, clamps=(Clamp("all", held),),
                springs=(Spring("base", stiffness),), masses=masses)


def _lowest_frequency(body):
    a = assemble_body(body)
    K = a.K.tocsc()[a.free][:, a.free]
    M = a.M.tocsc()[a.free][:, a.free]
    w2 = spla.eigsh(K, k=1, M=M, sigma=0, which="LM")[0]
    return float(np.sqrt(w2[0]) / (2 * np.pi))


@pytest.mark.parametrize("dim", [2, 3])
@pytest.mark.parametrize("where", ["top", "end"])
def test_mass_on_springs_has_the_spring_mass_frequency(dim, where):
    """A block on springs k translating in y, with a point mass m on a facet set or a
    node set: f = sqrt(k / (m_block + m)) / (2 pi), the block's own mass rho V. The point
    mass equals the block's (the nodes under it move with the block to 1e-7: the mesh's
    local flexibility under a mass 16 times the block's gave 1e-5 in 3D)."""
    k = 1e6
    volume = 0.1 * 0.02 * (0.02 if dim == 3 else 1.0)
    block = m = RIGID.rho * volume
    f = _lowest_frequency(_block(dim, (PointMass(where, m),), k))
    assert f == pytest.approx(np.sqrt(k / (block + m)) / (2 * np.pi), rel=1e-6)
    f0 = _lowest_frequency(_block(dim, (), k))
    assert f0 == pytest.approx(np.sqrt(k / block) / (2 * np.pi), rel=1e-6)
    assert f / f0 == pytest.approx(np.sqrt(0.5), rel=1e-6)


def test_mass_matrix_carries_the_mass_in_every_direction():
    """A rigid translation of the set in any direction carries the whole mass: 1^T M_p
    restricted to one direction sums to m; the shares of a facet set are tributary."""
    body = _block(2, (PointMass("top", 3.0), PointMass("end", 0.5)))
    Mp = point_mass_matrix(body).diagonal().reshape(-1, 2)
    np.testing.assert_allclose(Mp.sum(axis=0), [3.5, 3.5], rtol=1e-14)
    top = np.unique(body.mesh.facet_sets["top"])
    x = body.mesh.points[top, 0]
    order = np.argsort(x)
    ends = Mp[top[order], 0]
    assert ends[0] == pytest.approx(3.0 / 10, rel=1e-12)       # half of 1/5 of the top
    assert ends[2] == pytest.approx(3.0 / 5, rel=1e-12)


@pytest.mark.parametrize("mass, match", [
    (0.0, "mass must be a finite number > 0"),
    (-1.0, "mass must be a finite number > 0"),
    (float("nan"), "mass must be a finite number > 0"),
    ("5", "mass must be a finite number > 0"),
])
def test_bad_mass_is_refused(mass, match):
    with pytest.raises(InputError, match=match):
        PointMass("top", mass)


def test_mass_on_an_unknown_set_is_refused_by_name():
    with pytest.raises(InputError, match=r"point mass on unknown set 'nut'; available sets"):
        _block(2, (PointMass("nut", 1.0),))
