r"""The Brake-Reuss beam (BRB): two stainless steel beams joined by a three-bolt lap
joint, tested free-free (docs/validation.md, section "The Brake-Reuss beam").

Every number below carries its source; the numbers no public source gave us are
marked *assumption* with the reason.

Sources
-------
[G] N. N. Balaji, "An Abaqus-MATLAB tutorial for jointed systems", public repository
    ``Nidish96/Abaqus4Joints``: ``assets/parts/HALFBEAM.py`` (half-beam geometry,
    holes, washer partition), ``assets/parts/NUTWASHERBOLT_516.py`` (5/16 in bolt, nut
    and washer), ``docs/abqtut.org`` (the tutorial: 3 bolts, 12 kN each, free-free).
[P] J. H. Porter and M. R. W. Brake, "Towards a predictive, physics-based friction
    model for the dynamics of jointed structures", Mech. Syst. Signal Process. 192
    (2023) 110210; its code ``tmd-lab/microslip-rough-contact``
    (``EPMC_SIMS/main_epmc.m``: E = 192.31 GPa and nu = 0.3 of 304L, density
    7784.3 kg/m^3, the three bolt preloads 12002, 12075, 12670 N, whose origin
    the file does not state) and ``tmd-lab/tmdsimpy``
    (``examples/structures/brb_epmc.py``: the same preloads and E, simulated
    tied-state frequencies 168.5026, 580.4082, 1177.6498 Hz with a flat interface and
    180.6293, 595.2815, 1199.9013 Hz with the measured mesoscale gap, lines 590-594;
    the linear damping ratios 0.087 % and 0.034 % of the first two bending modes
    "taken from experiments on BRB", lines 604-615; the yield strength 331.7 MPa and
    tangent modulus 620 MPa of the asperities, lines 218-219; and the data file
    ``examples/structures/data/brb_surface_data.mat`` of the measured surfaces: the
    effective asperity radius ``Re`` = 1.3649 mm, the asperity pair density
    ``area_density`` = 1.3713e6 /m^2, the range ``z_max`` = 28.05 um of the pair gaps,
    their measured density, and the mesoscale gap ``mesoscale_xygap``).

Measured surfaces ([P]) (what qsma's default takes from them):

* the asperities: radius, density and yield of [P]; the gaps of the asperity pairs
  modelled as a Gaussian of standard deviation 3.17 um (the standard deviation of
  [P]'s measured pair-gap density, evaluated from the data file) truncated at the
  measured range z_max = 28.05 um (``n_sigma = z_max / (2 sigma)``). The measured
  density has a longer tail towards the first-touching pairs than the Gaussian; at
  the mean lap pressure (12.6 MPa) the two give the same closure within 0.05 um and
  stick stiffnesses within 15 %;
* the mesoscale gap of the lap (the surfaces' shape, 0 to 109 um), averaged across
  the width (it varies across it by a few um) at x = -60, -50, ..., 60 mm: 21, 43, 62,
  77, 89, 98, 103, 102, 95, 83, 65, 36, 6.5 um (evaluated from ``mesoscale_xygap``;
  *assumption*: [P]'s x axis runs as qsma's, from the left beam to the right one: the
  data file does not say which end is which);
* the linear damping of the structure, 0.087 % (the first bending mode).

With the measured surfaces the beam also carries its bolt sets (28 g each, half on
each washer annulus) and [P]'s 0.8 g accelerometer at the tip; the flat variant keeps
the massless bolts of the earlier model.

Geometry [G] (x along the beam, y the bolt axis through the thickness, z across
the width; origin at the centre of the joint on the interface):

* each half beam is 420 mm long (x from -360 to +60 mm for the left one), 25.4 mm
  thick and 25.4 mm wide, halved to 12.7 mm over the last 120 mm (the lap): the two
  halves overlap over x in [-60, 60] mm and the assembled beam is 720 mm long;
* three bolts on the beam's centre line at x = -30, 0, +30 mm (z = 12.7 mm);
* washers 5/16 in: bore 11/32 in, outside diameter 11/16 in, 1/16 in thick; the
  beam's bearing face under each washer is that annulus (the beam partition of
  radius 11/32 in in [G]);
* bolt 5/16 in shank (diameter 0.3125 in).

Modelling choices (each an approximation named in docs/validation.md):

* the 8.5 mm bolt holes [G] are not modelled: the structured hexahedral mesh
  keeps the interface node-matching, and the annular washer sets leave the hole
  area unloaded;
* a washer set is the outer-face facets whose centroid lies in the washer annulus
  (the bearing area of the mesh converges to the annulus with refinement);
* the bolt is the spring of :class:`qsma.model.Bolt`: pretension in the preload,
  then locked with ``k = E_b A / L``, ``A`` the 5/16 in shank area and ``L`` the grip
  (two 12.7 mm halves and two 1/16 in washers, 28.575 mm) [G];
* ``E_b = 200 GPa`` for the bolt: *assumption*, the steel of the tutorial's bolts
  [G] (the bolts' grade is not in our sources);
* ``mu = 0.6``: *assumption*. [P] uses mu = 0.03 at the asperity level of a rough
  contact law, which is not a Coulomb coefficient of a flat interface; 0.6 is the
  coefficient of qsma's other steel examples;
* every bolt gets the mean of the three preloads of [P], as [P] does;
* with ``surfaces="flat"`` the bolts, nuts and washers have no mass (28 g a set by
  [G]'s dimensions; the lap is an antinode of the first bending mode:
  docs/validation.md estimates the effect) and the 0.8 g accelerometer of [P] is not
  modelled; the default (measured surfaces) carries both.
"""
from __future__ import annotations

