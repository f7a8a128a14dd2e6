"""The per-pair law: disk projection, natural map, classification, local solutions."""
import numpy as np
import pytest

from qsma.contact import OPEN, SLIPPING, STUCK, ContactProblem
from qsma.contact.law import (PairQuantities, classify, local_states, natural_map,
                              project_disk)


def test_projection_on_the_disk_is_joint_not_per_component():
    x = np.array([[3.0, 4.0], [0.3, 0.4], [0.0, 0.0], [-6.0, 8.0]])
    radius = np.array([1.0, 1.0, 1.0, 0.0])
    out = project_disk(x, radius)
    np.testing.assert_allclose(out[0], [0.6, 0.8])               # scaled, not clamped to (1, 1)
    np.testing.assert_allclose(out[1], [0.3, 0.4])               # inside: unchanged
    np.testing.assert_allclose(out[2], [0.0, 0.0])
    np.testing.assert_allclose(out[3], [0.0, 0.0])               # zero radius
    np.testing.assert_allclose(np.linalg.norm(out, axis=1), [1.0, 0.5, 0.0, 0.0])


def test_projection_in_2d_is_a_clip():
    out = project_disk(np.array([[2.0], [-3.0], [0.5]]), np.array([1.0, 1.0, 1.0]))
    np.testing.assert_allclose(out.ravel(), [1.0, -1.0, 0.5])


def quantities(P, Q, w, dv):
    return PairQuantities(np.array(P, float), np.array(Q, float)[:, None],
                          np.array(w, float), np.array(dv, float)[:, None])


def test_natural_map_vanishes_exactly_on_the_three_rows_of_the_law():
    mu, c = np.full(3, 0.5), 10.0
    q = quantities(P=[2.0, 2.0, 0.0], Q=[0.7, -1.0, 0.0], w=[0.0, 0.0, 0.3], dv=[0.0, 0.2, -0.4])
    r_n, r_t = natural_map(q, mu, c)                 # stuck, slipping, open
    np.testing.assert_array_equal(r_n, 0.0)
    np.testing.assert_array_equal(r_t, 0.0)
    np.testing.assert_array_equal(classify(q, mu, c), [STUCK, SLIPPING, OPEN])


@pytest.mark.parametrize("P, Q, w, dv, r_n, r_t", [
    (2.0, 1.5, 0.0, 0.0, 0.0, 0.5),          # |Q| above mu P = 1 while stuck
    (2.0, 1.0, 0.0, 0.3, 0.0, 2.0),          # slipping along the friction force
    (-1.0, 0.0, 0.0, 0.0, 1.0, 0.0),         # tension
    (1.0, 0.0, 0.05, 0.0, 0.5, 0.0),         # pressure on an open gap: min(P, c w)
    (0.0, 0.0, -0.2, 0.0, 2.0, 0.0),         # penetration
])
def test_natural_map_measures_each_violation(P, Q, w, dv, r_n, r_t):
    r = natural_map(quantities([P], [Q], [w], [dv]), np.array([0.5]), 10.0)
    assert r[0][0] == pytest.approx(r_n) and r[1][0] == pytest.approx(r_t)


def test_classify_reports_round_off_slip_at_the_friction_limit_as_stuck():
    q = quantities(P=[2.0], Q=[-1.0], w=[0.0], dv=[1e-15])
    assert classify(q, np.array([0.5]), 10.0, threshold=1e-12).tolist() == [STUCK]
    assert classify(q, np.array([0.5]), 10.0).tolist() == [SLIPPING]


def test_local_states_of_a_single_pair_are_its_exact_candidates():
    problem = ContactProblem(np.array([[10.0, 4.0], [4.0, 100.0]]), 0.5)
    d, zero = np.zeros((1, 2)), np.zeros((1, 2))
    pairs = np.array([0])
    for lam_w, valid in [([[3.0, 10.0]], [True, False, False]),     # stuck
                         ([[-9.0, 10.0]], [False, True, False]),    # slipping
                         ([[1.0, -10.0]], [False, False, True])]:   # open
        lam = np.array(lam_w)                                       # at d = 0: lam = lam_w
        local = local_states(problem, d, lam, zero, 0.0, pairs)
        assert local.valid.tolist() == [valid]
    assert local_states(problem, d, np.array([[-9.0, 10.0]]), zero, 0.0,
                        pairs).direction.tolist() == [[1.0]]        # slips against Q
