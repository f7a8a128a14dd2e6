"""Materials, boundary conditions, loads, bodies and the assembled model."""
from __future__ import annotations

from dataclasses import dataclass, field, replace
import math
import warnings

import numpy as np

from ..errors import InputError, NearlyIncompressibleWarning
from .damping import LinearDamping
from .friction import check_mu
from ..mesh.celltypes import CELL_TYPES
from ..mesh.mesh import Mesh

#: Poisson's ratio above which the displacement elements of qsma lock. Measured with
#: linear_modes on sandwich-2d, f0 at refine 1 against refine 4: the discretisation
#: error is 2.0 % at nu = 0.285, 2.9 % at 0.45, 4.4 % at 0.475 (twice that at 0.285),
#: 8.4 % at 0.49 and 42 % at 0.499 (f0 367 Hz instead of 259).
NU_LOCKING = 0.475


def _finite(name, value):
    if not isinstance(value, (int, float, np.floating, np.integer)) or isinstance(value, bool):
        raise InputError(f"{name} must be a number, got {value!r}")
    if not math.isfinite(value):
        raise InputError(f"{name} must be finite, got {value!r}")
    return float(value)


@dataclass(frozen=True)
class Material:
    """Isotropic linear elastic material, in the model's unit system (``Model.units``:
    E in Pa and rho in kg/m^3 in SI, MPa and t/mm^3 in mm-N-s-tonne).

    Plane strain is used in 2D (unit out-of-plane depth).
    """

    E: float
    nu: float
    rho: float

    def __post_init__(self):
        E, nu, rho = (_finite(n, getattr(self, n)) for n in ("E", "nu", "rho"))
        if E <= 0:
            raise InputError(f"Young's modulus E must be > 0, got {E}")
        if not -1.0 < nu < 0.5:
            raise InputError(f"Poisson's ratio nu must lie in (-1, 0.5), got {nu}")
        if rho <= 0:
            raise InputError(f"density rho must be > 0, got {rho}")
        if nu > NU_LOCKING:
            warnings.warn(
                f"Poisson's ratio nu = {nu} is close to 0.5 (lambda / mu = "
                f"{2 * nu / (1 - 2 * nu):.3g}): displacement elements lock and the model "
                f"comes out too stiff (sandwich-2d, coarse mesh: f0 +8 % at nu = 0.49, "
                f"+42 % at 0.499). Use a mixed (u-p) or incompatible-mode element, or "
                f"refine the mesh and check that the results converge",
                NearlyIncompressibleWarning, stacklevel=3)
        object.__setattr__(self, "E", E)
        object.__setattr__(self, "nu", nu)
        object.__setattr__(self, "rho", rho)

    @property
    def lame(self):
        """Lame parameters (lambda, mu) of the 3D material (plane strain in 2D)."""
        E, nu = self.E, self.nu
        return E * nu / ((1 + nu) * (1 - 2 * nu)), E / (2 * (1 + nu))


@dataclass(frozen=True)
class Clamp:
    """Dirichlet condition on the nodes of a set, for components ``components``
    (``None``: every component): ``u_c = 0``, or with ``displacement`` (one value per
    component held, in the model's length unit) the displacement prescribed in the
    preload step and held from then on (a support moved into place, a displacement-
    driven preload, as an Abaqus ``*BOUNDARY`` row with a value)."""

    set: str
    components: tuple | None = None
    displacement: tuple | None = None

    def __post_init__(self):
        if self.displacement is not None:
            v = self.displacement
            if isinstance(v, (str, bytes)) or not hasattr(v, "__len__"):
                raise InputError(f"clamp on {self.set!r}: displacement must be a list of one "
                                 f"value per component held, got {v!r}")
            object.__setattr__(self, "displacement", tuple(
                _finite(f"displacement of the clamp on {self.set!r}", x) for x in v))


@dataclass(frozen=True)
class Pressure:
    """Pressure ``p`` (the model's stress unit, positive pushes into the body) on a
    facet set, part of the load pattern named ``load`` (the bolt preload is
    ``"preload"``)."""

    set: str
    p: float
    load: str = "preload"

    def __post_init__(self):
        object.__setattr__(self, "p", _finite(f"pressure on {self.set!r}", self.p))


@dataclass(frozen=True)
class NodalForce:
    """Force ``force`` (N; N per metre of depth in 2D, one component per direction) on
    every node of a node or facet set, as an Abaqus / CalculiX ``*CLOAD`` applies it;
    part of the load pattern named ``load``."""

    set: str
    force: tuple
    load: str = "preload"

    def __post_init__(self):
        f = self.force
        if isinstance(f, (str, bytes)) or not hasattr(f, "__len__"):
            raise InputError(f"force on {self.set!r}: force must be a list of one value "
                             f"per direction (N), got {f!r}")
        object.__setattr__(self, "force", tuple(_finite(f"force on {self.set!r}", v)
                                                for v in f))


