"""Schur complement backends: every registered backend against a dense reference."""
import importlib.util

import numpy as np
import pytest
import scipy.sparse as sp

from qsma._infra import dense
from qsma.reduction import schur
from qsma.reduction.schur import metis_superlu, registry, superlu, superlu_schur
from qsma.errors import InputError
from qsma.examples import sandwich_2d
from qsma.fe import assemble_body
from qsma.reduction.schur import AUTO_ORDER, SCHUR_BACKENDS, available_backends, schur_complement
from qsma.model import make_pairing
from helpers import assert_same_solve_bits

RTOL = 1e-10


def _backend(name):
    """Skip when the backend's optional package is missing."""
    requires = SCHUR_BACKENDS[name].requires
    if requires is not None:
        pytest.importorskip(requires)
    return name


def laplacian_2d(nx, ny, shift=1e-3):
    """5-point Laplacian on an nx x ny grid plus ``shift * I`` (SPD)."""
    lap = lambda m: sp.diags([-1.0, 2.0, -1.0], [-1, 0, 1], shape=(m, m))
    K = sp.kron(sp.identity(ny), lap(nx)) + sp.kron(lap(ny), sp.identity(nx))
    return (K + shift * sp.identity(nx * ny)).tocsr()


def sandwich_body():
    """Free DOFs of the bottom beam of sandwich-2d (refine 1) and the positions of its
    interface DOFs among them, in pair order."""
    model = sandwich_2d(1)
    a = assemble_body(model.bodies[0])
    nodes = make_pairing(model).nodes1
    dofs = (2 * nodes[:, None] + np.arange(2)).ravel()
    C = np.searchsorted(a.free, dofs)
    assert np.array_equal(a.free[C], dofs)
    return a.K.tocsr()[a.free][:, a.free], C


def random_spd(n, density, seed):
    rng = np.random.default_rng(seed)
    B = sp.random(n, n, density=density, random_state=rng)
    return (B @ B.T + n * sp.identity(n)).tocsr()


def problems():
    rng = np.random.default_rng(0)
    K1 = laplacian_2d(12, 9)
    K3 = random_spd(80, 0.03, 3)
    return {
        "laplacian": (K1, rng.permutation(K1.shape[0])[:17]),
        "elasticity": sandwich_body(),
        "random": (K3, np.array([5, 79, 0, 33, 12])),
    }


PROBLEMS = problems()


def dense_reference(K, C):
    K = K.toarray()
    E = np.setdiff1d(np.arange(len(K)), C)
    Kc = K[np.ix_(C, C)] - K[np.ix_(C, E)] @ np.linalg.solve(K[np.ix_(E, E)], K[np.ix_(E, C)])
    return Kc, K[np.ix_(E, E)], E


@pytest.mark.parametrize("name", sorted(SCHUR_BACKENDS))
@pytest.mark.parametrize("problem", sorted(PROBLEMS))
def test_backend_matches_dense_reference(name, problem):
    K, C = PROBLEMS[problem]
    Kc, solver = schur_complement(K, C, backend=_backend(name))
    Kc_ref, K_EE, E = dense_reference(K, C)
    assert Kc.shape == (len(C), len(C))
    np.testing.assert_array_equal(Kc, Kc.T)
    assert np.abs(Kc - Kc_ref).max() <= RTOL * np.abs(Kc_ref).max()
    np.testing.assert_array_equal(solver.E, E)
    assert solver.backend == name and solver.min_pivot_ratio > schur.PIVOT_RATIO_MIN
    rng = np.random.default_rng(7)
    B = rng.normal(size=(len(E), 3))
    X = solver(B)
    x = solver(B[:, 1])
    X_ref = np.linalg.solve(K_EE, B)
    assert X.shape == B.shape and x.shape == (len(E),)
    # backward error at round-off; forward error within cond(K_EE) eps (2.7e6 for the
    # sandwich beam, so the dense reference itself is only good to ~1e-10)
    scale = np.abs(K_EE).max() * np.abs(X).max()
    assert np.abs(K_EE @ X - B).max() <= 1e-13 * scale
    forward = RTOL * np.linalg.cond(K_EE) * np.finfo(float).eps / 1e-10
    assert np.abs(X - X_ref).max() <= max(RTOL, forward) * np.abs(X_ref).max()
    assert np.abs(x - X[:, 1]).max() <= 1e-12 * np.abs(X).max()
    assert solver(np.zeros((len(E), 0))).shape == (len(E), 0)