import dataclasses
import math

import numpy as np

from ..errors import InputError
from ..model import (Body, Bolt, Interface, LinearDamping, Material, Model, PointMass,
                     Probe)
from ..mesh.generate import graded_axis, structured_mesh
from ..mesh.mesh import Mesh

_IN = 0.0254      # metres per inch

#: The Brake-Reuss beam (SI units), sources in the module docstring.
BRB = dict(
    L_half=0.420,                 # [G] length of one half beam
    c=0.120,                      # [G] lap length
    h=0.0254,                     # [G] beam thickness (each half 12.7 mm in the lap)
    b=0.0254,                     # [G] beam width
    x_bolts=(-0.030, 0.0, 0.030),  # [G] bolt positions from the lap centre
    r_washer_in=11 / 64 * _IN,    # [G] washer bore radius (11/32 in diameter)
    r_washer_out=11 / 32 * _IN,   # [G] washer outside radius (11/16 in diameter)
    t_washer=_IN / 16,            # [G] washer thickness
    d_bolt=5 / 16 * _IN,          # [G] shank diameter
    E=192.31e9, nu=0.3, rho=7784.3,       # [P] 304L
    preloads=(12002.0, 12075.0, 12670.0),  # [P] per bolt, N; every bolt gets the mean
    E_bolt=200e9,                 # assumption (steel of the tutorial's bolts [G])
    bolt_set_mass=0.028,          # [G] bolt, nut and two washers by their dimensions, kg
    sensor_mass=0.8e-3,           # [P] the accelerometer at the tip (main_epmc.m), kg
    mu=0.6,                       # assumption (see the module docstring)
)

#: Published comparison values, Hz: [P]'s simulated first three bending modes of the
#: prestressed model (tmdsimpy examples/structures/brb_epmc.py, lines 590-594): flat
#: interface, and with the measured mesoscale gap.
BRB_PUBLISHED_HZ = dict(simulated_flat=(168.5026, 580.4082, 1177.6498),
                        simulated_meso=(180.6293, 595.2815, 1199.9013))

#: The asperities of the measured lap surfaces ([P], module docstring):
#: :class:`qsma.contact.laws.RoughSurface` arguments, SI units.
BRB_ROUGH = dict(
    sigma=3.17e-6,                # std of the measured pair-gap density (evaluated)
    radius=1.3649e-3,             # [P] Re, effective radius of an asperity pair
    density=1.3713e6,             # [P] asperity pairs per m^2
    E=192.31e9, nu=0.3,           # [P] 304L
    yield_strength=331.7e6,       # [P] asperity yield strength
    hardening=620e6,              # [P] tangent (hardening) modulus
    n_sigma=28.048e-6 / (2 * 3.17e-6),   # [P] z_max = 28.048 um, the measured range
)
#: The mesoscale gap of the lap ([P] ``mesoscale_xygap`` averaged across the width),
#: x (m) and gap (m).
BRB_MESOSCALE_GAP = (
    tuple(x * 1e-3 for x in range(-60, 61, 10)),
    tuple(g * 1e-6 for g in (21, 43, 62, 77, 89, 98, 103, 102, 95, 83, 65, 36, 6.5)),
)
#: Linear damping ratio of the first bending mode ([P], "taken from experiments").
BRB_DAMPING = 0.087e-2

