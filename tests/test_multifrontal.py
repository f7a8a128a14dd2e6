"""The multifrontal Cholesky backend (qsma.reduction.schur.multifrontal): Kc and K_EE
solves against dense references on 2D, 3D and tetrahedral bodies, scalar problems, disconnected E,
trees of many small fronts, the structure's invariants and the refusal of a K_EE
that is not positive definite."""
from pathlib import Path
import sys

import numpy as np
import pytest
import scipy.sparse as sp

from qsma.reduction import schur
from qsma.reduction.schur import multifrontal as mf, superlu
from qsma.errors import InputError
from qsma.fe import assemble_body
from qsma.reduction.schur import schur_complement
from qsma.model import Body, Clamp, Material
from qsma.mesh.generate import structured_mesh
from qsma.mesh.io import read_mesh

# pymetis is a dependency everywhere but on Windows, where it has no wheel: skip only
# there, so that a broken install elsewhere fails here instead of skipping the backend
pytestmark = pytest.mark.skipif(sys.platform == "win32",
                                reason="pymetis (METIS) has no Windows wheel")

DATA = Path(__file__).parent / "data"
STEEL = Material(200e9, 0.3, 7800.0)


def laplacian(*shape, shift=1e-3):
    """Scalar Laplacian (one DOF per node) on a grid of ``shape`` plus ``shift I``."""
    lap = lambda m: sp.diags([-1.0, 2.0, -1.0], [-1, 0, 1], shape=(m, m))
    K = sp.csr_matrix((int(np.prod(shape)),) * 2)
    for axis, m in enumerate(shape):
        parts = [sp.identity(k) for k in shape]
        parts[axis] = lap(m)
        term = parts[0]
        for q in parts[1:]:
            term = sp.kron(term, q)
        K = K + term
    return (K + shift * sp.identity(K.shape[0])).tocsr()


def block_3d(n=(7, 3, 4)):
    """A clamped hexahedral block (3 DOFs per node); C: the free DOFs of its top face
    y = 1 in a shuffled order."""
    mesh = structured_mesh(np.linspace(0, 2, n[0]), np.linspace(0, 1, n[1]),
                           np.linspace(0, 1, n[2]))
    p = mesh.points
    mesh = mesh.with_sets(node_sets={"clamp": np.flatnonzero(p[:, 0] < 1e-9)})
    a = assemble_body(Body("block", mesh, STEEL, clamps=(Clamp("clamp"),)))
    top = np.flatnonzero((p[:, 1] > 1 - 1e-9) & (p[:, 0] > 1e-9))
    dofs = (3 * top[:, None] + np.arange(3)).ravel()
    C = np.searchsorted(a.free, dofs)
    return a.K.tocsr()[a.free][:, a.free], np.random.default_rng(1).permutation(C)


def tet_box():
    """The Gmsh tetrahedral box of tests/data clamped on its bottom facets; C: the
    DOFs of its top facets."""
    mesh = read_mesh(DATA / "gmsh_box_v41.msh", cell_type="tetra")
    bottom = np.unique(mesh.facet_sets["bottom"])
    top = np.setdiff1d(np.unique(mesh.facet_sets["top"]), bottom)
    mesh = mesh.with_sets(node_sets={"clamp": bottom})
    a = assemble_body(Body("box", mesh, STEEL, clamps=(Clamp("clamp"),)))
    C = np.searchsorted(a.free, (3 * top[:, None] + np.arange(3)).ravel())
    return a.K.tocsr()[a.free][:, a.free], C


def reference(K, C):
    K = K.toarray()
    E = np.setdiff1d(np.arange(len(K)), C)
    K_EE = K[np.ix_(E, E)]
    return K[np.ix_(C, C)] - K[np.ix_(C, E)] @ np.linalg.solve(K_EE, K[np.ix_(E, C)]), K_EE


def check_against_dense(K, C):
    Kc, solver = schur_complement(K, C, backend="multifrontal")
    Kc_ref, K_EE = reference(K, C)
    assert solver.backend == "multifrontal"
    assert np.abs(Kc - Kc_ref).max() <= 1e-10 * np.abs(Kc_ref).max()
    np.testing.assert_array_equal(Kc, Kc.T)
    B = np.random.default_rng(3).standard_normal((solver.n, 5))
    X = solver(B)
    assert np.abs(K_EE @ X - B).max() <= 1e-12 * np.abs(K_EE).max() * np.abs(X).max()
    assert np.abs(solver(B[:, 2]) - X[:, 2]).max() <= 1e-13 * np.abs(X).max()
    assert solver.min_pivot_ratio > schur.PIVOT_RATIO_MIN
    return Kc, solver


@pytest.fixture
def small_fronts(monkeypatch):
    """Leaves of at most 2 nodes: deep trees, many separators, empty boundaries."""
    monkeypatch.setattr(mf, "LEAF_NODES", 2)


