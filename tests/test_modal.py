"""Tied linear modes of sandwich-2d."""
import numpy as np
import pytest

from qsma.errors import InputError
from qsma.examples import sandwich_2d
from qsma.fe import assemble_body
from qsma.modal import linear_modes, mode_tip, stacked
from qsma.model import make_pairing
from helpers import assert_same_solve_bits

# Euler-Bernoulli first clamped-free frequencies with E/(1 - nu^2) (sandwich-2d.md):
F_TWO_BEAMS, F_SOLID = 142.7, 285.3


def _setup(refine):
    m = sandwich_2d(refine)
    return m, [assemble_body(b) for b in m.bodies], make_pairing(m)


def test_sandwich_reference_mesh_sizes():
    m, _, p = _setup(1)
    assert m.n_nodes == 2250 and p.n_pairs == 65
    assert np.allclose(p.normals, [0.0, 1.0]) and np.allclose(p.frames[:, 0], [1.0, 0.0])


def test_tied_first_bending_between_bounds_and_converging():
    rows = []
    for r in (1, 2, 4):
        m, A, p = _setup(r)
        f = linear_modes(m, A, p, n_modes=3).f_hz[0]
        rows.append((r, m.n_nodes, f))
    print("\nrefine  nodes   f1 tied-all [Hz]")
    for r, n, f in rows:
        print(f"{r:6d} {n:6d} {f:12.3f}")
    f = np.array([row[2] for row in rows])
    assert np.all((F_TWO_BEAMS < f) & (f < F_SOLID))
    diffs = np.abs(np.diff(f))
    assert np.all(np.diff(f) < 0)            # stiffness converges from above (locking)
    assert diffs[1] < 0.5 * diffs[0]         # successive changes shrink
    assert diffs[1] / f[-1] < 0.01


def test_untied_is_two_separate_beams():
    m, A, p = _setup(1)
    f = linear_modes(m, A, p, tied=np.zeros(p.n_pairs, bool), n_modes=2).f_hz
    assert f[0] == pytest.approx(f[1], rel=1e-6)          # two identical beams
    assert f[0] == pytest.approx(F_TWO_BEAMS, rel=0.04)    # refine 1, Q1 locking


def test_modes_mass_normalised_and_ties_hold():
    m, A, p = _setup(1)
    md = linear_modes(m, A, p, n_modes=3)
    M = stacked([a.M for a in A])
    G = md.shapes.T @ (M @ md.shapes)
    assert np.abs(G - np.eye(3)).max() < 1e-9
    off = m.dof_offsets()
    for c in range(2):
        u1 = md.shapes[off[0] + 2 * p.nodes1 + c]
        u2 = md.shapes[off[1] + 2 * p.nodes2 + c]
        assert np.abs(u1 - u2).max() == 0.0                # elimination, not penalty
    assert abs(mode_tip(md, m, 0)) > 0


def test_bad_tie_mask_rejected():
    m, A, p = _setup(1)
    with pytest.raises(InputError, match="tied mask"):
        linear_modes(m, A, p, tied=np.ones(3, bool))


# ----------------------------------------------------------------------------------
# Shift-invert through the condensation's factors (qsma.modal.SubstructuredInverse)

import dataclasses  # noqa: E402

from qsma.analysis import StageClock, prepare  # noqa: E402
from qsma.examples import lap_2d, lap_2d_free  # noqa: E402
from qsma.examples.bolted import BOLT_2D, lap_2d_bolted  # noqa: E402
from qsma.modal import identity_rows, substructured_inverse, tie_transform  # noqa: E402
from qsma.model import Bolt  # noqa: E402
from qsma.analysis.options import RunOptions  # noqa: E402


def _mortar_lap(free=(), bolt=False):
    """lap-2d with 23 top elements against 30 in the overlap (dual mortar), optionally
    a bolt instead of the pressures and the bodies in ``free`` unclamped."""
    m = lap_2d(1, top_overlap_elements=23)
    bodies = tuple(dataclasses.replace(b, pressures=() if bolt else b.pressures,
                                       clamps=() if b.name in free else b.clamps)
                   for b in m.bodies)
    bolts = (Bolt("bolt", "bottom", "bolt", "top", "bolt", BOLT_2D["pretension"],
                  BOLT_2D["stiffness"]),) if bolt else ()
    return dataclasses.replace(m, bodies=bodies, bolts=bolts)