#: Elements per segment at refine 1: along the outer 300 mm, along the 120 mm lap
#: (a multiple of 4, so that the bolt axes are grid lines), per 12.7 mm half
#: thickness, across the 25.4 mm width (even: the bolt axes are grid lines).
BRB_MESH = dict(n_outer=10, n_lap=16, n_half=2, n_width=4)


def brb_pretension() -> float:
    """Pretension of every bolt: the mean of the three preloads of [P], N."""
    return float(np.mean(BRB["preloads"]))


def brb_bolt_stiffness() -> float:
    r"""Locked axial stiffness of one bolt, :math:`k = E_b \pi d^2 / (4 L)` with the
    grip :math:`L = h + 2 t_w` (both lap halves and both washers), N/m."""
    s = BRB
    area = math.pi * s["d_bolt"] ** 2 / 4
    return s["E_bolt"] * area / (s["h"] + 2 * s["t_washer"])


def _check_refine(refine):
    if isinstance(refine, bool) or not isinstance(refine, (int, np.integer)) or refine < 1:
        raise InputError(f"refine must be a positive integer (1 = the coarse test mesh), "
                         f"got {refine!r}")


def _axes(refine, left):
    """Grid axes of one half beam (x, y, z)."""
    s, m = BRB, BRB_MESH
    a, lap_end = s["L_half"] - s["c"] / 2, s["c"] / 2
    outer = (-a, -lap_end, m["n_outer"] * refine)
    lap = (-lap_end, lap_end, m["n_lap"] * refine)
    xs = graded_axis(outer, lap) if left else graded_axis(lap, (lap_end, a, outer[2]))
    t = s["h"] / 2
    ys = graded_axis((-t, 0.0, m["n_half"] * refine), (0.0, t, m["n_half"] * refine))
    zs = np.linspace(0.0, s["b"], m["n_width"] * refine + 1)
    return xs, ys, zs


def _drop_cells(mesh: Mesh, keep: np.ndarray) -> Mesh:
    """``mesh`` with only the cells ``keep`` and the nodes they use (renumbered)."""
    cells = mesh.cells[keep]
    used, inverse = np.unique(cells, return_inverse=True)
    return Mesh(mesh.points[used], inverse.reshape(cells.shape), mesh.cell_type)


def _half_beam_mesh(refine, left) -> Mesh:
    """One stepped half beam: the box of its axes without the lap's other half
    (left beam: the upper half y > 0 of the lap is removed; right beam: the lower)."""
    box = structured_mesh(*_axes(refine, left))
    centre = box.points[box.cells].mean(axis=1)
    lap = np.abs(centre[:, 0]) < BRB["c"] / 2
    other_half = centre[:, 1] > 0 if left else centre[:, 1] < 0
    return _drop_cells(box, ~(lap & other_half))


def _washer(mesh, facets, x_bolt):
    """Facets of ``facets`` whose centroid lies in the washer annulus around the bolt
    axis at ``x_bolt`` (z = b / 2)."""
    s = BRB
    c = mesh.points[facets].mean(axis=1)
    r = np.hypot(c[:, 0] - x_bolt, c[:, 2] - s["b"] / 2)
    return facets[(r >= s["r_washer_in"]) & (r <= s["r_washer_out"])]


def _sets(mesh, left):
    s = BRB
    eps = 1e-9 * s["L_half"]
    t, lap_end = s["h"] / 2, s["c"] / 2
    p = mesh.points
    outer_y = -t if left else t
    outer = mesh.boundary_facets_where(lambda q: np.abs(q[:, 1] - outer_y) < eps)
    facet_sets = {
        "interface": mesh.boundary_facets_where(
            lambda q: (np.abs(q[:, 1]) < eps) & (np.abs(q[:, 0]) <= lap_end + eps)),
    }
    for k, xb in enumerate(s["x_bolts"]):
        facet_sets[f"washer{k + 1}"] = _washer(mesh, outer, xb)
    end_x = -(s["L_half"] - lap_end) if left else s["L_half"] - lap_end
    node_sets = {"end": np.flatnonzero(np.abs(p[:, 0] - end_x) < eps)}
    return mesh.with_sets(node_sets=node_sets, facet_sets=facet_sets)


#: What :func:`brb` takes for the interface: the measured surfaces (asperities, shape,
#: linear damping; the default) or a flat interface of hard contact with rigid stick.
SURFACES = ("measured", "flat")


def _with_masses(body):
    """``body`` with the masses the beam carries: half a bolt set (head or nut, a
    washer, half the shank) on each washer annulus, and the accelerometer on the right
    beam's free end."""
    s = BRB
    masses = [PointMass(f"washer{k}", s["bolt_set_mass"] / 2)
              for k in range(1, len(s["x_bolts"]) + 1)]
    if body.name == "right":
        masses.append(PointMass("end", s["sensor_mass"]))
    return dataclasses.replace(body, masses=tuple(masses))