@pytest.mark.parametrize("name", sorted(SCHUR_BACKENDS))
def test_rows_follow_the_order_of_C(name):
    K, C = PROBLEMS["laplacian"]
    perm = np.random.default_rng(2).permutation(len(C))
    Kc, _ = schur_complement(K, C, backend=_backend(name))
    Kc_p, _ = schur_complement(K, C[perm], backend=name)
    np.testing.assert_allclose(Kc_p, Kc[np.ix_(perm, perm)], rtol=0, atol=1e-12 * abs(Kc).max())


@pytest.mark.parametrize("name", sorted(SCHUR_BACKENDS))
@pytest.mark.parametrize("C", [[0, 1], [0]], ids=["one-node", "one-dof"])
def test_singular_K_EE_raises_input_error(name, C):
    # the whole sandwich beam without its clamp: held by one node, it can still rotate
    a = assemble_body(sandwich_2d(1).bodies[0])
    with pytest.raises(InputError, match="singular or not positive definite"):
        schur_complement(a.K.tocsr(), np.array(C), backend=_backend(name))


def test_auto_takes_the_first_available_backend_in_auto_order():
    """multifrontal only for matrices of at least 2.5 DOFs per node (3D solids): the
    random matrix (one DOF per supervariable) and the sandwich-2d beam go to the next
    backend, the 3D Laplacian's Kronecker product with a 3 x 3 block does not."""
    first = lambda skip: next(n for n in AUTO_ORDER if n in available_backends()
                              and n not in skip)
    skip = {"multifrontal"}
    for name in ("random", "elasticity"):
        _, solver = schur_complement(*PROBLEMS[name])
        assert solver.backend == first(skip)
    assert {"splu", "superlu_schur"} <= set(available_backends())
    K3 = sp.kron(laplacian_3d(6), sp.csr_matrix(np.array([[4.0, 1, 0], [1, 4, 1],
                                                            [0, 1, 4]]))).tocsr()
    assert schur.suits_multifrontal(K3)
    assert not schur.suits_multifrontal(PROBLEMS["elasticity"][0])
    _, solver = schur_complement(K3, np.arange(0, K3.shape[0], 7))
    assert solver.backend == first(set())


def test_superlu_schur_falls_back_to_the_dense_solve(monkeypatch):
    monkeypatch.setattr(superlu_schur, "_superlu_trailing_schur", lambda Kp, nE: None)
    K, C = PROBLEMS["laplacian"]
    Kc, _ = schur_complement(K, C, backend="superlu_schur")
    Kc_ref, _, _ = dense_reference(K, C)
    assert np.abs(Kc - Kc_ref).max() <= RTOL * np.abs(Kc_ref).max()


def test_registry_decorator_adds_a_backend(monkeypatch):
    monkeypatch.setattr(registry, "SCHUR_BACKENDS", dict(SCHUR_BACKENDS))

    @schur.register_backend("dense_test")
    def _dense(K, C, E):
        Kc, K_EE, _ = dense_reference(K, C)
        return schur.SchurParts(Kc, lambda b: np.linalg.solve(K_EE, b), 1.0)

    Kc, solver = schur_complement(*PROBLEMS["random"], backend="dense_test")
    assert solver.backend == "dense_test" and "dense_test" in available_backends()


