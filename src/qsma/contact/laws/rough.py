r"""Contact of two rough surfaces from their asperities (a statistical asperity model).

The surfaces touch at the summits of their asperities. As in Greenwood and
Williamson's model, the summits are spheres of one radius whose heights are
random, the contacts do not interact, and the pressure is their sum per unit area:
an asperity pair whose initial gap is ``z`` (``z = 0`` for the pair that touches
first) is pressed by ``delta = h - z`` when the surfaces have closed by ``h``, and

.. math:: p(h) = \eta \int_0^{z_{max}} \phi(z)\, F(h - z)\, dz,\qquad
          k_t(h) = \eta \int_0^{z_{max}} \phi(z)\, 8 G^* a(h - z)\, dz,

with ``eta`` the number of asperity pairs per unit area, ``phi`` the density of their
gaps (here a Gaussian of standard deviation ``sigma`` about its mean, truncated at
``n_sigma`` standard deviations on either side: ``z_max = 2 n_sigma sigma``), ``F`` and
``a`` the normal force and contact radius of one pair and ``8 G* a`` its Mindlin stick
stiffness. Two identical bodies: ``E* = E / (2 (1 - nu^2))``,
``G* = G / (2 (2 - nu))`` with ``G = E / (2 (1 + nu))``.

One pair of effective radius ``R`` (half the summits' radius) is elastic (Hertz) up to
``1.9 delta_y``, then elastic-plastic by the sphere law of Jackson and Green (2005)
with the strain-hardening correction of Ghaednia et al. (2019):

* ``C = 1.295 exp(0.736 nu)``, ``delta_y = 2 (pi C S_y / (4 E*))^2 (2R)``;
* Hertz: ``F = 4/3 E* sqrt(R) delta^{3/2}``, ``a = sqrt(R delta)``;
* beyond, with ``r = delta / delta_y``: ``a_p = 2R (pi C S_y / (4 E*))
  sqrt(r (r / 1.9)^B)``, ``B = 0.14 exp(23 S_y / (2 E*))``; the hardening blend
  ``a = a_e + (a_p - a_e) e^Y`` of the elastic and plastic radii; the hardness
  ``H / S_y = 2.84 - 0.92 (1 - cos(pi a / (2R)))``; ``F_c = 4/3 (R / E*)^2
  (C pi S_y / 2)^3``; ``F_p = F_c [exp(-r^{5/12} / 4) r^{3/2} + 4 H / (C S_y)
  (1 - exp(-r^{5/9} / 25)) r]``; ``F = F_p + (F_e - F_p)(1 - exp(-3.3 E_t / E))``.

A plastically loaded pair unloads elastically (Brake 2015) on
``F = 4/3 E* sqrt(R_u) (delta - delta_r)^{3/2}`` through its largest load
``(delta_m, F_m)``, ``delta_r = delta_m (1 - F_m / F_Hertz(delta_m))``,
``R_u = F_m^2 / ((4/3 E*)^2 (delta_m - delta_r)^3)``: stiffer than the loading
curve. A QSMA loads the joint once (the preload) and then moves it a little about that
state, so the law is the loading curve for the preload and, after it, the tangent of
the unloading curve at each pair's preload state (:meth:`unloading_stiffness`; see
:class:`qsma.contact.layer.Layer`, ``frozen``).

The integrals are evaluated once per law on a table of closures (Gauss-Legendre in
``z`` between the kinks of the pair law), and the pressure-overclosure curve is that
table, piecewise linear (:class:`TabularPressure`: its inverse is exact).
"""
from __future__ import annotations

from dataclasses import dataclass, field
import math

import numpy as np

from ...errors import InputError
from .base import NormalLaw, TangentialLaw, positive
from .tabular import TabularPressure

#: Closures of the table, evenly spaced up to 1.5 times the closure at which every pair
#: touches (and log-spaced near the first touch): the piecewise-linear law then differs
#: from the integral by less than 2e-4 of the pressure (tests/test_interface_laws.py).
TABLE_POINTS = 1500
#: Gauss-Legendre points of the integral over the pair gaps.
GAUSS_POINTS = 400


