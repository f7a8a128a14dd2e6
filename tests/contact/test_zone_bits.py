"""The cheaper bookkeeping of the zone's growth moves the same numbers: bordering by
blocks placed as slices, symmetrising in place and the block system's gathers give
the same bits as the element-wise fancy indexing and the copies they replace."""
import numpy as np
import pytest
import scipy.linalg as sla

from qsma.contact import ContactProblem
from qsma.contact import zone as zone_module
from qsma.contact.linear import BlockSystem, free_components, known_displacement
from qsma._infra.dense import SYMMETRISE_ROWS
from qsma.reduction.schur.registry import symmetrised
from qsma.contact.state import OPEN, SLIPPING, STUCK
from qsma.contact.zone import ContactZone, Elimination, _place, _runs, _spd_inverse


def _problem(n=40, dim=3, seed=7, mu=0.3):
    rng = np.random.default_rng(seed)
    A = rng.normal(size=(dim * n, dim * n))
    return ContactProblem(A @ A.T / n + np.diag(np.full(dim * n, 2.0)), mu, dim=dim)


def _reference_bordered(self, pairs):
    """The bordering as first written (np.ix_ assignments, a symmetrised copy): the
    reference the faster one must equal to the bit. Returns ``(S, Bt)``."""
    pairs = np.asarray(pairs, dtype=bool) & ~self.keep
    p, keep = self.problem, self.keep | pairs
    flat = np.repeat(keep, p.dim)
    iA, iO = np.flatnonzero(flat), np.flatnonzero(~flat)
    in_O = np.full(p.size, -1)
    in_O[self.iO] = np.arange(len(self.iO))
    g = in_O[np.flatnonzero(np.repeat(pairs, p.dim))]
    rows = in_O[iO]
    unit = np.zeros((len(self.iO), len(g)))
    unit[g, np.arange(len(g))] = 1.0
    H = self.inverse.solve(unit)
    C = _spd_inverse(H[g])
    CB = C @ self.Bt[g]
    HG = H[rows]
    at_A = np.searchsorted(iA, self.iA)
    at_G = np.searchsorted(iA, self.iO[g])
    S = np.empty((len(iA), len(iA)))
    S[np.ix_(at_A, at_A)] = self.sub.K + self.Bt[g].T @ CB
    S[np.ix_(at_A, at_G)] = CB.T
    S[np.ix_(at_G, at_A)] = CB
    S[np.ix_(at_G, at_G)] = C
    Bt = np.empty((len(iO), len(iA)))
    Bt[:, at_A] = self.Bt[rows] - HG @ CB
    Bt[:, at_G] = -HG @ C
    return 0.5 * (S + S.T), Bt


def _reference_build(problem, keep):
    """The elimination as first written: ``(S symmetrised by a copy, Bt)``."""
    flat = np.repeat(keep, problem.dim)
    iA, iO = np.flatnonzero(flat), np.flatnonzero(~flat)
    K = problem.K
    L = sla.cholesky(K[np.ix_(iO, iO)], lower=True, overwrite_a=True, check_finite=False)
    W = sla.solve_triangular(L, K[np.ix_(iO, iA)], lower=True, overwrite_b=True,
                             check_finite=False)
    S = K[np.ix_(iA, iA)] - W.T @ W
    Bt = sla.solve_triangular(L, W, lower=True, trans="T", overwrite_b=True,
                              check_finite=False)
    return 0.5 * (S + S.T), Bt


def _same_bits(a, b):
    return a.shape == b.shape and np.array_equal(a, b) and (
        np.asarray(a).view(np.int64) == np.asarray(b).view(np.int64)).all()


def test_runs_of_increasing_positions():
    assert _runs(np.array([], int)) == []
    assert _runs(np.array([4])) == [(0, 4, 1)]
    assert _runs(np.array([0, 1, 2, 5, 6, 9])) == [(0, 0, 3), (3, 5, 2), (5, 9, 1)]