def measured_interface(itf):
    """``itf`` with the measured surfaces of [P]: the rough-surface law
    (:data:`BRB_ROUGH`) and the mesoscale gap (:data:`BRB_MESOSCALE_GAP`)."""
    from ..contact.laws import InterfaceLaw, RoughSurface
    from ..model.gapfield import GapField
    x, g = BRB_MESOSCALE_GAP
    gap = GapField(("x",), np.array(x)[:, None], np.array(g),
                   source="the Brake-Reuss beam's mesoscale gap")
    return dataclasses.replace(itf, law=InterfaceLaw(RoughSurface(**BRB_ROUGH)), gap=gap)


def brb(refine: int = 1, mu: float | None = None, element: str = "C3D8I",
        surfaces: str = "measured") -> Model:
    r"""The Brake-Reuss beam, free-free, with its three pretensioned bolts.

    Two hexahedral half beams (``"left"``, x < 60 mm, and ``"right"``) meet on the
    lap's interface y = 0, |x| <= 60 mm, node to node; no clamp (the test hangs on
    soft suspensions). Bolt ``k`` joins the washer set ``washer{k}`` on the left
    beam's outer face y = -12.7 mm (head) to the one on the right beam's outer face
    y = +12.7 mm (nut), pretension :func:`brb_pretension`, locked stiffness
    :func:`brb_bolt_stiffness`. The probe is the mean y displacement of the right
    beam's free end (x = 360 mm), where [G] puts its output node.

    Parameters
    ----------
    refine : int
        Every element divided ``refine`` times per direction. ``1``: the coarse test
        mesh (1,030 nodes, 85 interface pairs; preload and tied modes in about a
        second, a run of five levels in 20 to 30 s); ``2``: the validation mesh
        (6,282 nodes, 297 pairs; 13 levels in 2.4 CPU minutes, docs/validation.md).
    mu : float, optional
        Friction coefficient (default 0.6, an assumption: module docstring).
    element : str
        ``"C3D8I"`` (default: incompatible modes, which bend correctly with two
        elements per half thickness) or ``"hexahedron"`` (trilinear, full
        integration: shear locking stiffens the coarse meshes).
    surfaces : {"measured", "flat"}
        ``"measured"`` (default, the project's best prediction): the lap's measured
        surfaces of [P], their asperities as a rough-surface law
        (:data:`BRB_ROUGH`), their shape as the initial gap (:data:`BRB_MESOSCALE_GAP`),
        and the structure's linear damping (:data:`BRB_DAMPING`). ``"flat"``: a flat
        interface of hard contact with rigid stick and no linear damping.

    Notes
    -----
    The tied structure (pairs closed by the preload welded, open pairs free, bolts
    locked) has six rigid modes, which qsma skips; ``mode = 0`` is the first
    elastic mode.
    """
    _check_refine(refine)
    if element not in ("C3D8I", "hexahedron"):
        raise InputError(f"element must be 'C3D8I' or 'hexahedron', got {element!r}")
    if surfaces not in SURFACES:
        raise InputError(f"surfaces must be one of {SURFACES}, got {surfaces!r}")
    s = BRB
    steel = Material(s["E"], s["nu"], s["rho"])
    bodies = []
    for name, left in (("left", True), ("right", False)):
        mesh = _sets(_half_beam_mesh(refine, left), left)
        if element != "hexahedron":
            mesh = dataclasses.replace(mesh, element=element)
        bodies.append(Body(name, mesh, steel))
    N0, k = brb_pretension(), brb_bolt_stiffness()
    bolts = tuple(Bolt(f"bolt{j}", "left", f"washer{j}", "right", f"washer{j}", N0, k)
                  for j in range(1, len(s["x_bolts"]) + 1))
    suffix = "" if element == "C3D8I" else f", element={element}"
    itf = Interface("left", "interface", "right", "interface")
    damping = None
    if surfaces == "measured":
        itf, damping = measured_interface(itf), LinearDamping(ratio=BRB_DAMPING)
        bodies = [_with_masses(b) for b in bodies]
    else:
        suffix += ", flat"
    return Model(bodies=tuple(bodies), interface=itf,
                 tip=Probe(sets=(("right", "end"),), direction=(0.0, 1.0, 0.0)),
                 mu=s["mu"] if mu is None else mu, bolts=bolts, damping=damping,
                 name=f"brb (refine={refine}{suffix})")