def _pair_law(delta, R, E_star, G_star, E, nu, Sy, Et):
    """Normal force, contact radius and unloading stiffness of one asperity pair at
    interference ``delta`` (array, >= 0) loaded monotonically to it."""
    delta = np.maximum(delta, 0.0)
    F_e = 4.0 / 3.0 * E_star * np.sqrt(R) * delta ** 1.5
    a_e = np.sqrt(R * delta)
    k_e = 2.0 * E_star * np.sqrt(R * delta)
    if Sy is None:
        return F_e, a_e, k_e
    C = 1.295 * math.exp(0.736 * nu)
    dy = 2.0 * (math.pi * C * Sy / (4.0 * E_star)) ** 2 * (2.0 * R)
    r = delta / dy
    plastic = r > 1.9
    if not plastic.any():
        return F_e, a_e, k_e
    rp = r[plastic]
    B = 0.14 * math.exp(23.0 * Sy / (2.0 * E_star))
    a_p = 2.0 * R * (math.pi * C * Sy / (4.0 * E_star)) * np.sqrt(rp * (rp / 1.9) ** B)
    if Et > 0:
        s = 2.0 * math.sqrt(E / Sy)
        Y = (-s * (Et / E) ** (1.0 - (delta[plastic] - dy) / (4.0 * R))
             / ((4.0 - 3.0 * math.exp(-s * Et / E)) * (1.0 - Et / E)))
    else:
        Y = 0.0
    a = a_e[plastic] + (a_p - a_e[plastic]) * np.exp(Y)
    H = Sy * (2.84 - 0.92 * (1.0 - np.cos(math.pi * a / (2.0 * R))))
    Fc = 4.0 / 3.0 * (R / E_star) ** 2 * (C * math.pi * Sy / 2.0) ** 3
    F_p = Fc * (np.exp(-0.25 * rp ** (5.0 / 12.0)) * rp ** 1.5
                + 4.0 * H / (C * Sy) * (1.0 - np.exp(-rp ** (5.0 / 9.0) / 25.0)) * rp)
    F = F_p + (F_e[plastic] - F_p) * (1.0 - math.exp(-3.3 * Et / E))
    # elastic unloading through (delta, F): residual interference and flattened radius
    dm = delta[plastic]
    residual = dm * (1.0 - F / F_e[plastic])
    R_u = F ** 2 / ((4.0 / 3.0 * E_star) ** 2 * (dm - residual) ** 3)
    k_u = 2.0 * E_star * np.sqrt(R_u * (dm - residual))
    F_all, a_all, k_all = F_e.copy(), a_e.copy(), k_e.copy()
    F_all[plastic], a_all[plastic], k_all[plastic] = F, a, k_u
    return F_all, a_all, k_all


@dataclass(frozen=True)
class RoughStick(TangentialLaw):
    """The Mindlin stick stiffness of the asperities in contact, per unit area, at the
    pressure ``p`` (from the table of its :class:`RoughSurface`)."""

    surface: "RoughSurface" = field(repr=False, compare=False)

    name = "rough"

    def stiffness(self, p):
        return self.surface.stick_stiffness(p)

    def as_dict(self):
        return {}                           # implied by the normal law