@pytest.mark.parametrize("K, C, message", [
    (sp.identity(4, format="csr"), np.array([0, 0]), "repeated"),
    (sp.identity(4, format="csr"), np.array([4]), "outside"),
    (sp.identity(4, format="csr"), np.array([0.5]), "integer"),
    (sp.identity(4, format="csr"), np.arange(4), "between 1 and n - 1"),
    (sp.identity(4, format="csr"), np.array([], dtype=int), "between 1 and n - 1"),
    (np.eye(4), np.array([0]), "scipy sparse"),
    (sp.csr_matrix(np.triu(np.ones((4, 4)))), np.array([0]), "symmetric"),
    (sp.csr_matrix((4, 4)), np.array([0]), "not all zero"),
])
def test_bad_input_is_rejected(K, C, message):
    with pytest.raises(InputError, match=message):
        schur_complement(K, C, backend="splu")


def test_unknown_or_missing_backend():
    K, C = PROBLEMS["random"]
    with pytest.raises(InputError, match="unknown Schur backend 'nope'; registered"):
        schur_complement(K, C, backend="nope")
    missing = [n for n, b in SCHUR_BACKENDS.items()
               if b.requires and importlib.util.find_spec(b.requires) is None]
    for name in missing:
        with pytest.raises(InputError, match="not installed"):
            schur_complement(K, C, backend=name)


def test_solver_rejects_wrong_shapes():
    K, C = PROBLEMS["random"]
    _, solver = schur_complement(K, C, backend="splu")
    for b in (np.ones(3), np.ones((solver.n + 1, 2)), np.ones((solver.n, 2, 2))):
        with pytest.raises(InputError, match="right-hand side must have shape"):
            solver(b)
    assert "EESolver(n=75, backend='splu'" in repr(solver)


@pytest.mark.parametrize("backend", ["auto", "metis_superlu", "superlu_schur"])
def test_spd_solver_solves_and_refuses_a_singular_matrix(backend):
    """``spd_solver`` (tied-mode shift-invert) whatever the ordering: residual at
    round-off on the sandwich beam, InputError on a matrix with a null vector."""
    K, _ = PROBLEMS["elasticity"]
    solve = schur.spd_solver(K, backend=backend)
    b = np.random.default_rng(2).normal(size=(K.shape[0], 3))
    x = solve(b)
    scale = abs(K).max() * np.abs(x).max()
    assert np.abs(K @ x - b).max() <= 1e-12 * scale
    np.testing.assert_allclose(solve(b[:, 0]), x[:, 0], rtol=0, atol=1e-12 * np.abs(x).max())
    lap = laplacian_2d(8, 7, shift=0.0)
    neumann = lap - sp.diags(np.asarray(lap.sum(axis=1)).ravel())   # constants: null space
    with pytest.raises(InputError, match="singular or not positive definite"):
        schur.spd_solver(neumann.tocsr(), backend=backend)


def test_peak_memory_sees_a_large_allocation():
    """The peak resident memory reported for results.json rises by what a 160 MiB
    block touches (Linux VmHWM, reset first; elsewhere ru_maxrss, never lower).

    The block is a fresh anonymous mapping written page by page, so its pages become
    resident here whatever the allocator keeps: a numpy array was once served from
    pages already resident in a loaded CI run (VmRSS 515 MB before and after)."""
    import mmap
    from qsma._infra import resources as _resources
    _resources.reset_peak()
    before = _resources.peak_memory_mb()
    if before is None:
        pytest.skip("peak memory is not reported on this platform (Windows)")
    size = 160 * 2**20
    block = mmap.mmap(-1, size)
    pages = np.frombuffer(block, dtype=np.uint8)
    pages[::mmap.PAGESIZE] = 1                    # one write per page: all resident
    after = _resources.peak_memory_mb()
    snap = _resources.snapshot()                 # rounded to 0.1 MB
    assert pages[-mmap.PAGESIZE] == 1            # the block is alive and written
    assert after - before >= 150
    assert snap["peak_memory_mb"] >= after - 0.1 and snap["cpu_s"] > 0
    del pages
    block.close()


