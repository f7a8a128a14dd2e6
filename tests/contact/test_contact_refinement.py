"""The block step solved with an earlier step's LU factors (issue 14): iterative
refinement must give the answer of the step's own linear system to round-off, and
hand over to a new factorisation when it cannot."""
from types import SimpleNamespace

import numpy as np
import pytest

from qsma.contact import OPEN, SLIPPING, STUCK, ContactProblem, ContactState, solve
from qsma.contact import linear
from qsma.contact.linear import BlockSystem, basket_system

EPS = np.finfo(float).eps


def random_problem(n_pairs, dim, seed):
    rng = np.random.default_rng(seed)
    n = n_pairs * dim
    A = rng.normal(size=(n, n))
    K = A @ A.T / n + np.eye(n)
    return ContactProblem(K, rng.uniform(0.1, 0.8, n_pairs), dim=dim), rng


def unit(v):
    return v / np.linalg.norm(v, axis=1, keepdims=True)


def step_inputs(dim, seed, n_pairs=60):
    """A block step with every kind of pair (most slipping), its directions and
    ``alpha``, a previous displacement and a load."""
    problem, rng = random_problem(n_pairs, dim, seed)
    status = rng.choice([STUCK, SLIPPING, SLIPPING, SLIPPING, OPEN], n_pairs)
    direction = unit(rng.normal(size=(n_pairs, dim - 1)))
    alpha = rng.uniform(0, 1, n_pairs) if dim == 3 else np.zeros(n_pairs)
    return (problem, rng, status, direction, alpha, rng.normal(size=(n_pairs, dim)),
            rng.normal(size=problem.size))


def turned(direction, rng, angle):
    """Every direction (3D) turned by up to ``angle``."""
    phi = rng.uniform(-angle, angle, len(direction))
    c, s = np.cos(phi), np.sin(phi)
    return np.stack([c * direction[:, 0] - s * direction[:, 1],
                     s * direction[:, 0] + c * direction[:, 1]], axis=1)


def backward_error(problem, lam_w, status, direction, alpha, d_prev, c, d):
    """Backward error of ``d[U]`` in the step's own system, formed explicitly:
    ``max |b - A x| / (|A|_terms |x| + |b|)``, ``|A|_terms`` the absolute values of the
    terms that make each entry (``|K_t| + |mu s| |K_n| + |Pi| (|K_t| + c I)`` on a slip
    row, ``|K|`` on an open row): the round-off with which ``A`` itself is formed."""
    R, b, unknown, known = basket_system(problem, lam_w, status, direction, alpha, d_prev, c)
    A = R[:, unknown]
    rhs = b - R @ np.where(np.isin(np.arange(problem.size), unknown), 0.0, known)
    x = d[unknown]
    scale = _term_sizes(problem, status, direction, alpha, c, unknown) @ np.abs(x)
    return float(np.max(np.abs(rhs - A @ x) / (scale + np.abs(rhs))))


def _term_sizes(problem, status, direction, alpha, c, unknown):
    """``|A|_terms`` of :func:`backward_error`, row by row from K."""
    K, dim = np.abs(problem.K[:, unknown]), problem.dim
    rows = [K[i * dim + j] for i in np.flatnonzero(status == OPEN) for j in range(dim)]
    for i in np.flatnonzero(status == SLIPPING):
        s, m = direction[i], dim - 1
        Pi = alpha[i] * (np.eye(m) - np.outer(s, s))
        K_t, K_n = K[i * dim:i * dim + m], K[i * dim + m]
        own = np.zeros((m, len(unknown)))
        own[:, [np.flatnonzero(unknown == i * dim + j)[0] for j in range(m)]] = c * np.eye(m)
        for j in range(m):
            rows.append(K_t[j] + abs(problem.mu[i] * s[j]) * K_n
                        + np.abs(Pi[j]) @ (K_t + own))
    return np.array(rows)


@pytest.fixture
def refine_all(monkeypatch):
    """Refinement for every block step, whatever its size."""
    monkeypatch.setattr(linear, "REFINE_MIN", 0)


@pytest.mark.parametrize("seed", range(4))
def test_refined_step_solves_its_own_system_to_round_off(refine_all, seed, dim=3):
    """The second step (directions turned by up to 0.01 rad, ``alpha`` changed) is
    solved with the first step's factors in several corrections; its answer has the
    backward error of a direct solve in its own system and equals the direct solve to
    the conditioning's round-off."""
    problem, rng, status, direction, alpha, d_prev, lam_w = step_inputs(dim, seed)
    c = problem.kappa
    system = BlockSystem(problem, lam_w, status, d_prev)
    system.solve(direction, alpha, c)
    assert (system.n_factorised, system.n_refined) == (1, 0)
    direction2 = turned(direction, rng, 0.01)
    alpha2 = np.clip(alpha + rng.uniform(-0.01, 0.01, len(alpha)), 0, 1) if dim == 3 else alpha
    d = system.solve(direction2, alpha2, c)
    assert (system.n_factorised, system.n_refined) == (1, 1)
    assert system.n_corrections >= 1            # a case that needs the refinement
    assert backward_error(problem, lam_w, status, direction2, alpha2, d_prev, c, d) <= 16 * EPS
    fresh = BlockSystem(problem, lam_w, status, d_prev)
    direct = fresh.solve(direction2, alpha2, c)
    assert fresh.n_factorised == 1
    assert backward_error(problem, lam_w, status, direction2, alpha2, d_prev, c,
                          direct) <= 16 * EPS
    np.testing.assert_allclose(d, direct, rtol=0, atol=1e-12 * np.abs(direct).max())