MODELS = {
    "sandwich-2d": lambda: sandwich_2d(1),
    "lap-2d-free": lambda: lap_2d_free(1),
    "lap-2d-bolted": lambda: lap_2d_bolted(1),
    "lap-2d-bolted-top": lambda: lap_2d_bolted(1, free="top"),
    "lap-2d-bolted-free": lambda: lap_2d_bolted(1, free="all"),
    "mortar-lap": lambda: _mortar_lap(),
    "mortar-bolted-free": lambda: _mortar_lap(("bottom", "top"), bolt=True),
}


def _preloaded(name):
    p = prepare(MODELS[name]())
    reduced, _, pre = p.preloaded(RunOptions(), StageClock())
    return p, reduced, pre.status != 2


@pytest.mark.parametrize("name", sorted(MODELS))
def test_modes_through_the_condensation_equal_the_factorised_tied_stiffness(name):
    """The substructured shift-invert (per-body K_EE factors of the condensation, open
    pairs released on the dense interface, bolts by Woodbury, free-free rigid motions
    projected out) gives the modes of the factorised tied assembly. Measured (refine 1,
    closed pairs of the preload): frequencies to 3e-10 (lap-2d with a mortar interface
    and a bolt, top plate free), 7e-11 on sandwich-2d; shapes to 6e-11 of their
    largest entry; the difference is round-off of the two solvers amplified by the
    ARPACK iteration. sandwich-3d refine 1: f0 218.1947156114 / 218.1947156181 Hz."""
    p, reduced, closed = _preloaded(name)
    args = (p.model, p.assembled, p.pairing)
    full = linear_modes(*args, tied=closed, n_modes=4)
    sub = linear_modes(*args, tied=closed, n_modes=4, reduced=reduced)
    T = tie_transform(*args, closed)
    M = T.T @ stacked([a.M for a in p.assembled]) @ T
    assert substructured_inverse(*args, closed, reduced, T, M) is not None   # used
    r = full.n_rigid
    assert sub.n_rigid == r == (3 if "free" in name else 0)
    np.testing.assert_allclose(sub.f_hz[r:], full.f_hz[r:], rtol=2e-9)
    assert np.all(sub.omega[:r] == 0.0)
    Mall = stacked([a.M for a in p.assembled])
    for j in range(r, len(full.omega)):
        a, b = full.shapes[:, j], sub.shapes[:, j]
        b = b * np.sign(a @ (Mall @ b))
        assert np.abs(a - b).max() < 1e-9 * np.abs(a).max()
    G = sub.shapes.T @ (Mall @ sub.shapes)                 # rigid modes included
    assert np.abs(G - np.eye(len(sub.omega))).max() < 1e-9


@pytest.mark.parametrize("name", ["lap-2d-bolted-top", "mortar-bolted-free"])
def test_substructured_inverse_solves_the_tied_stiffness(name):
    """``(T^T K T) x = b`` to round-off for a random load (with the bolt stiffness;
    free-free: for a self-equilibrated load, up to a rigid motion)."""
    from qsma.fe.bolts import bolt_stiffness
    from qsma.reduction.rigid import assembly_motions
    p, reduced, closed = _preloaded(name)
    args = (p.model, p.assembled, p.pairing)
    T = tie_transform(*args, closed)
    K = T.T @ (stacked([a.K for a in p.assembled]) + bolt_stiffness(p.model)) @ T
    M = T.T @ stacked([a.M for a in p.assembled]) @ T
    inv = substructured_inverse(*args, closed, reduced, T, M)
    b = np.random.default_rng(1).standard_normal(T.shape[1])
    Z = assembly_motions(p.model, p.assembled)[identity_rows(T)]
    if Z.shape[1]:
        b -= M @ Z @ np.linalg.solve(Z.T @ M @ Z, Z.T @ b)
    x = inv(b)
    assert np.abs(K @ x - b).max() < 1e-9 * np.abs(b).max()
    assert np.abs(Z.T @ (M @ x)).max(initial=0.0) < 1e-12 * np.abs(M @ x).sum()


def test_identity_rows_pick_the_unknowns_of_the_tie():
    m, A, p = _setup(1)
    T = tie_transform(m, A, p, np.ones(p.n_pairs, bool))
    rows = identity_rows(T)
    np.testing.assert_array_equal(T[rows].toarray(), np.eye(T.shape[1]))
    assert identity_rows(T.multiply(0.5).tocsr()) is None