@dataclass(frozen=True, eq=False)
class Body:
    """One elastic body: mesh, material, clamps, pressure loads, grounded springs
    (:class:`qsma.model.spring.Spring`), point masses
    (:class:`qsma.model.mass.PointMass`) and nodal forces (:class:`NodalForce`)."""

    name: str
    mesh: Mesh
    material: Material
    clamps: tuple = ()
    pressures: tuple = ()
    springs: tuple = ()
    masses: tuple = ()
    forces: tuple = ()

    def __post_init__(self):
        for name in ("clamps", "pressures", "springs", "masses", "forces"):
            object.__setattr__(self, name, tuple(getattr(self, name)))
        from .spring import check_springs
        from .mass import check_masses
        check_springs(self)
        check_masses(self)
        names = self.mesh.set_names()
        for c in self.clamps:
            if c.set not in names:
                raise InputError(f"body {self.name!r}: clamp on unknown set {c.set!r}; "
                                 f"available sets: {names}")
            comps = range(self.mesh.dim) if c.components is None else c.components
            if len(comps) == 0:
                raise InputError(f"body {self.name!r}: the clamp on {c.set!r} holds no "
                                 f"component (components = []); list the components to "
                                 f"hold (0 = x, 1 = y, 2 = z), leave components out to "
                                 f"hold all, or remove the clamp")
            if not all(isinstance(k, (int, np.integer)) and not isinstance(k, bool)
                       and 0 <= k < self.mesh.dim for k in comps):
                raise InputError(f"body {self.name!r}: clamp components must be integers "
                                 f"in 0..{self.mesh.dim - 1} (0 = x, 1 = y, 2 = z), got "
                                 f"{c.components!r}")
            if c.displacement is not None and len(c.displacement) != len(comps):
                raise InputError(f"body {self.name!r}: the clamp on {c.set!r} holds "
                                 f"{len(comps)} component(s) and prescribes "
                                 f"{len(c.displacement)} displacement(s); give one value "
                                 f"per component held")
        if any(c.displacement is not None for c in self.clamps):
            self.prescribed_displacement()           # contradictory values refused here
        for p in self.pressures:
            if p.set not in self.mesh.facet_sets:
                raise InputError(f"body {self.name!r}: pressure on {p.set!r}, "
                                 f"{_not_a_facet_set(self.mesh, p.set)}")
        for f in self.forces:
            if f.set not in names:
                raise InputError(f"body {self.name!r}: force on unknown set {f.set!r}; "
                                 f"available sets: {names}")
            if len(f.force) != self.mesh.dim:
                raise InputError(f"body {self.name!r}: force on {f.set!r} needs "
                                 f"{self.mesh.dim} components, got {list(f.force)!r}")

    @property
    def dim(self):
        return self.mesh.dim

    @property
    def n_dofs(self):
        return self.mesh.n_nodes * self.mesh.dim

    def clamped_dofs(self) -> np.ndarray:
        """Sorted global DOF indices (node-major, ``dim * node + component``) held at zero."""
        dim = self.dim
        dofs = [dim * self.mesh.nodes(c.set)[:, None]
                + np.asarray(range(dim) if c.components is None else c.components)[None, :]
                for c in self.clamps]
        return np.unique(np.concatenate([d.ravel() for d in dofs])) if dofs \
            else np.zeros(0, dtype=np.int64)

    def prescribed_displacement(self) -> np.ndarray | None:
        """The displacement the clamps prescribe (full length, zero where a clamp
        holds at zero and at free DOFs), part of the preload; None if every clamp holds
        at zero. A DOF two clamps hold at different values is refused."""
        if all(c.displacement is None or not any(c.displacement) for c in self.clamps):
            return None
        dim = self.dim
        u = np.zeros(self.n_dofs)
        given = np.zeros(self.n_dofs, dtype=bool)
        for c in self.clamps:
            comps = np.asarray(range(dim) if c.components is None else c.components)
            values = np.zeros(len(comps)) if c.displacement is None \
                else np.asarray(c.displacement, dtype=float)
            dofs = dim * self.mesh.nodes(c.set)[:, None] + comps[None, :]
            vals = np.broadcast_to(values, dofs.shape)
            clash = given[dofs] & (u[dofs] != vals)
            if clash.any():
                i = np.argwhere(clash)[0]
                dof = int(dofs[tuple(i)])
                raise InputError(f"body {self.name!r}: node {dof // dim} component "
                                 f"{dof % dim} is held at {u[dof]:g} by one clamp and at "
                                 f"{float(vals[tuple(i)]):g} by the clamp on {c.set!r}; "
                                 f"give each held DOF one value")
            u[dofs] = vals
            given[dofs] = True
        return u

    def load_names(self):
        names = {p.load for p in self.pressures} | {f.load for f in self.forces}
        if self.prescribed_displacement() is not None:
            names.add("preload")
        return sorted(names)


