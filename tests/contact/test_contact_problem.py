"""ContactProblem validation and the input checks of solve()."""
import numpy as np
import pytest

from qsma.contact import (DEFAULT_TOL, METHODS, OPEN, SLIPPING, ContactProblem, ContactState,
                          residual, solve)
from qsma.contact.registry import AUTO_ACTIVE_SET_PAIRS, chosen_method
from qsma.errors import InputError


def spd(n, seed=0):
    rng = np.random.default_rng(seed)
    A = rng.standard_normal((n, n))
    return A @ A.T + n * np.eye(n)


def test_stores_symmetrised_readonly_arrays_and_per_pair_mu():
    K = spd(6)
    K[0, 1] += 1e-12 * np.abs(K).max()            # round-off asymmetry is accepted
    p = ContactProblem(K, 0.3, dim=2)
    assert p.n_pairs == 3 and p.size == 6
    np.testing.assert_array_equal(p.K, p.K.T)
    np.testing.assert_array_equal(p.mu, [0.3, 0.3, 0.3])
    np.testing.assert_array_equal(p.gap0, [0.0, 0.0, 0.0])
    assert p.kappa == pytest.approx(np.mean(np.diag(K)))
    np.testing.assert_array_equal(p.normal_index, [1, 3, 5])
    np.testing.assert_array_equal(p.tangent_index, [[0], [2], [4]])
    np.testing.assert_array_equal(p.diagonal_blocks[1], p.K[2:4, 2:4])
    with pytest.raises(ValueError):
        p.K[0, 0] = 1.0
    with pytest.raises(AttributeError):
        p.mu = np.zeros(3)
    assert "n_pairs=3" in repr(p) and "mu=0.3" in repr(p)


def test_frozen_symmetric_stiffness_is_held_without_a_copy():
    """A read-only, exactly symmetric K (an analysis's reduced model) is held as is; a
    writeable one, or a read-only one that is not exactly symmetric, is copied (and
    symmetrised), so the caller can never change a problem behind its back."""
    A = np.random.default_rng(3).normal(size=(6, 6))
    K = A @ A.T + 6 * np.eye(6)
    K = 0.5 * (K + K.T)
    K.flags.writeable = False
    assert np.shares_memory(ContactProblem(K, mu=0.3).K, K)
    writeable = K.copy()
    held = ContactProblem(writeable, mu=0.3).K
    assert not np.shares_memory(held, writeable)
    np.testing.assert_array_equal(held, K)
    base = K.copy()
    view = base.view()
    view.flags.writeable = False                 # read-only, but its base is not
    assert not np.shares_memory(ContactProblem(view, mu=0.3).K, base)
    skew = K.copy()
    skew[0, 1] += 1e-14 * np.abs(K).max()
    skew.flags.writeable = False
    held = ContactProblem(skew, mu=0.3).K
    assert not np.shares_memory(held, skew)
    np.testing.assert_array_equal(held, held.T)
    assert not held.flags.writeable


def test_3d_indices():
    p = ContactProblem(spd(6), [0.1, 0.2], gap0=[0.0, 1e-3], dim=3)
    np.testing.assert_array_equal(p.normal_index, [2, 5])
    np.testing.assert_array_equal(p.tangent_index, [[0, 1], [3, 4]])
    np.testing.assert_array_equal(p.mu, [0.1, 0.2])


@pytest.mark.parametrize("K, dim, match", [
    (np.ones((4, 3)), 2, r"square.*expected shape \(N, N\), got \(4, 3\)"),
    (np.eye(5), 2, "multiple of dim=2.*got 5"),
    (np.eye(4), 3, "multiple of dim=3.*got 4"),
    (np.zeros((0, 0)), 2, "positive multiple"),
    (np.diag([1.0, np.nan, 1.0, 1.0]), 2, "finite: found 1 NaN/Inf"),
    (np.diag([1.0, 1.0, -1.0, 1.0]), 2, "positive definite"),
])
def test_bad_stiffness_raises_with_expected_and_actual(K, dim, match):
    with pytest.raises(InputError, match=match):
        ContactProblem(K, 0.5, dim=dim)


def test_asymmetric_stiffness_names_the_entries():
    K = spd(4)
    K[0, 3] += 0.1 * np.abs(K).max()
    expected = r"symmetric: expected max\|K - K\^T\| <= .* got .*K\[0,3\]"
    with pytest.raises(InputError, match=expected):
        ContactProblem(K, 0.5)