def test_mechanism_falls_back_to_the_full_factorisation():
    """Pairs tied that do not hold the bodies together (none tied, the top plate free):
    the substructured path declines and the full path names the free body."""
    p, reduced, _ = _preloaded("lap-2d-bolted-top")
    none = np.zeros(p.pairing.n_pairs, bool)
    T = tie_transform(p.model, p.assembled, p.pairing, none)
    M = T.T @ stacked([a.M for a in p.assembled]) @ T
    assert substructured_inverse(p.model, p.assembled, p.pairing, none, reduced, T,
                                 M) is None
    with pytest.raises(InputError, match="not held|rigid-body"):
        linear_modes(p.model, p.assembled, p.pairing, tied=none, n_modes=2,
                     reduced=reduced)


# ----------------------------------------------------------------------------------
# Block Krylov shift-invert (qsma.modal.block_shift_invert)

import scipy.sparse as sp  # noqa: E402
import scipy.sparse.linalg as spla  # noqa: E402
import scipy.linalg as sla  # noqa: E402

from qsma.modal import eigen as modal  # noqa: E402


def _chain(n):
    """Fixed-free chain of n unit masses and unit springs: ``K`` tridiagonal, ``M = I``,
    eigenvalues ``4 sin^2((2j - 1) pi / (2 (2n + 1)))``, j = 1..n."""
    K = sp.diags([-np.ones(n - 1), np.r_[2.0 * np.ones(n - 1), 1.0], -np.ones(n - 1)],
                 [-1, 0, 1], format="csc")
    j = np.arange(1, n + 1)
    return K, sp.identity(n, format="csc"), 4 * np.sin((2 * j - 1) * np.pi / (2 * (2 * n + 1))) ** 2


@pytest.mark.parametrize("k, block", [(6, 6), (6, 2), (1, 6), (12, 4)])
def test_block_shift_invert_gives_the_chain_spectrum(monkeypatch, k, block):
    """The k lowest eigenvalues of the chain to 1e-12, M-orthonormal vectors whose
    shift-invert residuals ``|K^-1 M x - x / lam|_M`` are below 1e-10 / lam (the
    solver's criterion is 1e-11); blocks narrower than k included."""
    monkeypatch.setattr(modal, "EIG_BLOCK", block)
    K, M, exact = _chain(400)
    lu = spla.splu(K)
    applied = []

    def solve(B):
        applied.append(B.shape)
        return lu.solve(np.asfortranarray(B))
    lam, vec = modal.block_shift_invert(solve, M, k)
    np.testing.assert_allclose(lam, exact[:k], rtol=1e-12)
    np.testing.assert_allclose(vec.T @ (M @ vec), np.eye(k), atol=1e-12)
    res = lu.solve(np.asfortranarray(M @ vec)) - vec / lam      # S x - mu x
    assert np.all(np.sqrt(np.einsum("ik,ik->k", res, M @ res)) < 1e-10 / lam)
    assert all(s[1] <= block for s in applied)            # the operator saw blocks


@pytest.mark.parametrize("n", [9, 14, 30])
def test_block_shift_invert_on_a_space_it_exhausts(n):
    """Few DOFs: the basis reaches the whole space (the next block is numerically in
    its span and dropped); the Ritz pairs are then exact, and returned as such."""
    K, M, exact = _chain(n)
    lu = spla.splu(K)
    lam, vec = modal.block_shift_invert(lambda B: lu.solve(np.asfortranarray(B)), M, 6)
    np.testing.assert_allclose(lam, exact[:6], rtol=1e-11)


def test_block_shift_invert_with_a_start_in_the_null_space_of_the_projection():
    """A start block entirely along the removed motions (here the first unit vector,
    projected out) is replaced by random directions: the answer is unchanged."""
    K, M, exact = _chain(200)
    lu = spla.splu(K)
    Z = np.zeros((200, 1))
    Z[-1] = 1.0
    gram = Z.T @ (M @ Z)

    def solve(B):                      # K^-1 restricted to the M-complement of Z
        X = lu.solve(np.asfortranarray(B - (M @ Z) @ np.linalg.solve(gram, Z.T @ B)))
        return X - Z @ np.linalg.solve(gram, (M @ Z).T @ X)
    lam, vec = modal.block_shift_invert(solve, M, 3, Z, gram, start=Z)
    assert np.all(np.abs(Z.T @ (M @ vec)) < 1e-12)
    # the reference: the operator that ``solve`` applies (M = I), K^-1 compressed to
    # the orthogonal complement of Z, dense; lambda = 1 / mu for its largest mu
    N = sla.null_space(Z.T)
    mu = sla.eigh(N.T @ lu.solve(N), eigvals_only=True)
    ref = 1.0 / mu[::-1][:3]
    np.testing.assert_allclose(lam, ref, rtol=1e-10)