def _not_a_facet_set(mesh, name) -> str:
    """Why ``name`` cannot carry a pressure and what to name instead."""
    facets = f"available facet sets: {sorted(mesh.facet_sets)}"
    faces = ("a facet set: in an .inp file a *SURFACE, TYPE=ELEMENT of the loaded faces "
             f"(rows 'element set, S1'..'S{len(CELL_TYPES[mesh.cell_type].facets)}'), in a Gmsh "
             f"file a physical group of dimension {mesh.dim - 1}")
    if name in mesh.cell_sets:
        return (f"which is a cell set (elements, e.g. the set of an Abaqus *DLOAD), not a "
                f"facet set: a pressure acts on element faces. Name {faces}; {facets}")
    if name in mesh.node_sets:
        return (f"which is a node set, not a facet set: a pressure acts on element faces "
                f"(loads on nodes, as an Abaqus *CLOAD, are forces: forces = [{{ set = "
                f"{name!r}, force = [...] }}]). Name {faces}; {facets}")
    return f"an unknown facet set; {facets}"


@dataclass(frozen=True)
class Probe:
    """A response quantity: mean displacement along ``direction`` of the nodes of
    set ``set`` in each listed body (e.g. the tip deflection)."""

    sets: tuple          # ((body name, set name), ...)
    direction: tuple     # unit vector, length dim


