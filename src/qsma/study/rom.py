r"""Reduced-order model export: a modal four-parameter Iwan element fitted to a QSMA
backbone, written as ``rom.json`` (format: docs/studies.md).

Segalman's four-parameter Iwan element (D. J. Segalman, "A four-parameter Iwan model
for lap-type joints", J. Appl. Mech. 72 (2005) 752-760) is a parallel array of Jenkins
elements (unit stiffness, slip force :math:`\phi`) with the density

.. math::

    \rho(\phi) = R\,\phi^{\chi}\,[H(\phi) - H(\phi - \phi_{max})]
                 + S\,\delta(\phi - \phi_{max}),

parametrised by the macroslip force :math:`F_S`, the stiffness :math:`K_T`, the
exponent :math:`\chi` and :math:`\beta = S / \int_0^{\phi_{max}} R\phi^\chi d\phi`:

.. math::

    \phi_{max} = \frac{F_S (1+\beta)}{K_T (\beta + \frac{\chi+1}{\chi+2})},\quad
    R = \frac{F_S (\chi+1)}{\phi_{max}^{\chi+2} (\beta + \frac{\chi+1}{\chi+2})},\quad
    S = \frac{F_S\,\beta}{\phi_{max} (\beta + \frac{\chi+1}{\chi+2})}.

Under monotonic loading to :math:`u` (with :math:`v = \min(u, \phi_{max})`) the force
is :math:`F(u) = \int_0^v \phi\rho\,d\phi + u\int_v^\infty \rho\,d\phi`, i.e.
:math:`F = K_T u - R u^{\chi+2}/((\chi+1)(\chi+2))` below macroslip and :math:`F_S`
beyond, and the dissipation per cycle of amplitude :math:`u` (Masing) is
:math:`D = \int_0^v 4\phi(u-\phi)\rho\,d\phi`, i.e. :math:`4 R u^{\chi+3} /
((\chi+2)(\chi+3))` below macroslip.

The modal model (as in the modal Iwan models of Segalman and of Deaner, Allen et al.)
puts the element in parallel with the residual modal stiffness of the fully slipped
joint, so that the small-amplitude stiffness is the tied :math:`\omega_0^2`:

.. math::

    \alpha(q) = (\omega_0^2 - K_T)\,q + F_{Iwan}(q).
"""
from __future__ import annotations

from dataclasses import dataclass
import json

import numpy as np

from ..errors import AnalysisError, InputError

ROM_SCHEMA_VERSION = 1
#: Bounds of chi: Segalman's element needs chi > -1 (finite stiffness); chi <= 1 covers
#: every joint reported in his paper (-1 < chi <= 0) with margin.
CHI_BOUNDS = (-0.999, 1.0)
#: Starting exponents and beta ratios of the multi-start fit (the span of Segalman's
#: table of lap-joint identifications, chi from -0.8 to 0, beta from 0.1 to 10).
CHI_STARTS = (-0.8, -0.5, -0.2, 0.0)
BETA_STARTS = (0.1, 1.0, 10.0)


#: Levels needed beyond phi_max: there the modal backbone is the line
#: (omega0^2 - K_T) q + F_S, two unknowns; with fewer than three points other elements
#: match the backbone exactly (seen with one point: a different F_S, K_T, beta).
MACROSLIP_LEVELS = 3


