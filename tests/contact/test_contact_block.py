"""The block step formed on the unknown columns only (qsma.contact.linear.block_step)
solves the system of fixed pair states exactly as the full rows do."""
import numpy as np
import pytest

from qsma.contact import ContactProblem
from qsma.contact.linear import basket_system, block_step, solve_partitioned
from qsma.contact.state import OPEN, SLIPPING, STUCK


@pytest.mark.parametrize("dim", [2, 3])
@pytest.mark.parametrize("with_alpha", [False, True])
def test_block_step_equals_the_full_rows(dim, with_alpha):
    rng = np.random.default_rng(dim + 10 * with_alpha)
    n = 25
    A = rng.normal(size=(dim * n, dim * n))
    p = ContactProblem(A @ A.T / n + np.diag(np.full(dim * n, 2.0)),
                       rng.uniform(0.1, 0.6, n), rng.uniform(-0.01, 0.01, n), dim)
    status = rng.choice([STUCK, SLIPPING, OPEN], size=n)
    s = rng.normal(size=(n, dim - 1))
    direction = s / np.linalg.norm(s, axis=1)[:, None]
    alpha = rng.uniform(0.2, 1.0, n) if with_alpha else np.zeros(n)
    lam_w = rng.normal(size=dim * n)
    d_prev = rng.normal(size=(n, dim))
    R, b, unknown, known = basket_system(p, lam_w, status, direction, alpha, d_prev, p.kappa)
    want = solve_partitioned(R, b, unknown, known)
    got = block_step(p, lam_w, status, direction, alpha, d_prev, p.kappa)
    np.testing.assert_allclose(got, want, rtol=0, atol=1e-12 * np.abs(want).max())
    # and it is a solution of the rows: R d = b
    np.testing.assert_allclose(R @ got, b, rtol=0, atol=1e-11 * np.abs(R).max()
                               * np.abs(got).max())


def test_block_step_with_every_pair_stuck_is_the_known_displacement():
    p = ContactProblem(np.eye(6) * 3.0, 0.3, [0.1, -0.2, 0.0], 2)
    d_prev = np.arange(6.0).reshape(3, 2)
    d = block_step(p, np.ones(6), np.full(3, STUCK), np.zeros((3, 1)), np.zeros(3), d_prev,
                   p.kappa)
    np.testing.assert_array_equal(d.reshape(3, 2), [[0.0, -0.1], [2.0, 0.2], [4.0, -0.0]])


@pytest.mark.parametrize("dim", [2, 3])
def test_block_step_without_slipping_pairs(dim):
    rng = np.random.default_rng(5)
    n = 8
    A = rng.normal(size=(dim * n, dim * n))
    p = ContactProblem(A @ A.T / n + np.eye(dim * n), 0.3, dim=dim)
    status = np.where(np.arange(n) < 3, OPEN, STUCK)
    args = (np.zeros((n, dim - 1)), np.zeros(n), rng.normal(size=(n, dim)))
    lam_w = rng.normal(size=dim * n)
    R, b, unknown, known = basket_system(p, lam_w, status, *args, p.kappa)
    np.testing.assert_allclose(block_step(p, lam_w, status, *args, p.kappa),
                               solve_partitioned(R, b, unknown, known), rtol=0, atol=1e-13)