# ---------------------------------------------------------------- in-place symmetry
def test_symmetrised_in_place_equals_the_half_sum_bit_for_bit():
    """Blocked in place (blocks smaller than the matrix) and the same bits as
    ``0.5 * (A + A.T)``; no copy is returned."""
    A = np.random.default_rng(3).standard_normal((1100, 1100))
    ref = 0.5 * (A + A.T)
    out = dense.symmetrised(A)
    assert out is A and np.array_equal(out, ref)


@pytest.mark.parametrize("source", ["upper", "lower"])
def test_mirror_triangle_copies_one_triangle(source):
    A = np.random.default_rng(4).standard_normal((1030, 1030))
    keep = np.triu(A) if source == "upper" else np.tril(A)
    expected = keep + (np.triu(A, 1).T if source == "upper" else np.tril(A, -1).T)
    assert np.array_equal(dense.mirror_triangle(A, source), expected)


# ----------------------------------------------------------------------------------
# Supervariables and the nested-dissection ordering on their quotient graph

def _groups_by_brute_force(A):
    out = [0]
    for i in range(1, A.shape[0]):
        same = np.array_equal(A.indices[A.indptr[i]:A.indptr[i + 1]],
                              A.indices[A.indptr[i - 1]:A.indptr[i]])
        out.append(out[-1] + (not same))
    return np.array(out)


@pytest.mark.parametrize("seed", range(8))
def test_supervariables_are_runs_of_rows_with_one_pattern(seed):
    """Node blocks of 1-3 DOFs with a few entries added that break some blocks: the
    groups equal a row-by-row comparison of the patterns."""
    rng = np.random.default_rng(seed)
    R = sp.random(40, 40, density=0.1, random_state=seed)
    dofs = int(rng.integers(1, 4))
    A = sp.kron(R + R.T + sp.identity(40), np.ones((dofs, dofs))).tolil()
    for _ in range(3):
        A[rng.integers(0, A.shape[0]), rng.integers(0, A.shape[0])] = 0.5
    A = A.tocsr()
    A.sort_indices()
    np.testing.assert_array_equal(schur.supervariables(A), _groups_by_brute_force(A))


def test_nested_dissection_keeps_a_node_together_and_orders_with_little_fill():
    """On the bottom beam of sandwich-2d (2 DOFs a node) the permutation lists each
    node's DOFs consecutively, and SuperLU on the reordered matrix fills less than in
    the natural order."""
    pytest.importorskip("pymetis")
    import scipy.sparse.linalg as spla
    K, C = sandwich_body()
    E = np.setdiff1d(np.arange(K.shape[0]), C)
    A = K[E][:, E].tocsr()
    p = schur.nested_dissection(A)
    np.testing.assert_array_equal(np.sort(p), np.arange(A.shape[0]))
    group = schur.supervariables(A)
    assert group[-1] + 1 < A.shape[0]                     # nodes were merged
    runs = group[p]                                       # each group once, unbroken
    assert np.count_nonzero(np.diff(runs)) == group[-1]
    fill = lambda B: spla.splu(B.tocsc(), permc_spec="NATURAL", diag_pivot_thresh=0.0,
                               options={"SymmetricMode": True}).L.nnz
    assert fill(A[p][:, p]) < fill(A)


def test_dropping_scipys_cached_factor_copies_keeps_the_solver():
    """scipy's SuperLU keeps the CSC copies of L and U built at the first access of
    either; after ``_drop_extracted_factors`` they hold no entries (where scipy caches
    them: the same object at every access) and ``solve`` is still exact."""
    import scipy.sparse.linalg as spla
    A = laplacian_2d(30, 20)
    lu, ratio, _ = superlu._superlu(A)                  # reads lu.U, then drops
    assert ratio > 0
    b = np.random.default_rng(0).standard_normal(A.shape[0])
    assert np.abs(A @ lu.solve(b) - b).max() < 1e-12 * np.abs(b).max()
    if lu.L is lu.L:                                   # cached by this scipy
        assert lu.L.nnz == 0 and lu.U.nnz == 0
    fresh = spla.splu(A.tocsc())
    assert fresh.L.nnz > 0                             # the copies are not shared