@dataclass(frozen=True)
class Iwan4:
    """Segalman's four-parameter Iwan element (module docstring for the formulas)."""

    F_S: float
    K_T: float
    chi: float
    beta: float

    def __post_init__(self):
        for name in ("F_S", "K_T"):
            v = getattr(self, name)
            if not (np.isfinite(v) and v > 0):
                raise InputError(f"Iwan parameter {name} must be positive, got {v!r}")
        if not (CHI_BOUNDS[0] <= self.chi <= CHI_BOUNDS[1]):
            raise InputError(f"Iwan exponent chi must be in {CHI_BOUNDS}, got {self.chi!r}")
        if not (np.isfinite(self.beta) and self.beta >= 0):
            raise InputError(f"Iwan ratio beta must be >= 0, got {self.beta!r}")

    @property
    def _c(self):
        return self.beta + (self.chi + 1) / (self.chi + 2)

    @property
    def phi_max(self) -> float:
        return self.F_S * (1 + self.beta) / (self.K_T * self._c)

    @property
    def R(self) -> float:
        return self.F_S * (self.chi + 1) / (self.phi_max ** (self.chi + 2) * self._c)

    @property
    def S(self) -> float:
        return self.F_S * self.beta / (self.phi_max * self._c)

    def force(self, u):
        """Force under monotonic loading from rest to displacement ``u`` >= 0."""
        u = np.asarray(u, float)
        c, pm, R = self.chi, self.phi_max, self.R
        v = np.minimum(u, pm)
        return (R * v ** (c + 2) / (c + 2) + u * R * (pm ** (c + 1) - v ** (c + 1)) / (c + 1)
                + np.where(u < pm, u * self.S, self.S * pm))

    def dissipation(self, u):
        """Energy dissipated per cycle of amplitude ``u`` (Masing's rules)."""
        u = np.asarray(u, float)
        c, pm, R = self.chi, self.phi_max, self.R
        v = np.minimum(u, pm)
        return (4 * R * (u * v ** (c + 2) / (c + 2) - v ** (c + 3) / (c + 3))
                + np.where(u > pm, 4 * self.S * pm * (u - pm), 0.0))

    def as_dict(self) -> dict:
        return dict(F_S=self.F_S, K_T=self.K_T, chi=self.chi, beta=self.beta,
                    phi_max=self.phi_max, R=self.R, S=self.S)


@dataclass(frozen=True)
class ModalIwan:
    """A mode with an Iwan joint: ``alpha(q) = (omega0^2 - K_T) q + F_Iwan(q)``."""

    omega0: float
    element: Iwan4

    @property
    def k_inf(self) -> float:
        """Modal stiffness left when the joint is fully slipped, ``omega0^2 - K_T``."""
        return self.omega0 ** 2 - self.element.K_T

    def alpha(self, q):
        q = np.asarray(q, float)
        return self.k_inf * q + self.element.force(q)

    def frequency(self, q):
        r"""Secant frequency :math:`\sqrt{\alpha/q}/(2\pi)` [Hz]."""
        return np.sqrt(self.alpha(q) / np.asarray(q, float)) / (2 * np.pi)

    def damping(self, q):
        r"""Equivalent viscous damping ratio :math:`D/(2\pi q \alpha)` (as QSMA's)."""
        q = np.asarray(q, float)
        return self.element.dissipation(q) / (2 * np.pi * q * self.alpha(q))


@dataclass(frozen=True, eq=False)
class IwanFit:
    """A fitted modal Iwan model and how well it matches the backbone per level."""

    success: bool
    message: str
    model: ModalIwan
    q: np.ndarray
    alpha: np.ndarray
    alpha_fit: np.ndarray
    error: np.ndarray          # (alpha_fit - alpha) / alpha per level
    nfev: int

    @property
    def max_error(self) -> float:
        return float(np.max(np.abs(self.error)))

    @property
    def rms_error(self) -> float:
        return float(np.sqrt(np.mean(self.error ** 2)))