def test_refinement_stopped_early_is_caught(refine_all, monkeypatch, dim=3):
    """The test above has teeth: with an acceptance test that passes anything (the
    refinement stopping at its first iterate), the answer is that of the first step's
    matrix and its backward error in the second step's system is far above
    round-off."""
    monkeypatch.setattr(linear, "REFINE_ETA", 1.0)
    problem, rng, status, direction, alpha, d_prev, lam_w = step_inputs(dim, 0)
    c = problem.kappa
    system = BlockSystem(problem, lam_w, status, d_prev)
    system.solve(direction, alpha, c)
    direction2 = turned(direction, rng, 0.01)
    d = system.solve(direction2, alpha, c)
    assert system.n_refined == 1 and system.n_corrections == 0
    assert backward_error(problem, lam_w, status, direction2, alpha, d_prev, c, d) > 1e-8


@pytest.mark.parametrize("dim", [2, 3])
def test_far_directions_get_a_new_factorisation(refine_all, dim):
    """Directions unrelated to the factorised ones: the refinement gives up (it
    contracts too slowly or not at all) and the step is factorised again, exactly."""
    problem, rng, status, direction, alpha, d_prev, lam_w = step_inputs(dim, 3)
    c = problem.kappa
    system = BlockSystem(problem, lam_w, status, d_prev)
    system.solve(direction, alpha, c)
    far = -direction if dim == 2 else unit(rng.normal(size=direction.shape))
    d = system.solve(far, alpha, c)
    assert system.n_factorised == 2 and system.n_refined == 0
    assert system.n_corrections <= linear.REFINE_STEPS
    assert backward_error(problem, lam_w, status, far, alpha, d_prev, c, d) <= 16 * EPS


def test_small_steps_are_factorised(monkeypatch):
    """Below REFINE_MIN unknowns every step is a factorisation (cheaper there)."""
    problem, rng, status, direction, alpha, d_prev, lam_w = step_inputs(3, 1, n_pairs=20)
    system = BlockSystem(problem, lam_w, status, d_prev)
    assert system.unknown.size < linear.REFINE_MIN
    for angle in (0.0, 0.01):
        system.solve(turned(direction, rng, angle), alpha, problem.kappa)
    assert (system.n_factorised, system.n_refined) == (2, 0)


def test_singular_block_raises(refine_all):
    """An exactly singular block step raises ``LinAlgError`` as the direct solve did
    (the basket turns it into a failed solve)."""
    valid = ContactProblem(np.eye(6), 0.5, dim=3)
    K = np.eye(6)
    K[3:, 3:] = 0.0                                  # pair 1 has no stiffness
    problem = SimpleNamespace(K=K, **{name: getattr(valid, name) for name in (
        "dim", "n_pairs", "mu", "gap0", "tangent_index", "normal_index")})
    system = BlockSystem(problem, np.zeros(6), np.array([STUCK, OPEN]), np.zeros((2, 3)))
    with pytest.raises(np.linalg.LinAlgError):
        system.solve(np.zeros((2, 2)), np.zeros(2), 1.0)


@pytest.mark.parametrize("seed", range(3))
def test_solves_with_and_without_refinement_agree(monkeypatch, seed):
    """A warm-started 3D load sequence solved with refinement on every step and with a
    factorisation on every step: same states, answers equal to round-off, every level
    accepted by the unchanged residual."""
    problem, rng = random_problem(80, 3, seed)
    pattern = rng.normal(size=(80, 3))
    pattern[:, 2] = -np.abs(pattern[:, 2]) - 1.0            # pressed
    shear = np.zeros((80, 3))
    shear[:, :2] = rng.normal(size=(80, 2))
    loads = [pattern + t * shear for t in np.linspace(0.2, 1.2, 6)]

    def ramp(refine_min):
        monkeypatch.setattr(linear, "REFINE_MIN", refine_min)
        state, out = ContactState.reference(problem), []
        for lam_w in loads:
            res = solve(problem, lam_w, state)
            assert res.success, res.message
            out.append(res)
            state = res.state
        return out

    refined, direct = ramp(0), ramp(10 ** 9)
    assert any(r.n_slipping for r in direct)
    for a, b in zip(refined, direct):
        np.testing.assert_array_equal(a.status, b.status)
        np.testing.assert_allclose(a.d, b.d, rtol=0, atol=1e-11 * np.abs(b.d).max())
        np.testing.assert_allclose(a.lam, b.lam, rtol=0, atol=1e-11 * np.abs(b.lam).max())