@dataclass(frozen=True)
class RoughSurface(NormalLaw):
    """Asperity contact of two rough surfaces of the same material (module docstring).

    Parameters
    ----------
    sigma : float
        Standard deviation of the asperity pairs' gaps (m); for two surfaces of summit
        height deviation ``s`` each, ``sqrt(2) s``.
    radius : float
        Effective radius of an asperity pair (m), half the summits' radius.
    density : float
        Asperity pairs per unit area (1/m^2).
    E, nu : float
        Young's modulus (Pa) and Poisson's ratio of the two bodies.
    yield_strength : float or None
        Yield strength ``S_y`` (Pa); None: elastic asperities (Greenwood-Williamson).
    hardening : float
        Tangent modulus ``E_t`` of the strain hardening (Pa), 0 for none.
    n_sigma : float
        Truncation of the gap distribution, standard deviations either side.
    """

    sigma: float
    radius: float
    density: float
    E: float
    nu: float
    yield_strength: float | None = None
    hardening: float = 0.0
    n_sigma: float = 4.0

    name = "rough"

    def __post_init__(self):
        owner = "rough-surface contact law"
        for key, unit in (("sigma", "m"), ("radius", "m"), ("density", "1/m^2"),
                          ("E", "Pa"), ("n_sigma", "standard deviations")):
            object.__setattr__(self, key, positive(owner, key, getattr(self, key), unit))
        if isinstance(self.nu, bool) or not isinstance(self.nu, (int, float)) \
                or not -1 < self.nu < 0.5:
            raise InputError(f"{owner}: nu must lie in (-1, 0.5), got {self.nu!r}")
        if self.yield_strength is not None:
            object.__setattr__(self, "yield_strength",
                               positive(owner, "yield_strength", self.yield_strength, "Pa"))
        if self.hardening:
            object.__setattr__(self, "hardening",
                               positive(owner, "hardening", self.hardening, "Pa"))
        object.__setattr__(self, "_table", self._tabulate())

    # --- the integrals ------------------------------------------------------------

    @property
    def plastic(self) -> bool:
        return self.yield_strength is not None

    @property
    def z_max(self):
        return 2.0 * self.n_sigma * self.sigma

    def _moduli(self):
        E_star = self.E / (2.0 * (1.0 - self.nu ** 2))
        G = self.E / (2.0 * (1.0 + self.nu))
        return E_star, G / (2.0 * (2.0 - self.nu))

    def _density(self, z):
        """Truncated Gaussian density of the pair gaps on [0, z_max]."""
        m = self.n_sigma * self.sigma
        norm = math.erf(self.n_sigma / math.sqrt(2.0))
        return np.exp(-0.5 * ((z - m) / self.sigma) ** 2) / (
            self.sigma * math.sqrt(2.0 * math.pi) * norm)

    def integrals(self, h):
        """``(p, k_t, k_unload)`` per unit area at closures ``h`` (array, m): Gauss-
        Legendre over the gaps ``z in [0, min(h, z_max)]`` (pairs with ``z > h`` do
        not touch)."""
        h = np.atleast_1d(np.asarray(h, dtype=float))
        E_star, G_star = self._moduli()
        x, w = np.polynomial.legendre.leggauss(GAUSS_POINTS)
        top = np.minimum(h, self.z_max)[:, None]
        z = 0.5 * top * (x[None] + 1.0)
        wz = 0.5 * top * w[None] * self._density(z)
        F, a, k = _pair_law((h[:, None] - z).ravel(), self.radius, E_star, G_star, self.E,
                            self.nu, self.yield_strength, self.hardening)
        shape = z.shape
        eta = self.density
        return (eta * np.sum(wz * F.reshape(shape), axis=1),
                eta * np.sum(wz * 8.0 * G_star * a.reshape(shape), axis=1),
                eta * np.sum(wz * k.reshape(shape), axis=1))

    def _tabulate(self):
        h = self.z_max * np.concatenate([[0.0], np.geomspace(1e-5, 1e-2, 60)[:-1],
                                         np.linspace(1e-2, 1.5, TABLE_POINTS)])
        p, kt, ku = self.integrals(h)
        keep = np.concatenate([[True], np.diff(p) > 0])        # strictly increasing
        h, p, kt, ku = h[keep], p[keep], kt[keep], ku[keep]
        return dict(curve=TabularPressure(tuple(zip(p.tolist(), h.tolist()))),
                    p=p, kt=kt, ku=ku)

    # --- the law ---------------------------------------------------------------------

    @property
    def onset(self):
        return 0.0

    def pressure(self, h):
        return self._table["curve"].pressure(h)

    def stiffness(self, h):
        return self._table["curve"].stiffness(h)

    def overclosure(self, p):
        return self._table["curve"].overclosure(p)

    def tangent_at_pressure(self, p):
        return self._table["curve"].tangent_at_pressure(p)

    def unloading_stiffness(self, p):
        """Stiffness per unit area of the elastic unloading from pressure ``p`` (Pa/m),
        the sum of the asperities' unloading slopes (equal to the loading tangent for
        elastic asperities)."""
        t = self._table
        return np.interp(np.maximum(p, 0.0), t["p"], t["ku"])

    def stick_stiffness(self, p):
        """Mindlin stick stiffness per unit area at pressure ``p`` (Pa/m)."""
        t = self._table
        return np.interp(np.maximum(p, 0.0), t["p"], t["kt"])

    @property
    def stick(self):
        """The tangential law this surface implies (:class:`RoughStick`)."""
        return RoughStick(self)

    def scale_pressure(self):
        """The pressure at which half the asperity pairs touch."""
        return float(self.pressure(self.n_sigma * self.sigma))

    def as_dict(self):
        return {"normal": "rough", "sigma": self.sigma, "radius": self.radius,
                "density": self.density, "E": self.E, "nu": self.nu,
                "yield_strength": self.yield_strength, "hardening": self.hardening,
                "n_sigma": self.n_sigma}