@pytest.mark.parametrize("kwargs, match", [
    ({"mu": -0.1}, "mu must be >= 0: got -0.1 at pair 0"),
    ({"mu": [0.2, -0.5]}, "at pair 1"),
    ({"mu": [0.2, 0.2, 0.2]}, r"one value per pair: expected shape \(2,\), got \(3,\)"),
    ({"mu": np.nan}, "mu must be finite"),
    ({"mu": None}, "mu is required"),
    ({"mu": 0.3, "gap0": [0.0]}, r"gap0.*expected shape \(2,\), got \(1,\)"),
    ({"mu": 0.3, "gap0": [0.0, np.inf]}, "gap0 must be finite"),
    ({"mu": 0.3, "dim": 4}, "dim must be 2 or 3, got 4"),
])
def test_bad_friction_gap_or_dim_raises(kwargs, match):
    with pytest.raises(InputError, match=match):
        ContactProblem(spd(4), **kwargs)


def test_input_error_is_a_value_error():
    with pytest.raises(ValueError):
        ContactProblem(np.eye(3), 0.5)


@pytest.fixture
def problem():
    return ContactProblem(np.diag([10.0, 100.0, 10.0, 100.0]), 0.5)


def test_unknown_method_lists_valid_ones(problem):
    expected = (r"unknown contact method 'newton'; "
                r"valid: \['auto', 'active_set', 'basket', 'nodal_gs'\]")
    with pytest.raises(InputError, match=expected):
        solve(problem, np.ones((2, 2)), method="newton")


@pytest.mark.parametrize("dim, n_pairs, chosen", [
    (3, AUTO_ACTIVE_SET_PAIRS, "active_set"), (3, AUTO_ACTIVE_SET_PAIRS - 1, "basket"),
    (2, 2 * AUTO_ACTIVE_SET_PAIRS, "basket")])
def test_auto_method_follows_dimension_and_size(dim, n_pairs, chosen):
    """``method="auto"``: active_set on 3D problems from AUTO_ACTIVE_SET_PAIRS pairs,
    basket below and in 2D; the result names the method that ran, and its answer meets
    the acceptance test like any other (a compressed, sheared interface)."""
    problem = ContactProblem(spd(dim * n_pairs, seed=n_pairs), mu=0.3, dim=dim)
    lam_w = np.tile([0.5] * (dim - 1) + [1.0], (n_pairs, 1)) * dim * n_pairs
    res = solve(problem, lam_w, method="auto")
    assert chosen_method("auto", problem) == chosen
    assert res.method == chosen and res.success
    closed = res.status != OPEN
    assert closed.all() and (res.status == SLIPPING).any()  # pressed, and some slide
    assert residual(problem, lam_w, res.d, res.lam) <= DEFAULT_TOL
    for name in METHODS:                        # an explicit name is never replaced
        assert chosen_method(name, problem) == name


def test_auto_method_of_a_zone_is_that_of_the_whole_interface():
    """A zone solve with ``method="auto"`` uses the method of the full problem, not of
    the (smaller) zone: every zone of a run is solved by the same method."""
    from qsma.contact.zone import ContactZone, solve_in_zone
    n = AUTO_ACTIVE_SET_PAIRS + 20
    problem = ContactProblem(spd(3 * n, seed=3), mu=0.3, dim=3)
    keep = np.zeros(n, bool)
    keep[:10] = True
    lam_w = np.tile([0.1, 0.0, 1.0], (n, 1)) * 3 * n       # pressed (lam_n > 0)
    lam_w[~keep, 2] = -0.5 * 3 * n                         # pulled apart: stay open
    res, zone = solve_in_zone(ContactZone.build(problem, keep), lam_w,
                              ContactState.reference(problem), method="auto")
    assert res.method == "active_set" and res.success
    assert zone.keep.sum() < AUTO_ACTIVE_SET_PAIRS      # a zone basket would be chosen for
    assert np.all(res.status[~zone.keep] == OPEN)


def test_auto_method_refuses_the_options_of_one_method():
    """Method options belong to one method; with auto the method depends on the size,
    so they are refused with the fix named, whatever the size."""
    problem = ContactProblem(spd(6), mu=0.3, dim=3)
    with pytest.raises(InputError, match=r"name the method \(method='basket'"):
        solve(problem, np.ones((2, 3)), method="auto", coupling="gauss_seidel")


@pytest.mark.parametrize("method", sorted(METHODS))
def test_unknown_option_raises(problem, method):
    expected = r"unknown option\(s\) \['tolerance'\] .* valid: \['tol', 'maxiter'"
    with pytest.raises(InputError, match=expected):
        solve(problem, np.ones((2, 2)), method=method, tolerance=1e-3)


