"""Physically impossible numbers are never reported as success (what the physics
guarantees is checked per level; docs/theory.md section 7, docs/errors.md)."""
import dataclasses

import numpy as np
import pytest

import qsma
from qsma.analysis.result import FAILURE_FLAGS
from qsma.examples import sandwich_2d
from qsma.analysis.levels import Levels
from qsma.model import Material, Pressure


def test_tiny_levels_are_exactly_linear():
    """Levels of 1 nm .. 100 nm with every closed pair stuck: the modal response comes
    from the increments, so f = f0 and zeta = 0 (the difference of two totals gave
    f = 496 Hz and zeta = 0.151 at 1e-16 m before)."""
    r = qsma.run(sandwich_2d(1), levels=Levels.log("tip", 1e-9, 1e-7, 3))
    assert r.success, r.message
    assert np.allclose(r.f_hz, r.f0_hz, rtol=1e-6) and np.all(np.abs(r.zeta) < 1e-8)


def test_unresolvable_modal_response_is_a_failure_with_a_reason():
    m = sandwich_2d(1)
    m = dataclasses.replace(m, bodies=tuple(
        dataclasses.replace(b, pressures=(Pressure("bolt", 1e30),)) for b in m.bodies))
    r = qsma.run(m, levels=Levels.log("tip", 1e-6, 1e-3, 4))
    assert not r.success
    assert "numerical resolution" in r.message
    assert r.failed_levels


def test_levels_far_below_the_preload_are_still_linear():
    """Tip 1e-16 .. 1e-14 m (a failure with "numerical resolution" before issue 12):
    the ramp's 'preload' column of W is now the one the preload was solved with
    (ReducedModel.add_pattern keeps it), so the increments from the preload are exact
    and the stuck levels give f0 (measured -3.4e-10) and zeta ~ 0 (6e-16)."""
    r = qsma.run(sandwich_2d(1), levels=Levels.log("tip", 1e-16, 1e-14, 3))
    assert r.success, r.message
    np.testing.assert_allclose(r.f_hz, r.f0_hz, rtol=1e-6)
    assert np.all(np.abs(r.zeta) < 1e-8)


def test_soft_body_gives_no_success_with_impossible_values():
    """A top beam with E = 1 MPa on steel (issue 18 measured zeta = -0.059 and a tip
    falling as the load doubles, exit 0): every level either holds a physically
    possible answer or is a failure; no negative damping is reported as an answer."""
    m = sandwich_2d(1)
    soft = dataclasses.replace(m.bodies[1], material=Material(1e6, 0.285, 6600.0))
    r = qsma.run(dataclasses.replace(m, bodies=(m.bodies[0], soft)),
                 levels=Levels.log("tip", 1e-6, 1e-3, 6))
    ok = [k for k in range(r.n_levels) if k not in r.failed_levels]
    assert np.all(r.zeta[ok] >= -1e-8)
    if r.success:
        assert not r.failed_levels
    for k in r.failed_levels:
        assert set(r.flags[k]) & set(FAILURE_FLAGS)
