"""Displacements prescribed by clamps (a support moved into place, a displacement-driven
preload, an Abaqus *BOUNDARY row with a value): part of the preload, held from then on."""
from __future__ import annotations

import dataclasses

import numpy as np
import pytest

import qsma
from qsma.errors import InputError
from qsma.examples import sandwich_2d
from qsma.analysis.levels import Levels
from qsma.model import Clamp

LEVELS = Levels("alpha", (20.0, 200.0, 2000.0))


def _moved(model, shift):
    """``model`` with every clamp moved by ``shift`` (all components held)."""
    bodies = tuple(dataclasses.replace(b, clamps=tuple(
        Clamp(c.set, None, tuple(shift)) for c in b.clamps)) for b in model.bodies)
    return dataclasses.replace(model, bodies=bodies)


def test_clamps_moved_together_translate_the_joint_rigidly():
    """Every clamp of sandwich-2d moved by the same vector: the structure translates as
    a rigid body, so the preload's contact forces, f0, the backbone and the damping are
    those of the unmoved model (to round-off), and every node's preload displacement is
    the unmoved one plus the shift (the prescribed displacement enters the preload as
    the forces it exerts, -K u_p, and the recovered fields as itself)."""
    base = sandwich_2d(1)
    shift = (3e-5, -2e-5)
    a = qsma.run(base, levels=LEVELS)
    b = qsma.run(_moved(base, shift), levels=LEVELS)
    scale = np.abs(a.preload.lam).max()
    assert np.abs(b.preload.lam - a.preload.lam).max() <= 1e-8 * scale
    assert b.f0_hz == pytest.approx(a.f0_hz, rel=1e-12)
    assert np.allclose(b.q, a.q, rtol=1e-7)
    assert np.allclose(b.zeta, a.zeta, rtol=1e-6, atol=1e-12)
    for ua, ub, body in zip(a.fields(None), b.fields(None), base.bodies):
        moved = ub.reshape(-1, 2) - ua.reshape(-1, 2)
        assert np.allclose(moved, shift, rtol=0, atol=1e-9 * max(shift))


def test_a_support_pushed_into_the_joint_closes_it_harder():
    """The top beam's clamp pushed 10 um towards the bottom beam (the bolt pressure
    unchanged): the clamp nodes sit exactly there in the preload and the joint carries
    more normal force than under the bolt alone."""
    base = sandwich_2d(1)
    top = base.body("top")
    pushed = dataclasses.replace(top, clamps=(Clamp("clamp", None, (0.0, -1e-5)),))
    model = dataclasses.replace(base, bodies=(base.bodies[0], pushed))
    a = qsma.run(base, levels=LEVELS)
    b = qsma.run(model, levels=LEVELS)
    u = b.fields(None)[1].reshape(-1, 2)[top.mesh.nodes("clamp")]
    assert np.allclose(u, [0.0, -1e-5], rtol=0, atol=1e-15)
    assert b.preload.lam[:, -1].sum() > a.preload.lam[:, -1].sum()
    assert b.success


def test_prescribed_values_are_checked():
    body = sandwich_2d(1).bodies[0]
    with pytest.raises(InputError, match="holds 1 component.*prescribes 2"):
        dataclasses.replace(body, clamps=(Clamp("clamp", (1,), (0.0, 1e-5)),))
    with pytest.raises(InputError, match="held at 0 by one clamp and at 1e-05"):
        dataclasses.replace(body, clamps=(Clamp("clamp", (1,)),
                                          Clamp("clamp", (1,), (1e-5,))))
    with pytest.raises(InputError, match="must be finite"):
        Clamp("clamp", (1,), (float("nan"),))
