"""Reduced integration of the quadratic quadrilateral and hexahedron (CPE8R, CPS8R,
C3D20R): the stiffness on 2x2 (2x2x2) Gauss points, the consistent mass; a zero-energy
(hourglass) mode, which spreads through meshes one element thick, is refused."""
from __future__ import annotations

import dataclasses
import re
import subprocess

import numpy as np
import pytest
import scipy.sparse.linalg as sla

import qsma
from qsma.errors import InputError
from qsma.examples import sandwich_2d
from qsma.fe import assemble_body
from qsma.fe.formulation import resolve_formulation
from qsma.analysis.levels import Levels
from qsma.mesh.generate import structured_mesh
from qsma.model import Body, Clamp, Interface, Material, Model, Probe

from helpers import needs_ccx

E_MPA, NU, RHO = 210e3, 0.3, 7.85e-9          # steel in mm-N-s-tonne
L, H = 10.0, 1.0


def _beam_mesh(n, element, y0=0.0):
    m = structured_mesh(np.linspace(0, L, n[0] + 1), np.linspace(y0, y0 + H, n[1] + 1),
                        np.linspace(0, H, n[2] + 1), cell_type="hexahedron20")
    x = m.points
    m = m.with_sets(node_sets={"root": np.flatnonzero(np.isclose(x[:, 0], 0.0)),
                               "tip": np.flatnonzero(np.isclose(x[:, 0], L))},
                    facet_sets={"low": m.boundary_facets_where(
                                    lambda p: np.isclose(p[:, 1], y0)),
                                "high": m.boundary_facets_where(
                                    lambda p: np.isclose(p[:, 1], y0 + H))})
    return dataclasses.replace(m, element=element)


def _cantilever_hz(n, element, k=6):
    body = Body("beam", _beam_mesh(n, element), Material(E_MPA, NU, RHO),
                clamps=(Clamp("root"),))
    a = assemble_body(body)
    K, M = a.K[a.free][:, a.free], a.M[a.free][:, a.free]
    w = sla.eigsh(K, k, M, sigma=0, which="LM", return_eigenvectors=False)
    return np.sqrt(np.sort(w)) / (2 * np.pi)


def test_c3d20r_is_resolved_and_named():
    form = resolve_formulation(_beam_mesh((1, 1, 1), "C3D20R"))
    assert form.reduced and form.name == "C3D20R"
    assert "reduced integration" in form.label and "2x2x2 Gauss" in form.label
    with pytest.raises(InputError, match="8-node quadrilaterals and 20-node hexahedra"):
        resolve_formulation(dataclasses.replace(
            structured_mesh(np.linspace(0, 1, 3), np.linspace(0, 1, 3)), element="CPE4R"))


def test_c3d20r_cantilever_is_softer_than_c3d20_and_near_euler_bernoulli():
    """A 10 x 1 x 1 steel cantilever on 10 x 2 x 2 cells: the first bending frequency of
    C3D20R lies below C3D20's (the reduced rule softens) and both within 1 % of
    Euler-Bernoulli's 1.875^2 / (2 pi) sqrt(E I / (rho A L^4)) (shear and the 3D clamp
    lower a beam of slenderness 10 by about 0.5 %)."""
    full = _cantilever_hz((10, 2, 2), "C3D20")
    red = _cantilever_hz((10, 2, 2), "C3D20R")
    eb = 1.8751 ** 2 / (2 * np.pi) * np.sqrt(E_MPA * H ** 4 / 12 / (RHO * H * H * L ** 4))
    assert red[0] < full[0]
    assert red[0] == pytest.approx(eb, rel=1e-2) and full[0] == pytest.approx(eb, rel=1e-2)