# ----------------------------------------------------------------------------------
# Multi-RHS solves in column blocks on several threads

def laplacian_3d(n, shift=1e-2):
    """7-point Laplacian on an n x n x n grid plus ``shift * I`` (SPD, a 3D fill)."""
    lap = sp.diags([-1.0, 2.0, -1.0], [-1, 0, 1], shape=(n, n))
    eye = sp.identity(n)
    K = (sp.kron(sp.kron(lap, eye), eye) + sp.kron(sp.kron(eye, lap), eye)
         + sp.kron(sp.kron(eye, eye), lap))
    return (K + shift * sp.identity(n ** 3)).tocsr()


@pytest.mark.parametrize("backend", ["metis_superlu", "multifrontal", "splu",
                                     "superlu_schur"])
def test_threaded_solves_equal_serial_ones_bit_for_bit(backend, monkeypatch):
    """The K_EE solver of a backend on 1, 2 and 3 threads (QSMA_SOLVE_THREADS) gives
    the same bits for every column (the solves run on one BLAS thread whatever the
    process setting: with several the bits of a solve depend on its width), also in
    another block of even offset, and solves the system (residual). Bit for bit on
    the OpenBLAS kernels that pair columns (helpers.PAIRWISE_KERNELS), else to 1e-14."""
    _backend(backend)
    K = laplacian_3d(14)
    C = np.arange(0, K.shape[0], 37)
    _, solve = schur_complement(K, C, backend=backend)
    B = np.random.default_rng(4).standard_normal((solve.n, 25))
    results = {}
    for threads in ("1", "2", "3"):
        monkeypatch.setenv("QSMA_SOLVE_THREADS", threads)
        results[threads] = solve(B)
    monkeypatch.setenv("QSMA_SOLVE_THREADS", "1")
    other = solve(B[:, 6:18])
    assert_same_solve_bits(results["1"], results["2"])
    assert_same_solve_bits(results["1"], results["3"])
    assert_same_solve_bits(other, results["1"][:, 6:18])
    K_EE = K[solve.E][:, solve.E]
    X = results["2"]
    assert np.abs(K_EE @ X - B).max() < 1e-12 * np.abs(B).max() * 100


def test_solved_by_columns_splits_and_passes_errors_on():
    """Blocks of at least SOLVE_MIN_COLUMNS columns, one per thread, in order; a vector
    or a narrow block is one plain call; an exception in a worker thread reaches the
    caller."""
    seen = []

    def solve(b):
        seen.append(b.shape[1] if b.ndim == 2 else 0)
        return 2.0 * b

    B = np.arange(60.0).reshape(4, 15)
    assert np.array_equal(schur.solved_by_columns(solve, B, threads=2), 2.0 * B)
    assert sorted(seen) == [7, 8]
    seen.clear()
    narrow = B[:, :2 * schur.SOLVE_MIN_COLUMNS - 1]
    schur.solved_by_columns(solve, narrow, threads=4)
    assert seen == [narrow.shape[1]]
    seen.clear()
    schur.solved_by_columns(solve, B[:, 0], threads=2)
    assert seen == [0]

    def failing(b):
        if b[0, 0] > 0:                                  # the second block only
            raise ValueError("worker failed")
        return b
    with pytest.raises(ValueError, match="worker failed"):
        schur.solved_by_columns(failing, B, threads=2)


@pytest.mark.parametrize("value", ["0", "-2", "two", "1.5"])
def test_bad_solve_thread_setting_is_refused(value, monkeypatch):
    from qsma._infra.threads import solve_threads
    monkeypatch.setenv("QSMA_SOLVE_THREADS", value)
    with pytest.raises(InputError, match="QSMA_SOLVE_THREADS must be a positive integer"):
        solve_threads()
    with pytest.raises(InputError, match="QSMA_SOLVE_THREADS"):      # at the solve
        schur.solved_by_columns(lambda b: b, np.ones((3, 12)))


