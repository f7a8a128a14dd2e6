"""The cell type records (qsma.mesh.celltypes) agree with themselves and with the
programs they name: a new record is checked here before any mesh uses it."""
import numpy as np
import pytest
import skfem

from qsma.mesh.celltypes import (CELL_TYPES, TYPES, abaqus_element_types, abaqus_faces,
                                 reference_nodes)


@pytest.mark.parametrize("name", sorted(TYPES))
def test_shape_functions_interpolate_at_the_reference_nodes(name):
    """The monomials of ``basis`` at the reference nodes give an invertible Vandermonde
    matrix: the shape functions exist and are 1 at their node, 0 at the others."""
    t = TYPES[name]
    if t.dim == 0:
        return
    x = reference_nodes(name)
    assert x.shape == (t.n_nodes, t.dim)
    V = np.prod(x[:, None, :] ** np.asarray(t.basis)[None, :, :], axis=2)
    N = V @ np.linalg.inv(V)
    np.testing.assert_allclose(N, np.eye(t.n_nodes), atol=1e-12)
    assert len(set(map(tuple, x.round(12)))) == t.n_nodes          # distinct nodes


@pytest.mark.parametrize("name", sorted(CELL_TYPES))
def test_facets_are_outward_and_their_nodes_match_the_facet_type(name):
    """Each facet lists the facet type's nodes: its corners first, its further nodes at
    the means the facet type gives them (so a facet read from a file in the facet type's
    order is the cell's facet); its normal (corners, right-hand order) points away from
    the reference cell's centre."""
    t = CELL_TYPES[name]
    ft = TYPES[t.facet_type]
    x = reference_nodes(name)
    centre = x[:t.corners].mean(axis=0)
    assert len({frozenset(f) for f in t.facets}) == len(t.facets)
    covered = set()
    for f in t.facets:
        assert len(f) == ft.n_nodes
        xf = x[list(f)]
        for k, group in enumerate(ft.higher_nodes):
            np.testing.assert_allclose(xf[ft.corners + k], xf[list(group)].mean(axis=0))
        c = xf[:ft.corners]
        if t.dim == 2:
            edge = c[1] - c[0]
            normal = np.array([edge[1], -edge[0]])
        else:
            normal = np.cross(c[1] - c[0], c[2] - c[0])
        assert normal @ (c.mean(axis=0) - centre) > 0
        covered |= set(f)
    if t.linear in ("quad", "hexahedron"):                      # [-1, 1]^d
        on = np.any(np.isclose(np.abs(x), 1.0), axis=1)
    else:                                                       # the unit simplex
        on = np.any(np.isclose(x, 0.0), axis=1) | np.isclose(x.sum(axis=1), 1.0)
    on_boundary = set(np.flatnonzero(on).tolist())
    assert covered == on_boundary                      # interior nodes on no facet


@pytest.mark.parametrize("name", sorted(CELL_TYPES))
def test_abaqus_faces_are_the_facets_renumbered(name):
    t = CELL_TYPES[name]
    assert sorted(map(sorted, abaqus_faces(name))) == sorted(map(sorted, t.facets))


def test_names_in_other_programs_are_unique_and_exist():
    gmsh = [t.gmsh for t in TYPES.values()]
    assert len(set(gmsh)) == len(gmsh) and None not in gmsh
    names = [n for t in TYPES.values() for n in t.abaqus]
    assert len(set(names)) == len(names)
    assert set(abaqus_element_types().values()) <= set(TYPES)
    for t in CELL_TYPES.values():
        mesh_cls, elem_cls, order = t.skfem
        assert issubclass(getattr(skfem, mesh_cls), skfem.Mesh)
        assert getattr(skfem, elem_cls)().doflocs.shape[0] == t.n_nodes
        assert order in (2, 4)
        assert t.abaqus_write is None or t.abaqus_write in t.abaqus
        nodes = t.skfem_nodes
        assert nodes is None or sorted(nodes) == list(range(len(nodes)))


@pytest.mark.parametrize("name", [n for n, t in TYPES.items() if t.gmsh_higher_nodes])
def test_gmsh_higher_nodes_are_a_permutation_of_ours(name):
    t = TYPES[name]
    ours = [frozenset(g) for g in t.higher_nodes]
    theirs = [frozenset(g) for g in t.gmsh_higher_nodes]
    assert sorted(map(sorted, ours)) == sorted(map(sorted, theirs))


@pytest.mark.parametrize("name", sorted(CELL_TYPES))
def test_scikit_fem_reference_vertices_are_ours(name):
    """scikit-fem's reference cell, its vertices taken in our order (``skfem_nodes``),
    is ours up to an affine map of the reference domain (its [0, 1]^d, mirrored for
    hexahedra): the node correspondence the assembly relies on."""
    t = CELL_TYPES[name]
    geometry = CELL_TYPES[t.skfem_geometry or name]
    ref = getattr(skfem, geometry.skfem[0]).init_refdom().p.T     # its vertices
    n = len(ref)
    assert n == TYPES[geometry.linear].n_nodes
    ours = reference_nodes(geometry.name)
    if geometry.skfem_nodes is not None:
        ours = ours[list(geometry.skfem_nodes)]
    X = np.column_stack([ours[:n], np.ones(n)])
    A, *_ = np.linalg.lstsq(X, ref, rcond=None)
    np.testing.assert_allclose(X @ A, ref, atol=1e-12)
    assert abs(np.linalg.det(A[:-1])) > 1e-3
