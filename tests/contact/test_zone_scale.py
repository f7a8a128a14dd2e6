"""A contact zone whose stiffness scale is decades below the full problem's: its answer
is judged, and if need be solved again, in the full problem's scale."""
from __future__ import annotations

from pathlib import Path

import numpy as np

from qsma.contact import ContactProblem, ContactState, force_residual
from qsma.contact.residual import FORCE_TOL
from qsma.contact.state import OPEN
from qsma.contact.zone import ContactZone, solve_in_zone

DATA = Path(__file__).resolve().parents[1] / "data" / "contact" / "contact18_level26.npz"


def test_a_zone_far_softer_than_the_full_problem_is_solved_to_the_full_check():
    """CalculiX's contact18 deck at a loop level where the upper cube stands on one
    corner (tests/data/contact/README.md): with its three open pairs eliminated the
    zone's stiffness scale kappa is 3e-7 of the full problem's, so the guess (a stuck
    pair slipping by 3.4e-7 mm) met the zone's check at tol and at RETRY_TOL * tol but
    failed the full problem's force check (1.3e-6 > FORCE_TOL). Solved again to the
    tolerance in the full problem's scale, the pair sticks exactly and the answer
    passes."""
    z = np.load(DATA)
    problem = ContactProblem(z["K"], z["mu"], z["gap0"], dim=3)
    before = ContactState(z["prev_d"], z["prev_lam"], z["prev_status"])
    guess = ContactState(z["d"], z["lam"], z["prev_status"])
    zone = ContactZone.build(problem, z["prev_status"] != OPEN)
    assert zone.sub.kappa / problem.kappa < 1e-6
    assert force_residual(problem, z["lam_w"], guess.d, guess.lam, before) > FORCE_TOL
    res, _ = solve_in_zone(zone, z["lam_w"], before, method="basket", guess=guess)
    assert res.success
    assert force_residual(problem, z["lam_w"], res.d, res.lam, before) <= FORCE_TOL
    np.testing.assert_array_equal(res.d[1, :2], before.d[1, :2])      # stuck: no slip