def fit_iwan(q, alpha, omega0, *, rtol=1e-12) -> IwanFit:
    r"""Fit a :class:`ModalIwan` to a backbone by least squares on the relative error
    :math:`(\alpha_{fit}(q_k) - \alpha_k)/\alpha_k`, from several starts
    (:data:`CHI_STARTS` x :data:`BETA_STARTS`), bounds :math:`F_S, K_T > 0`,
    :math:`K_T \le \omega_0^2`, :data:`CHI_BOUNDS`, :math:`\beta \ge 0`.

    Below macroslip the modal backbone is :math:`\omega_0^2 q - R q^{\chi+2} /
    ((\chi+1)(\chi+2))`: only :math:`R, \chi` are identified there. ``success`` is
    False, and the message says why, unless :data:`MACROSLIP_LEVELS` levels lie beyond
    :math:`\phi_{max}`.
    """
    from scipy.optimize import least_squares
    q, alpha = np.asarray(q, float), np.asarray(alpha, float)
    good = np.isfinite(q) & np.isfinite(alpha) & (q > 0) & (alpha > 0)
    if good.sum() < 5:
        raise InputError(f"an Iwan fit needs at least 5 levels with q > 0 and alpha > 0, "
                         f"got {int(good.sum())}: give more load levels")
    q, alpha = q[good], alpha[good]
    k0 = omega0 ** 2
    slope = np.diff(alpha[-2:])[0] / np.diff(q[-2:])[0]
    kt0 = float(np.clip(k0 - slope, 1e-3 * k0, 0.999 * k0))
    fs0 = max(alpha[-1] - (k0 - kt0) * q[-1], 1e-6 * alpha[-1])

    def model_of(x):
        return ModalIwan(omega0, Iwan4(np.exp(x[0]), np.exp(x[1]), x[2], x[3]))

    def residual(x):
        return model_of(x).alpha(q) / alpha - 1

    lo = [-np.inf, -np.inf, CHI_BOUNDS[0], 0.0]
    hi = [np.inf, np.log(k0), CHI_BOUNDS[1], np.inf]
    best, nfev = None, 0
    for chi in CHI_STARTS:
        for beta in BETA_STARTS:
            x0 = [np.log(fs0), np.log(kt0), chi, beta]
            try:
                r = least_squares(residual, x0, bounds=(lo, hi), xtol=rtol, ftol=rtol,
                                  gtol=rtol, max_nfev=2000, method="trf")
            except (ValueError, FloatingPointError):
                continue
            nfev += r.nfev
            if best is None or r.cost < best.cost:
                best = r
    if best is None:
        raise AnalysisError("the Iwan fit failed from every start; check that the "
                            "backbone softens (alpha/q decreasing with q)")
    m = model_of(best.x)
    a_fit = m.alpha(q)
    err = a_fit / alpha - 1
    n_beyond = int(np.sum(q > m.element.phi_max))
    reached = n_beyond >= MACROSLIP_LEVELS
    ok = bool(best.success and reached)
    msg = best.message if reached else (
        f"{n_beyond} level(s) beyond the fitted macroslip amplitude phi_max = "
        f"{m.element.phi_max:.4g} (the backbone stops at q = {q[-1]:.4g}), fewer than "
        f"{MACROSLIP_LEVELS}: K_T, F_S and beta are not identified by it (below "
        f"macroslip only R and chi are); extend the load levels into gross slip")
    return IwanFit(ok, msg, m, q, alpha, a_fit, err, nfev)


#: Jenkins elements of the default series: a handful is what a time-domain code wants
#: to integrate, and 8 log-spaced slip amplitudes over the 3 decades of the spec's
#: levels put about 3 per decade (the fit error per level in rom.json tells if not).
JENKINS_ELEMENTS = 8
#: A secant stiffness within this of the first level's is the linear (stuck) range,
#: where no element is placed: QSMA's stuck levels of sandwich-2d match the tied
#: stiffness to 1e-9 (docs/theory.md, STUCK_FREQUENCY_RTOL 1e-6 on the frequency).
LINEAR_RTOL = 1e-6


@dataclass(frozen=True)
class JenkinsSeries:
    r"""A modal Jenkins series: a linear spring and Jenkins elements in parallel,

    .. math::

        \alpha(q) = k_\infty q + \sum_i k_i \min(q, u_i),\qquad
        D(q) = \sum_{u_i < q} 4 k_i u_i (q - u_i)

    (element i: stiffness :math:`k_i`, slip force :math:`k_i u_i`; :math:`D` is the
    dissipation per cycle of amplitude q under Masing's rules)."""

    k_inf: float
    stiffness: tuple
    slip: tuple

    def alpha(self, q):
        q = np.asarray(q, float)
        k, u = np.asarray(self.stiffness), np.asarray(self.slip)
        return self.k_inf * q + np.minimum(q[..., None], u) @ k

    def dissipation(self, q):
        q = np.asarray(q, float)
        k, u = np.asarray(self.stiffness), np.asarray(self.slip)
        return np.maximum(q[..., None] - u, 0.0) @ (4 * k * u)

    def frequency(self, q):
        return np.sqrt(self.alpha(q) / np.asarray(q, float)) / (2 * np.pi)

    def damping(self, q):
        q = np.asarray(q, float)
        return self.dissipation(q) / (2 * np.pi * q * self.alpha(q))


def fit_jenkins(q, alpha, slip=None, n_elements=JENKINS_ELEMENTS):
    r"""Fit a :class:`JenkinsSeries` with slip amplitudes ``slip`` (default
    ``n_elements`` log-spaced from the last level whose secant stiffness is that of
    the first level, to :data:`LINEAR_RTOL`, to the last level) to a backbone: the backbone
    is linear in :math:`(k_\infty, k_i)`, fitted by non-negative least squares of the
    relative error. Returns ``(series, relative error per level)``."""
    from scipy.optimize import nnls
    q, alpha = np.asarray(q, float), np.asarray(alpha, float)
    if slip is None:
        soft = np.flatnonzero(alpha / q < (1 - LINEAR_RTOL) * alpha[0] / q[0])
        start = q[max(soft[0] - 1, 0)] if soft.size else q[0]
        slip = np.logspace(np.log10(start), np.log10(q[-1]), n_elements + 1)[:-1]
    slip = np.asarray(slip, float)
    A = np.column_stack([q, np.minimum(q[:, None], slip)]) / alpha[:, None]
    x, _ = nnls(A, np.ones(len(q)), maxiter=50 * A.shape[1])
    series = JenkinsSeries(float(x[0]), tuple(x[1:].tolist()), tuple(slip.tolist()))
    return series, series.alpha(q) / alpha - 1


