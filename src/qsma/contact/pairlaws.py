"""The interface laws of every contact point of a run, as one record: which law each
point follows, its onset, the layer's deformation, stiffness and compliance at given
pressures (:class:`PairLaws`). The slider problem built from it is
:mod:`qsma.contact.layer`; the laws themselves are :mod:`qsma.contact.laws`."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import InputError

#: A nonlinear normal law is linearised at no less than this fraction of the mean
#: pressure: its tangent vanishes at the onset (the exponential law), and a layer that
#: soft would make ``K'`` ill-conditioned; the chord iteration takes the rest.
LOW_PRESSURE = 1e-2
#: The lowest floor of a secant linearisation (exact at the pressure it is taken at, so
#: the floor must lie below the pressures whose law matters: 1e-8 of the mean).
LOW_SECANT = 1e-8



@dataclass(frozen=True, eq=False)
class PairLaws:
    """The interface law of every contact point.

    Attributes
    ----------
    laws : distinct :class:`qsma.contact.laws.InterfaceLaw`
    index : (n_pairs,) int, the law of each contact point
    area : (n_pairs,) tributary area of each contact point (m^2; m per unit depth in 2D)
    dim : 2 or 3
    """

    laws: tuple
    index: np.ndarray
    area: np.ndarray
    dim: int

    def __post_init__(self):
        area = np.asarray(self.area, dtype=float)
        if area.shape != np.shape(self.index) or not np.all(area > 0):
            bad = int(np.count_nonzero(~(area > 0))) if area.shape == np.shape(self.index) \
                else area.shape
            raise InputError(f"interface law: every contact point needs a positive "
                             f"tributary area to turn pressures into forces, got {bad} "
                             f"without one")

    @property
    def n_pairs(self):
        return len(self.index)

    @property
    def rigid(self) -> bool:
        """Every law rigid: the slider is the interface (no layer)."""
        return all(law.rigid for law in self.laws)

    @property
    def linear(self) -> bool:
        """The layer is linear (no chord iteration)."""
        return all(law.normal.linear for law in self.laws)

    def _per_law(self, fn, out_shape=None):
        out = np.zeros(self.n_pairs if out_shape is None else out_shape)
        for j, law in enumerate(self.laws):
            rows = self.index == j
            if rows.any():
                out[rows] = fn(law, rows)
        return out

    def onset(self):
        """``h_0`` of each contact point (m)."""
        return self._per_law(lambda law, rows: law.normal.onset)

    def layer_deformation(self, P):
        """Normal deformation of the layer under pair forces ``P`` (N):
        ``h(P/A) - h_0`` (zero for hard laws and unloaded pairs, whose inverse is not
        evaluated)."""
        P = np.maximum(np.asarray(P, dtype=float), 0.0)

        def one(law, rows):
            out = np.zeros(int(rows.sum()))
            on = P[rows] > 0
            if not law.normal.hard and on.any():
                out[on] = (law.normal.overclosure(P[rows][on] / self.area[rows][on])
                           - law.normal.onset)
            return out
        return self._per_law(one)

    def pair_stiffness(self, h):
        """``A dp/dh`` of each pair at overclosure ``h`` (zero for hard laws)."""
        h = np.asarray(h, dtype=float)
        return self._per_law(lambda law, rows: 0.0 if law.normal.hard else
                             self.area[rows] * law.normal.stiffness(h[rows]))

    def pair_pressure(self, h):
        """Normal force ``A p(h)`` of each contact point at overclosure ``h`` (m); zero
        for hard laws (no pressure-overclosure function)."""
        h = np.asarray(h, dtype=float)
        return self._per_law(lambda law, rows: 0.0 if law.normal.hard else
                             self.area[rows] * law.normal.pressure(h[rows]))

    def scale_compliance(self):
        """``C`` with every pair at its law's own scale pressure (what the unit check
        compares with the structure: independent of any state)."""
        P = self._per_law(lambda law, rows: law.normal.scale_pressure() * self.area[rows])
        out = self.compliance(np.zeros(self.n_pairs))
        for j, law in enumerate(self.laws):
            rows = self.index == j
            if rows.any() and not law.normal.hard and not law.normal.linear:
                out[rows, -1] = 1.0 / (self.area[rows] * law.normal.tangent_at_pressure(
                    P[rows] / self.area[rows]))
        return out

    def graph_distance(self, P, h, k, where=None):
        """How far ``(h, P)`` lies from each pair's law, in force: the smaller of the
        pressure's miss ``|P - A p(h)|`` and the closure's ``k |h - h(P/A)|``, ``k`` the
        larger of a stiffness per pair (N/m; the layer's chord, finite and positive) and
        the law's own slope at ``h(P/A)``. The second
        measures a law with a vertical segment (CalculiX's exponential jumps at its
        clearance), where any pressure up to the jump belongs to the same closure."""
        P = np.maximum(np.asarray(P, dtype=float), 0.0)
        h = np.asarray(h, dtype=float)
        where = np.ones(len(P), bool) if where is None else np.asarray(where, bool)

        def one(law, rows):
            out = np.zeros(int(rows.sum()))
            sub = where[rows]
            if law.normal.hard or not sub.any():
                return out
            idx = np.flatnonzero(rows)[sub]
            A, p = self.area[idx], P[idx] / self.area[idx]
            force = np.abs(P[idx] - A * law.normal.pressure(h[idx]))
            h_p = law.normal.overclosure(p)
            # the stiffer of the chord and the law's own slope there: a closure miss
            # weighs at least what it costs in force on either (the slope alone vanishes
            # where a law starts with zero stiffness)
            slope = np.maximum(k[idx], A * law.normal.stiffness(h_p))
            off = np.abs(h[idx] - h_p)
            with np.errstate(invalid="ignore"):
                closure = np.where(P[idx] > 0, np.where(off > 0, slope * off, 0.0), np.inf)
            out[sub] = np.minimum(force, closure)
            return out
        return self._per_law(one)

    def linear_pairs(self):
        """Pairs whose normal law is linear (hard or a constant stiffness)."""
        return self._per_law(lambda law, rows: law.normal.linear).astype(bool)

    def plastic(self):
        """Pairs whose law deforms plastically when first loaded (its unloading is
        stiffer: :meth:`unloading_compliance`)."""
        return self._per_law(lambda law, rows: getattr(law.normal, "plastic",
                                                       False)).astype(bool)

    def unloading_compliance(self, P):
        """``1/(A k_u)`` with ``k_u`` the law's unloading stiffness from pair force ``P``
        (the loading tangent for laws without ``unloading_stiffness``)."""
        P = np.maximum(np.asarray(P, dtype=float), 0.0)

        def one(law, rows):
            p = P[rows] / self.area[rows]
            k = getattr(law.normal, "unloading_stiffness", law.normal.tangent_at_pressure)(p)
            return 1.0 / (self.area[rows] * k)
        with np.errstate(divide="ignore"):
            return self._per_law(one)

    def normal_slope(self, P):
        """``d(layer deformation)/dP`` per pair (m/N) at pair forces ``P``: the tangent
        compliance ``1/(A k_n)`` (zero for hard laws)."""
        P = np.maximum(np.asarray(P, dtype=float), 0.0)
        with np.errstate(divide="ignore"):         # a law without stiffness at p = 0
            return self._per_law(lambda law, rows: 0.0 if law.normal.hard else
                                 1.0 / (self.area[rows] * law.normal.tangent_at_pressure(
                                     P[rows] / self.area[rows])))

    def compliance(self, P, p_ref=None, secant=False, low=None):
        r"""``C`` of the layer linearised at pair forces ``P`` (N), (n_pairs, dim):
        ``1/(A k_t(p))`` tangential, ``1/(A k_n(p))`` normal with ``p = P/A``, zero where
        the law is rigid. A nonlinear normal law at a pair without pressure is
        linearised at no less than :data:`LOW_PRESSURE` times ``p_ref`` (the mean
        pressure of the loaded pairs, else the law's own scale): the tangent of a law at
        zero pressure may vanish, and a soft chord keeps the iteration contracting.
        ``secant``: the normal compliance is the secant from the onset,
        ``(h(p) - h_0) / (A p)``, instead of the tangent. ``low``: another floor than
        :data:`LOW_PRESSURE`."""
        P = np.maximum(np.asarray(P, dtype=float), 0.0)
        p = P / self.area
        loaded = p > 0
        if p_ref is None:
            p_ref = float(p[loaded].mean()) if loaded.any() else None
        out = np.zeros((self.n_pairs, self.dim))
        for j, law in enumerate(self.laws):
            rows = self.index == j
            if not rows.any():
                continue
            pj = p[rows]
            if not law.normal.hard:
                ref = p_ref if p_ref is not None else law.normal.scale_pressure()
                floor = LOW_PRESSURE if low is None else low
                at = pj if law.normal.linear else np.maximum(pj, floor * ref)
                if secant and not law.normal.linear:
                    out[rows, -1] = ((law.normal.overclosure(at) - law.normal.onset)
                                     / (self.area[rows] * at))
                else:
                    out[rows, -1] = 1.0 / (self.area[rows]
                                           * law.normal.tangent_at_pressure(at))
            if not law.tangential.rigid:
                # a stick stiffness that grows with the pressure (rough surfaces) is taken
                # at the same floor: an unloaded pair carries no shear either way
                ref = p_ref if p_ref is not None else law.normal.scale_pressure()
                at = np.maximum(pj, LOW_PRESSURE * ref) if ref else pj
                out[rows, :-1] = (1.0 / (self.area[rows]
                                         * law.tangential.stiffness(at)))[:, None]
        if not np.all(np.isfinite(out)):
            raise InputError("interface law: the layer has an infinite compliance (a "
                             "normal law whose stiffness vanishes at every pressure); give "
                             "a law that stiffens when pressed")
        return out
