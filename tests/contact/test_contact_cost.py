"""The cheaper forms of the block step and of the products (issue 14) against the plain
forms they replace: same linear system, same products, same measures."""
import numpy as np
import pytest

from qsma.contact import OPEN, SLIPPING, STUCK, ContactProblem, ContactState, solve
from qsma.contact.linear import BlockSystem, basket_system, solve_partitioned
from qsma.contact.residual import measures, products, residual_components


def random_problem(n_pairs, dim, seed, gap=False):
    rng = np.random.default_rng(seed)
    n = n_pairs * dim
    A = rng.normal(size=(n, n))
    K = A @ A.T / n + np.eye(n)
    gap0 = rng.uniform(-1e-3, 1e-3, n_pairs) if gap else None
    return ContactProblem(K, rng.uniform(0.1, 0.8, n_pairs), gap0, dim=dim), rng


@pytest.mark.parametrize("dim", [2, 3])
@pytest.mark.parametrize("seed", range(6))
def test_block_system_solves_the_system_of_basket_system(dim, seed):
    """The step reduced to the unknowns (known components moved to the force) is the
    solution of the full-row system of fixed states, for any mix of states, slip
    directions and (3D) cone curvature ``alpha``, with a previous displacement and
    initial gaps."""
    problem, rng = random_problem(12, dim, seed, gap=True)
    n, m = problem.n_pairs, dim - 1
    status = rng.choice([STUCK, SLIPPING, OPEN], n)
    status[:3] = [STUCK, SLIPPING, OPEN]
    direction = rng.normal(size=(n, m))
    direction /= np.linalg.norm(direction, axis=1, keepdims=True)
    alpha = rng.uniform(0, 1, n) if dim == 3 else np.zeros(n)
    d_prev = rng.normal(size=(n, dim))
    lam_w = rng.normal(size=problem.size)
    c = problem.kappa
    R, b, unknown, known = basket_system(problem, lam_w, status, direction, alpha, d_prev, c)
    expected = solve_partitioned(R, b, unknown, known)
    got = BlockSystem(problem, lam_w, status, d_prev).solve(direction, alpha, c)
    np.testing.assert_allclose(got, expected, rtol=0, atol=1e-12 * np.abs(expected).max())
    np.testing.assert_array_equal(got[np.setdiff1d(np.arange(problem.size), unknown)],
                                  known[np.setdiff1d(np.arange(problem.size), unknown)])


def test_block_system_all_stuck_and_all_open():
    """No unknowns: the known displacement itself; every pair open: ``K d = -lam_w``."""
    problem, rng = random_problem(5, 3, 1)
    d_prev, lam_w = rng.normal(size=(5, 3)), rng.normal(size=15)
    zeros = np.zeros((5, 2))
    stuck = BlockSystem(problem, lam_w, np.full(5, STUCK), d_prev).solve(zeros, np.zeros(5), 1.0)
    np.testing.assert_array_equal(stuck.reshape(5, 3)[:, :2], d_prev[:, :2])
    np.testing.assert_array_equal(stuck.reshape(5, 3)[:, 2], 0.0)
    opened = BlockSystem(problem, lam_w, np.full(5, OPEN), d_prev).solve(zeros, np.zeros(5), 1.0)
    np.testing.assert_allclose(problem.K @ opened, -lam_w, atol=1e-12)


@pytest.mark.parametrize("n", [8, 400, 1100])
def test_symmetric_products_equal_the_plain_ones(n):
    """``product`` (one triangle of K) and ``abs_product`` against ``K @ x`` and
    ``|K| @ |x|`` in double: round-off only (single precision from 1000 unknowns)."""
    rng = np.random.default_rng(n)
    A = rng.normal(size=(n, n))
    problem = ContactProblem(A @ A.T / n + np.eye(n), 0.3)
    x = rng.normal(size=problem.size)
    exact = problem.K @ x
    bound = problem.size * 2.0 ** -52 * (np.abs(problem.K) @ np.abs(x))   # summation order
    assert np.all(np.abs(problem.product(x) - exact) <= bound)
    size = np.abs(problem.K) @ np.abs(x)
    rtol = problem.size * 2.0 ** -24 if problem.size >= 1000 else problem.size * 2.0 ** -52
    np.testing.assert_allclose(problem.abs_product(x), size, rtol=rtol)
    np.testing.assert_allclose(problem.abs_product(x, symmetric=True), size, rtol=rtol)


def test_measures_with_known_products_equal_the_measures():
    """A method that hands its ``(K d, |K| |d|)`` to ``measures`` gets the same three
    numbers as a fresh evaluation (what the basket does at the end of a pass)."""
    problem, rng = random_problem(20, 3, 4)
    lam_w = rng.normal(size=(20, 3))
    previous = ContactState(rng.normal(size=(20, 3)) * 1e-3, np.zeros((20, 3)), np.zeros(20, int))
    r = solve(problem, lam_w, previous)
    assert r.success
    fresh = measures(problem, lam_w, r.d, r.lam, previous)
    known = measures(problem, lam_w, r.d, r.lam, previous, products(problem, r.d))
    assert fresh == known
    assert fresh[0] == residual_components(problem, lam_w, r.d, r.lam, previous).total
    assert r.residual == fresh[0]            # the basket's own products are the same