def _rom_units(res) -> dict:
    """Units of the model's quantities in its unit system (:mod:`qsma.units`)."""
    from ..units import quantity_unit
    unit = lambda q: quantity_unit(q, res.units, res.model.dim)
    return {"system": res.units.name, "q": unit("modal_amplitude"),
            "alpha": unit("modal_force"), "F_S": unit("modal_force"),
            "K_T": f"{res.units.time}^-2", "phi_max": unit("modal_amplitude"),
            "dissipation": unit("energy")}


def rom_dict(res, fit: IwanFit) -> dict:
    """The content of rom.json for a :class:`qsma.analysis.result.QSMAResult` and its fit."""
    from ..output.files import json_safe
    m = fit.model
    q, alpha = np.asarray(res.q, float), np.asarray(res.alpha, float)
    keep = np.isfinite(q) & np.isfinite(alpha) & (q > 0) & (alpha > 0)   # as fit_iwan
    q, alpha = q[keep], alpha[keep]
    level = lambda v: np.asarray(v)[keep]
    series, jerr = fit_jenkins(q, alpha)
    return json_safe({
        "schema_version": ROM_SCHEMA_VERSION,
        "kind": "modal_iwan4",
        "reference": "Segalman, J. Appl. Mech. 72 (2005) 752-760",
        "model": res.model_info["name"],
        "mode": {"index": res.mode_index, "omega0": res.omega0, "f0_hz": res.f0_hz,
                 "phi_tip": res.phi_tip},
        "units": _rom_units(res),
        "iwan": {**m.element.as_dict(), "k_inf": m.k_inf},
        "fit": {"success": fit.success, "message": fit.message,
                "objective": "least squares of (alpha_fit - alpha) / alpha over the levels",
                "max_relative_error": fit.max_error, "rms_relative_error": fit.rms_error,
                "nfev": fit.nfev},
        "jenkins": {"k_inf": series.k_inf, "stiffness": series.stiffness,
                    "slip_displacement": series.slip,
                    "slip_force": (np.asarray(series.stiffness) * series.slip),
                    "max_relative_error": float(np.max(np.abs(jerr))),
                    "objective": "non-negative least squares of (alpha_fit - alpha) / "
                                 "alpha, slip displacements fixed (log spaced)"},
        "levels": {"level": np.flatnonzero(keep), "q": q, "alpha": alpha,
                   "tip": level(res.tip),
                   "alpha_fit": m.alpha(q), "fit_error": m.alpha(q) / alpha - 1,
                   "f_hz": level(res.f_hz), "zeta": level(res.zeta),
                   "dissipation": level(res.dissipation),
                   "f_hz_rom": m.frequency(q), "zeta_rom": m.damping(q),
                   "dissipation_rom": m.element.dissipation(q),
                   "alpha_jenkins": series.alpha(q), "fit_error_jenkins": jerr,
                   "zeta_jenkins": series.damping(q)},
    })


def export_rom(res, path) -> IwanFit:
    """Fit the modal Iwan model to the backbone of ``res`` and write ``path``
    (rom.json); returns the fit."""
    from ..output.files import atomic_write
    fit = fit_iwan(res.q, res.alpha, res.omega0)
    atomic_write(path, json.dumps(rom_dict(res, fit), indent=1) + "\n")
    return fit


def read_rom(path) -> ModalIwan:
    """The modal Iwan model of a rom.json."""
    with open(path) as f:
        data = json.load(f)
    p = data["iwan"]
    return ModalIwan(data["mode"]["omega0"], Iwan4(p["F_S"], p["K_T"], p["chi"], p["beta"]))


__all__ = ["Iwan4", "ModalIwan", "IwanFit", "JenkinsSeries", "fit_iwan", "fit_jenkins",
           "export_rom", "read_rom", "rom_dict"]