@pytest.mark.parametrize("n_runs", [1, 3, 40])
def test_place_equals_fancy_assignment(n_runs, monkeypatch):
    """Blocks written as slices (few runs) or by the fancy fallback (many) land where
    ``out[np.ix_(rows, cols)] = block`` puts them, and nothing else is touched."""
    rng = np.random.default_rng(n_runs)
    n = 300
    cols = np.flatnonzero(np.repeat(rng.random(n // 3) < 0.5, 3))
    rows = np.sort(rng.choice(n, 120, replace=False)) if n_runs == 40 else \
        np.concatenate([np.arange(10 * k, 10 * k + 5) for k in range(n_runs)])
    block = rng.normal(size=(len(rows), len(cols)))
    for limit in (zone_module.PLACE_MAX_BLOCKS, 0):      # slices, then the fallback
        monkeypatch.setattr(zone_module, "PLACE_MAX_BLOCKS", limit)
        for r in (rows, None):
            expected = np.full((n, n), np.nan)
            got = expected.copy()
            b = block if r is not None else rng.normal(size=(n, len(cols)))
            expected[np.ix_(np.arange(n) if r is None else r, cols)] = b
            _place(got, r, cols, b)
            assert np.array_equal(got, expected, equal_nan=True)


@pytest.mark.parametrize("n", [1, 2, SYMMETRISE_ROWS - 1, SYMMETRISE_ROWS,
                               SYMMETRISE_ROWS + 1, 2 * SYMMETRISE_ROWS + 17])
def test_symmetrise_in_place_has_the_bits_of_the_copy(n):
    rng = np.random.default_rng(n)
    A = rng.normal(size=(n, n)) * 10.0 ** rng.integers(-8, 8, size=(n, n))
    expected = 0.5 * (A + A.T)
    out = symmetrised(A)
    assert out is A and _same_bits(A, expected)
    assert np.array_equal(A, A.T)


def test_derived_overwrite_holds_the_array_with_the_same_bits():
    p = _problem(n=50)
    rng = np.random.default_rng(2)
    K = np.array(p.K) + 1e-9 * rng.normal(size=p.K.shape)     # slightly asymmetric
    copied = ContactProblem.derived(K, p.mu, p.gap0, p.dim)
    mine = K.copy()
    held = ContactProblem.derived(mine, p.mu, p.gap0, p.dim, overwrite=True)
    assert held.K is mine and not held.K.flags.writeable
    assert _same_bits(held.K, copied.K)
    assert held.kappa == copied.kappa
    assert _same_bits(held.diagonal_blocks, copied.diagonal_blocks)


@pytest.mark.parametrize("dim", [2, 3])
def test_build_and_chain_of_borderings_equal_the_first_writing_to_the_bit(dim):
    """One elimination, then MAX_BORDERS borderings of one to a few pairs (runs of the
    zone and new pairs in between): every zone stiffness and ``K_OO^-1 K_OA`` has the
    bits of the code with np.ix_ assignments and a symmetrised copy."""
    n = 80
    p = _problem(n=n, dim=dim)
    rng = np.random.default_rng(11)
    keep = rng.random(n) < 0.25
    step = Elimination.build(p, keep)
    S_ref, Bt_ref = _reference_build(p, step.keep)
    assert _same_bits(step.sub.K, S_ref) and _same_bits(step.Bt, Bt_ref)
    for k in range(zone_module.MAX_BORDERS):
        outside = np.flatnonzero(~step.keep)
        pairs = np.zeros(n, bool)
        pairs[rng.choice(outside, 1 + k % 4, replace=False)] = True
        S_ref, Bt_ref = _reference_bordered(step, pairs)
        step = step.bordered(pairs)
        assert step.inverse.depth == k + 1
        assert _same_bits(step.sub.K, S_ref), k
        assert _same_bits(step.Bt, Bt_ref), k
        assert step.sub.K.flags.c_contiguous and step.Bt.flags.c_contiguous


def test_grown_zone_equals_a_fresh_elimination_after_faster_bordering():
    """Physics of the bordered zone (not only bits against the old code): the zone
    stiffness is the Schur complement of the eliminated pairs, to 1e-12."""
    p = _problem(n=36)
    zone = ContactZone.build(p, np.arange(36) % 4 == 0)
    for k in range(5):
        pairs = np.zeros(36, bool)
        pairs[[4 * k + 1, 4 * k + 2, 35 - k]] = True
        zone = zone.grown(pairs)
    iA = np.flatnonzero(np.repeat(zone.keep, 3))
    iO = np.flatnonzero(~np.repeat(zone.keep, 3))
    K = p.K
    schur = K[np.ix_(iA, iA)] - K[np.ix_(iA, iO)] @ np.linalg.solve(K[np.ix_(iO, iO)],
                                                                  K[np.ix_(iO, iA)])
    assert zone.steps[0].inverse.depth == 5
    np.testing.assert_allclose(zone.sub.K, schur, rtol=0, atol=1e-12 * np.abs(schur).max())


def test_block_system_rows_have_the_bits_of_the_fancy_gather():
    """``K_RU`` taken from the gathered rows is the C-ordered ``K[np.ix_(R, U)]`` (its
    layout decides the BLAS path of every product with it), and ``f`` is unchanged."""
    p = _problem(n=30)
    rng = np.random.default_rng(5)
    status = rng.choice([OPEN, SLIPPING, STUCK], size=30)
    d_prev = rng.normal(size=(30, 3))
    lam_w = rng.normal(size=p.size)
    system = BlockSystem(p, lam_w, status, d_prev)
    op, sl = np.flatnonzero(status == OPEN), np.flatnonzero(status == SLIPPING)
    unknown = free_components(p, op, sl)
    rows = np.concatenate([unknown[:3 * len(op)], p.tangent_index[sl].ravel(),
                           p.normal_index[sl]])
    assert system.K_RU.flags.c_contiguous
    assert _same_bits(system.K_RU, p.K[np.ix_(rows, unknown)])
    f = p.K[rows] @ known_displacement(p, status, d_prev) + lam_w[rows]
    n_o, k = 3 * len(op), len(sl)
    assert _same_bits(system.f_open, f[:n_o])
    assert _same_bits(system.f_t.ravel(), f[n_o:n_o + 2 * k])
    assert _same_bits(system.f_n, f[n_o + 2 * k:])