@pytest.mark.parametrize("method, options, match", [
    ("basket", {"coupling": "jacobi"}, "coupling must be one of"),
    ("active_set", {"augmentation": -1.0}, "augmentation must be a positive number"),
    ("nodal_gs", {"check_every": 0}, "check_every must be a positive integer"),
])
def test_bad_option_values_raise(problem, method, options, match):
    with pytest.raises(InputError, match=match):
        solve(problem, np.ones((2, 2)), method=method, **options)


@pytest.mark.parametrize("bad", [np.nan, np.inf, -np.inf])
def test_non_finite_load_raises(problem, bad):
    lam_w = np.ones((2, 2))
    lam_w[1, 0] = bad
    with pytest.raises(InputError, match="lam_w must be finite: found 1"):
        solve(problem, lam_w)


def test_load_of_wrong_shape_raises(problem):
    expected = r"lam_w must have shape \(2, 2\) \(n_pairs, dim\), got \(4,\)"
    with pytest.raises(InputError, match=expected):
        solve(problem, np.ones(4))


@pytest.mark.parametrize("kwargs, match", [
    ({"tol": 0.0}, "tol must be a positive finite number"),
    ({"tol": np.nan}, "tol must be a positive finite number"),
    ({"maxiter": 0}, "maxiter must be a positive integer"),
    ({"maxiter": 2.5}, "maxiter must be a positive integer"),
])
def test_bad_tol_or_maxiter_raises(problem, kwargs, match):
    with pytest.raises(InputError, match=match):
        solve(problem, np.ones((2, 2)), **kwargs)


def test_state_of_another_problem_raises(problem):
    other = ContactState.reference(ContactProblem(np.eye(6), 0.5))
    with pytest.raises(InputError, match=r"state.d must have shape \(2, 2\)"):
        solve(problem, np.ones((2, 2)), other)


def test_options_are_keyword_only(problem):
    with pytest.raises(TypeError):
        solve(problem, np.ones((2, 2)), None, "basket")


@pytest.mark.parametrize("scale_K, scale_d", [(1.0, 1.0), (1e200, 1e-200), (1e-200, 1e150)])
def test_abs_product_in_single_precision_is_a_faithful_size(scale_K, scale_d):
    """From SINGLE_PRECISION_FROM unknowns |K| |x| is formed in float32 on scaled
    operands: within N 2^-24 of the double product (all terms positive), and no
    overflow or underflow at extreme units."""
    from qsma.contact.problem import SINGLE_PRECISION_FROM
    n = SINGLE_PRECISION_FROM + 2
    rng = np.random.default_rng(7)
    A = rng.normal(size=(n, n)) / np.sqrt(n)
    p = ContactProblem(scale_K * (A @ A.T + np.eye(n)), 0.5)
    x = scale_d * rng.normal(size=n)
    exact = np.abs(p.K) @ np.abs(x)
    got = p.abs_product(x)
    assert np.all(np.isfinite(got)) and np.all(got > 0)
    assert np.max(np.abs(got / exact - 1)) < n * 2.0 ** -24
    assert np.max(np.abs(got / exact - 1)) < 1e-5                 # measured 6e-7
    assert np.array_equal(p.abs_product(np.zeros(n)), np.zeros(n))
    assert np.isnan(p.abs_product(np.full(n, np.nan))).all()
    small = ContactProblem(A[:8, :8] @ A[:8, :8].T + np.eye(8), 0.5)    # double below
    np.testing.assert_allclose(small.abs_product(x[:8]), np.abs(small.K) @ np.abs(x[:8]),
                               rtol=8 * 2.0 ** -52)          # summation order only


def test_a_pickled_problem_leaves_its_caches_behind():
    """A problem sent to another process (the loops on a Dask scheduler) carries its
    fields, not what was cached on it: |K|, the single-precision copy, the last zone
    elimination, each as large as K. The unpickled problem rebuilds |K| alike."""
    import pickle
    from qsma.contact.zone import ContactZone
    rng = np.random.default_rng(3)
    A = rng.standard_normal((60, 60))
    problem = ContactProblem(A @ A.T + 60 * np.eye(60), 0.3, dim=3)
    expected = problem.abs_K.copy()
    ContactZone.build(problem, np.arange(20) < 12)
    assert {"_abs_K", "_zone_outer"} <= set(problem.__dict__)
    back = pickle.loads(pickle.dumps(problem))
    assert not [k for k in back.__dict__ if k.startswith("_")]
    assert len(pickle.dumps(problem)) < 1.5 * problem.K.nbytes
    assert np.array_equal(back.K, problem.K) and np.array_equal(back.mu, problem.mu)
    assert back.kappa == problem.kappa and np.array_equal(back.abs_K, expected)