@pytest.mark.parametrize("leaves", ["default", "small"])
@pytest.mark.parametrize("case", ["scalar-2d", "scalar-3d", "block-3d", "tet-box"])
def test_kc_and_solves_match_the_dense_reference(case, leaves, monkeypatch):
    if leaves == "small":
        monkeypatch.setattr(mf, "LEAF_NODES", 2)
    if case == "scalar-2d":
        K = laplacian(13, 11)
        C = np.random.default_rng(0).permutation(K.shape[0])[:20]
    elif case == "scalar-3d":
        K = laplacian(6, 5, 7)
        C = np.arange(0, 30)[::-1]                       # one face, reversed
    elif case == "block-3d":
        K, C = block_3d()
    else:
        K, C = tet_box()
    check_against_dense(K, C)


def test_interface_that_cuts_e_into_disconnected_pieces(small_fronts):
    # a 9 x 12 grid cut by its grid lines x = 3 and x = 7: E in three pieces
    nx, ny = 9, 12
    K = laplacian(ny, nx)                           # node (j, i) at j * nx + i
    ix = np.arange(nx * ny) % nx
    C = np.flatnonzero((ix == 3) | (ix == 7))
    check_against_dense(K, C)


def test_block_diagonal_k_and_c_all_of_one_block():
    K1, K2 = laplacian(6, 5), laplacian(4, 4, 3)
    K = sp.block_diag([K1, K2, laplacian(7)], format="csr")
    C = np.arange(30, 78)                           # all of the second block
    Kc, _ = check_against_dense(K, C)
    assert np.abs(Kc - K2.toarray()).max() <= 1e-14 * abs(K2).max()


def test_c_without_coupling_to_e_and_e_without_edges():
    # diagonal K_EE (no edges: bisection into halves with an empty separator) and
    # one interface DOF coupled to nothing
    n = 40
    K = sp.diags(np.arange(1.0, n + 1)).tolil()
    K[0, 39] = K[39, 0] = 0.5
    K[1, 38] = K[38, 1] = 0.25
    check_against_dense(K.tocsr(), np.array([39, 38, 20]))


def test_tree_invariants(small_fronts):
    K, C = block_3d()
    E = np.setdiff1d(np.arange(K.shape[0]), C)
    K_EE, K_CE = K[E][:, E], K[np.sort(C)][:, E]
    s = mf.front_structure(K_EE, K_CE, leaf_nodes=2)
    # every E DOF eliminated exactly once, the DOFs of a node together
    np.testing.assert_array_equal(np.sort(s.perm), np.arange(len(E)))
    assert np.all(s.start[1:] >= s.start[:-1]) and s.start[-1] == len(E)
    assert np.all(np.diff(s.perm.reshape(-1, 3), axis=1) == 1)
    front = np.repeat(np.arange(s.n_fronts), np.diff(s.start))      # of a position
    assert s.n_fronts > 10
    for t in range(s.n_fronts):
        ancestors, p = set(), s.parent[t]
        while p >= 0:
            ancestors.add(int(p))
            p = s.parent[p]
        assert s.parent[t] == -1 or s.parent[t] > t                  # postorder
        b = s.boundary[t]
        assert np.all(np.diff(b) > 0) and set(front[b].tolist()) <= ancestors
        if s.parent[t] >= 0:                       # a child's sets reach its parent
            p = s.parent[t]
            own = np.arange(s.start[p], s.start[p + 1])
            assert set(b.tolist()) <= set(own.tolist()) | set(s.boundary[p].tolist())
            assert set(s.interface[t].tolist()) <= set(s.interface[p].tolist())
        # the coupling of the front's DOFs stays inside its subtree, boundary and C
        cols = K_EE[s.perm[s.start[t]:s.start[t + 1]]][:, s.perm]
        reach = front[np.unique(cols.indices)]
        subtree = {u for u in range(t + 1) if _is_descendant(s.parent, u, t)}
        assert set(reach.tolist()) <= subtree | ancestors
    np.testing.assert_array_equal(np.sort(s.interface_order), np.arange(len(C)))
    assert s.factor_entries() > 0


def _is_descendant(parent, u, t):
    while u >= 0:
        if u == t:
            return True
        u = parent[u]
    return False


def test_not_positive_definite_is_refused_without_a_crash():
    K = laplacian(8, 8).tolil()
    K[10, 10] = -5.0                                # indefinite K_EE
    K = K.tocsr()
    C = np.arange(60, 64)
    E = np.setdiff1d(np.arange(64), C)
    factor, _, ratio, _ = mf.multifrontal_schur(K[E][:, E], K[C][:, E],
                                                mf.front_structure(K[E][:, E], K[C][:, E]))
    assert factor is None and ratio == -np.inf
    with pytest.raises(InputError, match="singular or not positive definite"):
        schur_complement(K, C, backend="multifrontal")


def test_free_body_is_refused():
    # the block without its clamp, held at one node only: it can still rotate
    mesh = structured_mesh(np.linspace(0, 2, 7), np.linspace(0, 1, 3), np.linspace(0, 1, 4))
    a = assemble_body(Body("free", mesh, STEEL))
    with pytest.raises(InputError, match="singular or not positive definite"):
        schur_complement(a.K.tocsr(), np.arange(3), backend="multifrontal")