def test_block_shift_invert_finds_every_symmetry_class_from_a_rigid_start():
    """A start of rigid-body fields only has no component in the modes of some symmetry
    classes of a symmetric structure (a box clamped at both ends): the Krylov space
    built from it never reaches them, and an iteration started there alone returned
    the wrong "8 lowest" modes (the one at lambda = 3.19 was missing, 17 % error) as
    converged. The start gets a random part: the eight lowest are found (reference:
    ARPACK shift-invert from its own random start)."""
    from qsma.reduction.rigid import rigid_body_modes
    from qsma.model.body import Body, Material
    from qsma.mesh.generate import structured_mesh
    mesh = structured_mesh(np.linspace(-1, 1, 17), np.linspace(-0.15, 0.15, 5),
                           np.linspace(-0.1, 0.1, 3))
    ab = assemble_body(Body("box", mesh, Material(1.0, 0.3, 1.0)))
    P = mesh.points
    ends = np.flatnonzero(np.abs(np.abs(P[:, 0]) - 1) < 1e-12)
    free = np.setdiff1d(np.arange(3 * len(P)), (3 * ends[:, None] + np.arange(3)).ravel())
    K = ab.K.tocsc()[free][:, free].tocsc()
    M = ab.M.tocsc()[free][:, free].tocsc()
    lu = spla.splu(K)
    exact = np.sort(spla.eigsh(K, k=10, M=M, sigma=0, which="LM")[0])
    for k in (6, 8, 10):
        lam, _ = modal.block_shift_invert(lambda B: lu.solve(np.asfortranarray(B)), M, k,
                                          start=rigid_body_modes(P)[free])
        np.testing.assert_allclose(lam, exact[:k], rtol=1e-10)


def test_block_shift_invert_refuses_to_return_unconverged_modes(monkeypatch):
    """With one restart of one block allowed, the iteration cannot converge and says so
    (AnalysisError), instead of returning the Ritz pairs it has."""
    from qsma.errors import AnalysisError
    monkeypatch.setattr(modal, "EIG_MAX_RESTARTS", 1)
    monkeypatch.setattr(modal, "EIG_MAX_BLOCKS", 2)
    K, M, _ = _chain(400)
    lu = spla.splu(K)
    with pytest.raises(AnalysisError, match="did not converge"):
        modal.block_shift_invert(lambda B: lu.solve(np.asfortranarray(B)), M, 6)


def test_shift_invert_basis_is_written_in_place_and_restarts_as_products():
    """The basis of the block shift-invert lives in preallocated arrays: extending it
    writes the block in place (no copy of the whole basis), a restart keeps
    ``[Q, MQ, W, MW] Y`` and the next block ``W_last - Q (MQ^T W_last)``, as the
    products of the basis it was made from."""
    from qsma.modal.eigen import _Basis
    rng = np.random.default_rng(11)
    n = 40
    blocks = [[rng.standard_normal((n, 3)) for _ in range(4)] for _ in range(2)]
    basis = _Basis.empty(n, 8)
    arrays = basis.arrays
    for block in blocks:
        basis = basis.extended(*block)
    assert basis.size == 6 and all(a is b for a, b in zip(basis.arrays, arrays))
    whole = [np.hstack([blocks[0][i], blocks[1][i]]) for i in range(4)]
    for got, want in zip((basis.Q, basis.MQ, basis.W, basis.MW), whole):
        assert np.array_equal(got, want)
    Y = rng.standard_normal((6, 4))
    W_last = rng.standard_normal((n, 3))
    expected = [w @ Y for w in whole]
    nxt_expected = W_last - whole[0] @ (whole[1].T @ W_last)
    kept, nxt = basis.restarted(Y, W_last)
    assert kept.size == 4
    for got, want in zip((kept.Q, kept.MQ, kept.W, kept.MW), expected):
        assert np.allclose(got, want, rtol=0, atol=1e-13)
    assert np.allclose(nxt, nxt_expected, rtol=0, atol=1e-13)