@needs_ccx
@pytest.mark.parametrize("element", ["C3D20", "C3D20R"])
def test_cantilever_frequencies_equal_calculix(element, tmp_path):
    """The same mesh and element in CalculiX 2.20: the six lowest frequencies agree to
    1e-4 (measured 3e-7 for C3D20 and 3e-5 for C3D20R, whose mass CalculiX integrates
    otherwise; CalculiX prints 7 digits)."""
    mesh = _beam_mesh((10, 2, 2), element)
    lines = ["*NODE"] + [f"{i + 1}, {x:.12g}, {y:.12g}, {z:.12g}"
                         for i, (x, y, z) in enumerate(mesh.points)]
    lines.append(f"*ELEMENT, TYPE={element}, ELSET=E")
    for i, c in enumerate(mesh.cells):
        v = [str(i + 1)] + [str(x + 1) for x in c]
        lines += [", ".join(v[:16]) + ",", ", ".join(v[16:])]
    lines += ["*NSET, NSET=ROOT"] + [str(v + 1) for v in mesh.node_sets["root"]]
    lines += ["*BOUNDARY", "ROOT, 1, 3", "*MATERIAL, NAME=S", "*ELASTIC",
              f"{E_MPA}, {NU}", "*DENSITY", f"{RHO}", "*SOLID SECTION, ELSET=E, MATERIAL=S",
              "*STEP", "*FREQUENCY", "6", "*END STEP"]
    (tmp_path / "beam.inp").write_text("\n".join(lines) + "\n")
    subprocess.run(["ccx", "-i", "beam"], cwd=tmp_path, capture_output=True, check=True)
    block = (tmp_path / "beam.dat").read_text().split("E I G E N V A L U E   O U T P U T")[1]
    rows = [r.split() for r in block.splitlines()
            if re.match(r"^\s+\d+\s+[-\d.E+]+\s+", r)]
    ccx = np.array([float(r[3]) for r in rows[:6]])
    assert np.allclose(_cantilever_hz((10, 2, 2), element), ccx, rtol=1e-4)


def test_cpe8r_sandwich_is_close_to_cpe8():
    """sandwich-2d with CPE8R: f0 within 0.05 % of CPE8's below it (measured 0.02 %) and
    the same damping at the same modal forces within 1 %."""
    levels = Levels("alpha", (200.0, 2000.0))
    full = qsma.run(sandwich_2d(1, element="CPE8"), levels=levels)
    red = qsma.run(sandwich_2d(1, element="CPE8R"), levels=levels)
    assert red.success and red.f0_hz < full.f0_hz
    assert red.f0_hz == pytest.approx(full.f0_hz, rel=5e-4)
    assert np.allclose(red.zeta, full.zeta, rtol=1e-2)


def test_one_element_thick_c3d20r_is_refused_by_its_hourglass_mode():
    """A C3D20R cantilever one cell thick in both directions of its section, joined at
    its free end to a clamped block: the reduced rule leaves zero-energy modes that
    spread along the beam (0.02 Hz on the beam alone; two cells across the section
    suppress them), so the tied stiffness is singular: refused naming the body, its
    element and the fix, never reported as a frequency near 0. Modes that the
    factorisation passes are checked too (their strain energy on the full rule against
    the reduced one, :func:`qsma.modal.linear.check_hourglass`)."""
    steel = Material(E_MPA, NU, RHO)
    beam = _beam_mesh((10, 1, 1), "C3D20R")
    end = beam.boundary_facets_where(lambda p: np.isclose(p[:, 1], H) & (p[:, 0] >= 9.0))
    beam = beam.with_sets(facet_sets={"end": end})
    block = structured_mesh(np.linspace(9.0, L, 2), np.linspace(H, 2 * H, 2),
                            np.linspace(0, H, 2), cell_type="hexahedron20")
    block = block.with_sets(
        facet_sets={"low": block.boundary_facets_where(lambda p: np.isclose(p[:, 1], H)),
                    "top": block.boundary_facets_where(lambda p: np.isclose(p[:, 1], 2 * H))})
    bodies = (Body("beam", beam, steel, clamps=(Clamp("root"),)),
              Body("block", block, steel, clamps=(Clamp("top"),)))
    model = Model(bodies, Interface("beam", "end", "block", "low"),
                  tip=Probe((("beam", "tip"),), (0.0, 1.0, 0.0)), units="mm-N-s-tonne")
    from qsma.modal import linear_modes
    from qsma.model.pairing import make_pairing
    assembled = [assemble_body(b) for b in model.bodies]
    with pytest.raises(InputError, match=r"zero-energy \(hourglass\) mode.*'beam' "
                                         r"\(C3D20R\).*fully integrated"):
        linear_modes(model, assembled, make_pairing(model), n_modes=2)
    full = [assemble_body(dataclasses.replace(
        b, mesh=dataclasses.replace(b.mesh, element="C3D20"))) for b in model.bodies]
    assert linear_modes(model, full, make_pairing(model), n_modes=2).f_hz[0] > 1e3