@dataclass(frozen=True, eq=False)
class Model:
    """Elastic bodies joined by frictional contact interfaces.

    Two bodies and one interface: ``interface``. Any number of bodies and interfaces:
    ``interfaces`` (``interface`` then stays ``None``); :attr:`interface_list` is the
    tuple of interfaces either way. ``mu`` is the friction coefficient of every
    interface that sets none of its own (``Interface.mu``). ``tip`` is the probe
    reported as tip deflection and used to scale load levels. ``units`` names the
    unit system every number of the model is written in (:data:`qsma.units.UNIT_SYSTEMS`:
    ``"SI"``, the default, or ``"mm-N-s-tonne"``); nothing is converted, the name
    labels the results. ``damping``: the linear damping of the structure besides the
    joint (:class:`qsma.model.LinearDamping`), reported beside the joint's and added to
    it.
    """

    bodies: tuple
    interface: "Interface | None" = None
    tip: Probe | None = None
    mu: float = 0.6
    name: str = "model"
    extra: dict = field(default_factory=dict)
    interfaces: tuple = ()
    bolts: tuple = ()                 # qsma.model.bolt.Bolt, pretensioned then locked
    units: str = "SI"
    damping: "LinearDamping | None" = None   # of the structure besides the joint

    def __post_init__(self):
        object.__setattr__(self, "bodies", tuple(self.bodies))
        object.__setattr__(self, "interfaces", tuple(self.interfaces))
        if not self.bodies:
            raise InputError("the model has no bodies; give at least the two bodies that "
                             "an interface joins ([[bodies]] tables in a configuration)")
        names = [b.name for b in self.bodies]
        if len(set(names)) != len(names):
            raise InputError(f"body names must be unique, got {names}")
        dims = {b.dim for b in self.bodies}
        if len(dims) != 1:
            raise InputError(f"all bodies must have the same dimension, got {sorted(dims)}")
        mu = _finite("friction coefficient mu", self.mu)
        if mu < 0:
            raise InputError(f"friction coefficient mu must be >= 0, got {mu}")
        check_mu(mu)
        object.__setattr__(self, "mu", mu)
        from ..units import unit_system
        object.__setattr__(self, "units", unit_system(self.units).name)
        if self.interface is not None and self.interfaces:
            raise InputError("give either interface (two bodies) or interfaces (a list), "
                             "not both")
        if not self.interface_list:
            raise InputError("the model has no interface: name the facet sets in contact "
                             "(Interface(body1, set1, body2, set2))")
        for itf in self.interface_list:
            self._check_interface(itf, names)
        from .interface import check_interfaces
        check_interfaces(self)
        if self.tip is not None:
            self._check_probe(self.tip)
        self._check_bolts(names)
        if self.damping is not None and not isinstance(self.damping, LinearDamping):
            raise InputError(f"damping must be a qsma.model.LinearDamping, got "
                             f"{type(self.damping).__name__}")

    def _check_bolts(self, names):
        """Bolt ends on bodies of the model, unique bolt names."""
        object.__setattr__(self, "bolts", tuple(self.bolts))
        seen = set()
        for b in self.bolts:
            for end in b.bodies:
                if end not in names:
                    raise InputError(f"bolt {b.name!r} names body {end!r}, which is not "
                                     f"in the model (bodies: {names})")
            if b.name in seen:
                raise InputError(f"bolt names must be unique: {b.name!r} twice")
            seen.add(b.name)

    @property
    def interface_list(self) -> tuple:
        """Every interface of the model (one for ``interface``)."""
        return (self.interface,) if self.interface is not None else self.interfaces

    def check_mu_reaches(self, mu, fix: str, what: str | None = None):
        """Refuse a model-wide friction coefficient that some interface would not see:
        one that sets a ``mu`` of its own (other than ``mu``; ``mu=None``: any value, as
        a fit tries) keeps it. ``what`` names where the value came from (e.g.
        ``--mu 0.1``), ``fix`` says what to change."""
        own = [i for i in self.interface_list
               if i.mu is not None and (mu is None or i.mu != mu)]
        if own:
            more = f" (and {len(own) - 1} more)" if len(own) > 1 else ""
            what = what or f"friction coefficient mu = {mu!r}"
            raise InputError(f"{what} sets the friction coefficient of the whole model, "
                             f"but interface {own[0].label} sets its own mu = "
                             f"{own[0].mu}{more}, which the model's mu does not replace. "
                             f"Fix: {fix}")

    def with_mu(self, mu, fix: str, what: str | None = None) -> "Model":
        """The model with friction coefficient ``mu`` on every interface
        (:meth:`check_mu_reaches` first)."""
        self.check_mu_reaches(mu, fix, what)
        return replace(self, mu=mu)

    def _check_interface(self, itf, names):
        for b in (itf.body1, itf.body2):
            if b not in names:
                raise InputError(f"interface {itf.label} names body {b!r}, which is not in "
                                 f"the model (bodies: {names})")
        if itf.body1 == itf.body2:
            raise InputError(f"the interface {itf.label} joins body {itf.body1!r} to "
                             f"itself; body1 and body2 must be the two bodies in contact")
        self._check_pairing_tol(itf)

    def _check_pairing_tol(self, itf):
        """The interface pairing tolerance must be finite, >= 0 and below half the
        smallest distance between two nodes of either interface set, so that no node
        can find two partners (``nan`` or ``inf`` would pair nothing or everything, silently)."""
        if itf.tol is None:
            return
        tol = _finite("interface pairing tolerance tol", itf.tol)
        if tol < 0:
            raise InputError(f"interface pairing tolerance tol must be >= 0, got {tol}")
        for b, s in ((itf.body1, itf.set1), (itf.body2, itf.set2)):
            gap = _smallest_spacing(self.body(b).mesh, s)
            if gap is not None and tol >= 0.5 * gap:
                raise InputError(
                    f"interface pairing tolerance tol = {tol:g} m is not below half the "
                    f"smallest node spacing {gap:.3e} m of set {s!r} of body {b!r}: a node "
                    f"could pair with the wrong partner. Use a tol below {0.5 * gap:.3e} m "
                    f"(or leave it out: 1e-6 x the interface size)")

    def _check_probe(self, tip):
        if len(tip.sets) == 0:
            raise InputError("the tip probe needs at least one [body, set] pair")
        for b, s in tip.sets:
            self.body(b).mesh.nodes(s)
        d = tip.direction
        if (len(d) != self.dim or not all(isinstance(x, (int, float, np.integer, np.floating))
                                          and not isinstance(x, bool) for x in d)
                or not np.all(np.isfinite(d)) or np.linalg.norm(d) == 0):
            raise InputError(f"tip direction must be {self.dim} finite numbers, not all "
                             f"zero, got {list(d)!r}")

    @property
    def dim(self):
        return self.bodies[0].dim

    @property
    def n_nodes(self):
        return sum(b.mesh.n_nodes for b in self.bodies)

    @property
    def n_dofs(self):
        return sum(b.n_dofs for b in self.bodies)

    def body(self, name) -> Body:
        for b in self.bodies:
            if b.name == name:
                return b
        raise InputError(f"no body named {name!r}; bodies: {[b.name for b in self.bodies]}")

    def body_index(self, name) -> int:
        return [b.name for b in self.bodies].index(self.body(name).name)

    def dof_offsets(self) -> np.ndarray:
        """Start of each body's DOFs in the stacked vector of all bodies."""
        return np.concatenate([[0], np.cumsum([b.n_dofs for b in self.bodies])])


def _smallest_spacing(mesh, set_name):
    """Smallest distance between two distinct nodes of a set (``None``: fewer than two
    nodes, or the set is unknown: pairing reports that)."""
    from scipy.spatial import cKDTree
    try:
        x = mesh.points[mesh.nodes(set_name)]
    except InputError:
        return None
    if len(x) < 2:
        return None
    d, _ = cKDTree(x).query(x, k=2)
    gap = float(d[:, 1].min())
    return gap if gap > 0 else None         # duplicate nodes: pairing names them


from .interface import Interface  # noqa: E402  (circular type reference)