@pytest.mark.parametrize("value", [0, -1, 1.5, True, "2"])
def test_bad_solve_thread_argument_is_refused(value):
    from qsma._infra.threads import solve_threads
    with pytest.raises(InputError, match="solve threads must be a positive integer"):
        solve_threads(value)


def test_solve_threads_default_and_setting(monkeypatch):
    import os
    from qsma._infra.threads import solve_threads
    monkeypatch.delenv("QSMA_SOLVE_THREADS", raising=False)
    assert solve_threads() == max(1, min(2, len(os.sched_getaffinity(0))))
    monkeypatch.setenv("QSMA_SOLVE_THREADS", " 3 ")
    assert solve_threads() == 3
    assert solve_threads(np.int64(4)) == 4


@pytest.mark.parametrize("problem", ["laplacian_3d", "elasticity"])
def test_coupling_read_from_the_columns_of_U_equals_the_sliced_one(problem, monkeypatch):
    """``_coupling_transposed`` (U_EC^T read from the arrays of U's interface columns)
    gives the same Schur complement as slicing ``U[:nE, nE:]`` (the former path, kept
    as its fallback): the same entries in the same order, so the same bits; and it
    equals the dense reference."""
    _backend("metis_superlu")
    if problem == "laplacian_3d":
        K = laplacian_3d(12)
        C = np.random.default_rng(5).permutation(K.shape[0])[:150]
    else:
        K, C = PROBLEMS["elasticity"]
    seen = []
    original = metis_superlu._coupling_transposed

    def spy(U, nE):
        L_CE = original(U, nE)
        sliced = U[:nE, nE:].tocsr().T.tocsr()
        seen.append(abs(L_CE - sliced).max())
        return L_CE
    monkeypatch.setattr(metis_superlu, "_coupling_transposed", spy)
    Kc_new, _ = schur_complement(K, C, backend="metis_superlu")
    assert seen == [0.0]
    monkeypatch.setattr(metis_superlu, "_coupling_transposed",
                        lambda U, nE: U[:nE, nE:].tocsr().T.tocsr())
    Kc_old, _ = schur_complement(K, C, backend="metis_superlu")
    assert np.array_equal(Kc_new, Kc_old)
    ref, _, _ = dense_reference(K, C)
    assert np.abs(Kc_new - ref).max() < RTOL * np.abs(ref).max()


def test_coupling_falls_back_to_slicing_when_the_trailing_block_is_not_identity():
    U = sp.csc_matrix(np.array([[2.0, 0.5, 0.3],
                                [0.0, 3.0, 0.7],
                                [0.0, 0.1, 1.0]]))       # an entry below the unit
    L_CE = metis_superlu._coupling_transposed(U, 1)
    assert np.array_equal(L_CE.toarray(), np.array([[0.5], [0.3]]))
    U = sp.csc_matrix(np.array([[2.0, 0.5, 0.3],
                                [0.0, 1.0, 0.0],
                                [0.0, 0.0, 1.0]]))
    assert np.array_equal(metis_superlu._coupling_transposed(U, 1).toarray(),
                          np.array([[0.5], [0.3]]))


def test_one_blas_thread_nests_and_restores_the_setting():
    """Inside ``one_blas_thread`` BLAS has one thread, also in a nested block and in a
    worker thread; leaving the outermost block restores the previous limit."""
    import threading
    from threadpoolctl import threadpool_info, threadpool_limits
    from qsma._infra.threads import one_blas_thread

    def blas_threads():
        return {i["num_threads"] for i in threadpool_info() if i["user_api"] == "blas"}
    with threadpool_limits(limits=2, user_api="blas"):
        before = blas_threads()
        seen = []
        with one_blas_thread():
            with one_blas_thread():
                seen.append(blas_threads())
            worker = threading.Thread(target=lambda: seen.append(blas_threads()))
            worker.start()
            worker.join()
            seen.append(blas_threads())
        assert seen == [{1}, {1}, {1}]
        assert blas_threads() == before
