"""Element formulations: models anywhere in space, plane stress, quadratic cells,
incompatible modes, refusals of what is not implemented."""
import dataclasses

import numpy as np
import pytest
import scipy.sparse.linalg as spla

from qsma.errors import InputError
from qsma.examples import sandwich_2d, sandwich_3d
from qsma.fe import assemble_body
from qsma.modal import linear_modes
from qsma.model import Model, make_pairing


def translated(model: Model, offset) -> Model:
    """``model`` with every body moved by ``offset`` (m)."""
    bodies = [dataclasses.replace(b, mesh=dataclasses.replace(
        b.mesh, points=b.mesh.points + np.asarray(offset))) for b in model.bodies]
    return dataclasses.replace(model, bodies=tuple(bodies))


def _rel(a, b):
    d = a - b
    d = abs(d).max() if hasattr(d, "tocsr") else np.abs(d).max()
    s = abs(b).max() if hasattr(b, "tocsr") else np.abs(b).max()
    return d / s


@pytest.mark.parametrize("make, offset", [
    (sandwich_2d, (1000.0, -1000.0)),
    (sandwich_3d, (1000.0, 1000.0, -1000.0)),
])
def test_model_translated_by_one_km_gives_same_operators_and_frequency(make, offset):
    """Assembly on coordinates relative to each body's bounding-box centre: K, M, the
    preload and the tied f0 agree to 1e-8 (the translation itself rounds the
    coordinates at 1e3 * 2^-52 = 2e-13 m, 1e-10 of the smallest element)."""
    m0 = make(1)
    m1 = translated(m0, offset)
    A0 = [assemble_body(b) for b in m0.bodies]
    A1 = [assemble_body(b) for b in m1.bodies]
    for a0, a1 in zip(A0, A1):
        assert _rel(a1.K, a0.K) < 1e-8
        assert _rel(a1.M, a0.M) < 1e-8
        assert _rel(a1.loads["preload"], a0.loads["preload"]) < 1e-8
    f0 = linear_modes(m0, A0, make_pairing(m0), n_modes=1).f_hz[0]
    f1 = linear_modes(m1, A1, make_pairing(m1), n_modes=1).f_hz[0]
    assert abs(f1 - f0) < 1e-8 * f0