def test_solver_shapes():
    K, C = block_3d()
    _, solver = schur_complement(K, C, backend="multifrontal")
    n = solver.n
    assert solver(np.ones(n)).shape == (n,)
    assert solver(np.ones((n, 1))).shape == (n, 1)
    assert solver(np.ones((n, 13))).shape == (n, 13)
    assert solver(np.zeros((n, 0))).shape == (n, 0)
    with pytest.raises(InputError, match="right-hand side must have shape"):
        solver(np.ones(n + 1))


def test_many_columns_are_one_solve_whatever_the_thread_setting(monkeypatch):
    """The factor's loop over the fronts holds the GIL, so splitting the columns among
    Python threads only made the solves wait for each other (the backend's docstring): the
    solver takes all the columns in one call, and its answer agrees with the
    column-by-column solves whatever QSMA_SOLVE_THREADS says (to 1e-14 here: a lone
    column takes another path of the BLAS kernels than a column of a pair)."""
    K, C = block_3d()
    _, solver = schur_complement(K, C, backend="multifrontal")
    B = np.random.default_rng(7).standard_normal((solver.n, 24))

    def refused(*args):
        raise AssertionError("the multifrontal solve was split among threads")
    monkeypatch.setattr(superlu, "_threaded", refused)
    monkeypatch.setenv("QSMA_SOLVE_THREADS", "2")
    X = solver(B)
    X1 = solver(B[:, :1])[:, 0]
    A = K.toarray()
    E = np.setdiff1d(np.arange(K.shape[0]), C)
    residual = A[np.ix_(E, E)] @ X - B
    assert np.abs(residual).max() <= 1e-10 * np.abs(B).max()
    assert np.abs(X[:, 0] - X1).max() <= 1e-14 * np.abs(X1).max()


def test_same_kc_as_metis_superlu_on_the_3d_block():
    K, C = block_3d((9, 4, 5))
    Kc_m, s_m = schur_complement(K, C, backend="multifrontal")
    Kc_s, s_s = schur_complement(K, C, backend="metis_superlu")
    assert np.abs(Kc_m - Kc_s).max() <= 1e-12 * np.abs(Kc_s).max()
    B = np.random.default_rng(5).standard_normal((s_m.n, 4))
    assert np.abs(s_m(B) - s_s(B)).max() <= 1e-10 * np.abs(s_s(B)).max()


def test_minimum_cover_is_a_smallest_vertex_cover():
    """Koenig's construction against exhaustive search on small bipartite graphs."""
    from itertools import combinations
    rng = np.random.default_rng(0)
    for _ in range(200):
        n_left, n_right, m = rng.integers(1, 7), rng.integers(1, 7), rng.integers(1, 12)
        left, right = rng.integers(0, n_left, m), 100 + rng.integers(0, n_right, m)
        cover = set(mf.minimum_cover(left, right).tolist())
        assert all(a in cover or b in cover for a, b in zip(left, right))
        vertices = sorted(set(left.tolist()) | set(right.tolist()))
        smallest = next(k for k in range(len(vertices) + 1)
                        if any(all(a in S or b in S for a, b in zip(left, right))
                               for S in map(set, combinations(vertices, k))))
        assert len(cover) == smallest
    assert len(mf.minimum_cover(np.zeros(0, int), np.zeros(0, int))) == 0


@pytest.mark.parametrize("backend", ["multifrontal", "metis_superlu"])
def test_pattern_not_symmetric_values_symmetric(backend):
    """A stored zero on one side of the diagonal only (symmetric values, asymmetric
    pattern) once crashed the multifrontal fronts (IndexError) and METIS (a segfault):
    the node graph is built from the symmetrised pattern."""
    L = laplacian(12, 12, 3).tocoo()
    K = sp.csr_matrix((np.append(L.data, 0.0), (np.append(L.row, 396),
                                                 np.append(L.col, 35))), shape=L.shape)
    assert K.nnz == L.nnz + 1                     # (396, 35) stored as 0, (35, 396) not
    assert (K != K.T).nnz == 0
    C = np.arange(30)
    Kc, _ = schur_complement(K, C, backend=backend)
    Kc_ref, _ = reference(K, C)
    assert np.abs(Kc - Kc_ref).max() <= 1e-10 * np.abs(Kc_ref).max()


@pytest.mark.parametrize("backend", ["multifrontal", "metis_superlu", "splu"])
def test_negative_diagonal_is_refused_by_every_backend(backend):
    """An isolated E DOF with a negative diagonal: the LU pivot ratio d_i / a_i is 1
    there, so only the input check can see that K is not positive definite."""
    K = laplacian(6, 6).tolil()
    K[5, :] = 0.0
    K[:, 5] = 0.0
    K[5, 5] = -1.0
    with pytest.raises(InputError, match="not positive definite.*K\\[5, 5\\]"):
        schur_complement(K.tocsr(), np.arange(30, 36), backend=backend)