@pytest.mark.parametrize("name", ["sandwich-2d", "lap-2d-bolted-free"])
def test_tied_modes_on_two_solve_threads_equal_one_bit_for_bit(name, monkeypatch):
    """The shift-invert's K_EE solves split over two threads (QSMA_SOLVE_THREADS=2, the
    12-column blocks of two bodies in two halves) leave the modes bit for bit as on
    one thread (on the OpenBLAS kernels that pair columns, helpers.PAIRWISE_KERNELS;
    elsewhere omega to 1e-11 and the shapes to 1e-10 of their largest entry, as the
    shift-invert carries the round-off on: Nehalem kernel measured 3e-13 and
    1.2e-12), and they still solve the eigenproblem: backward error
    ``|K phi - w^2 M phi| / ((|K| + w^2 |M|) |phi|) <= 1e-12`` per elastic mode (1-norms;
    measured 1e-15 .. 1e-14)."""
    from qsma.fe.bolts import bolt_stiffness
    p, reduced, closed = _preloaded(name)
    args = (p.model, p.assembled, p.pairing)
    modes = {}
    for threads in ("1", "2"):
        monkeypatch.setenv("QSMA_SOLVE_THREADS", threads)
        modes[threads] = linear_modes(*args, tied=closed, n_modes=6, reduced=reduced)
    assert_same_solve_bits(modes["1"].omega, modes["2"].omega, rtol=1e-11)
    assert_same_solve_bits(modes["1"].shapes, modes["2"].shapes, rtol=1e-10)
    T = tie_transform(*args, closed)
    K = T.T @ (stacked([a.K for a in p.assembled]) + bolt_stiffness(p.model)) @ T
    M = T.T @ stacked([a.M for a in p.assembled]) @ T
    m = modes["2"]
    for j in range(m.n_rigid, len(m.omega)):
        phi = m.shapes[identity_rows(T), j]        # the unknowns: T phi = shape
        lam = m.omega[j] ** 2
        scale = (sp.linalg.norm(K, 1) + lam * sp.linalg.norm(M, 1)) * np.abs(phi).sum()
        assert np.abs(K @ phi - lam * (M @ phi)).sum() <= 1e-12 * scale


def test_leading_pairs_converge_first_and_the_iteration_finishes_as_a_whole():
    """``ShiftInvert.leading(1)`` stops as soon as the lowest pair passes the
    convergence test (the chain's lowest eigenvalue to 1e-12, fewer block solves than
    the six pairs need), and ``finish`` goes on from there to the same numbers as an
    uninterrupted ``block_shift_invert``."""
    K, M, exact = _chain(400)
    lu = spla.splu(K)
    applied = []

    def solve(B):
        applied.append(B.shape[1])
        return lu.solve(np.asfortranarray(B))
    iteration = modal.ShiftInvert(solve, M, 6)
    lam1, vec1 = iteration.leading(1)
    n_leading = len(applied)
    np.testing.assert_allclose(lam1, exact[:1], rtol=1e-12)
    res = lu.solve(np.asfortranarray(M @ vec1)) - vec1 / lam1
    assert np.sqrt(np.sum(res * (M @ res))) < 1e-10 / lam1[0]
    lam, vec = iteration.finish()
    assert n_leading < len(applied)
    whole = modal.block_shift_invert(lambda B: lu.solve(np.asfortranarray(B)), M, 6)
    assert np.array_equal(lam, whole[0]) and np.array_equal(vec, whole[1])
    assert modal.same_eigenvalues(lam1, lam[:1])


def test_same_eigenvalues_separates_round_off_from_another_mode():
    """Two converged Ritz values of one eigenvalue differ by at most twice the residual
    floor (relative); a neighbouring eigenvalue of the chain is far outside that."""
    _, _, exact = _chain(400)
    assert modal.same_eigenvalues(exact[:2], exact[:2] * (1 + 1e-9))
    assert not modal.same_eigenvalues(exact[:2], exact[:2] * (1 + 1e-7))
    assert not modal.same_eigenvalues(exact[:1], exact[1:2])
    assert not modal.same_eigenvalues(exact[:1], exact[:2])


def test_leading_modes_that_are_not_the_lowest_of_the_finished_set_are_refused():
    """The modes a run loaded before the iteration finished must be the first of the
    finished set: the same eigenvalues are taken with their leading shapes; a leading
    mode whose eigenvalue the finished set does not start with (a lower mode found
    later) raises AnalysisError instead of reporting modes beside a ramp of another
    mode."""
    from qsma.errors import AnalysisError
    from qsma.modal import Modes
    from qsma.modal.leading import with_leading
    rng = np.random.default_rng(1)
    tied = np.ones(3, bool)
    full = Modes(np.array([10.0, 20.0, 30.0]), rng.standard_normal((8, 3)), tied)
    early = Modes(np.array([10.0 * (1 + 1e-12)]), rng.standard_normal((8, 1)), tied)
    kept = with_leading(full, early)
    assert kept.omega[0] == early.omega[0] and np.array_equal(kept.shapes[:, 0],
                                                              early.shapes[:, 0])
    assert np.array_equal(kept.shapes[:, 1:], full.shapes[:, 1:])
    with pytest.raises(AnalysisError, match="not the lowest"):
        with_leading(full, Modes(np.array([20.0]), rng.standard_normal((8, 1)), tied))
