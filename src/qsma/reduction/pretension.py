r"""Locking the bolts after the preload (docs/theory.md section 11).

The reduced model of the preload carries, besides 'preload' (pressures and the
pretensions ``N0``), one unit-tension pattern per bolt and the bolt elongations as
functionals, ``ell = E_d d + E_a a`` (``a`` with the bolt factors ``dN``). After the
preload the bolts are locked: ``dN = k (ell - ell_pre)``. With ``E_N`` the
elongations' own columns, ``H = (I - k E_N)^-1 k`` and ``W_N`` the bolts' welded
force columns, eliminating ``dN`` gives a contact problem of the same form

.. math:: K' = K + W_N H E_d, \quad
          W'_{pre} = W_{pre} - W_N H E_d d_{pre}, \quad
          W'_p = W_p + W_N H E_{a,p},

and every functional ``f = f_d d + f_a a + f_N dN`` is transformed the same way.
``K'`` is symmetric by reciprocity (``W_N = -E_d^T``, Betti); the asymmetry left by
round-off is checked. At the preload state (``d = d_pre``, ``alpha = 0``) the
locked model gives the preload's forces exactly.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import AnalysisError

#: Relative asymmetry of ``W_N H E_d`` accepted (reciprocity holds to round-off).
RECIPROCITY_RTOL = 1e-8


@dataclass(frozen=True, eq=False)
class LockedModel:
    """A reduced model with its bolts locked at their preload length; the attributes
    not listed are those of ``base``.

    Attributes
    ----------
    base : the reduced model with the bolt patterns and elongation functionals
    bolts : the bolts (their patterns are columns of ``base``)
    d_pre : preload relative displacement
    K, W, patterns, functionals : the locked problem (bolt patterns eliminated)
    """

    base: object
    bolts: tuple
    d_pre: np.ndarray
    K: np.ndarray
    W: np.ndarray
    patterns: tuple
    functionals: dict
    H: np.ndarray
    E_d: np.ndarray
    E_a: np.ndarray

    def __getattr__(self, name):
        if name.startswith("__"):
            raise AttributeError(name)
        return getattr(self.base, name)

    @property
    def n_pairs(self):
        return self.K.shape[0] // self.base.dim

    def bolt_increment(self, d, a) -> np.ndarray:
        """``dN = H (E_d (d - d_pre) + E_a a)`` (the effective load factors ``a``)."""
        d = np.asarray(d, float).ravel()
        return self.H @ (self.E_d @ (d - self.d_pre) + self.E_a @ np.asarray(a, float))

    def base_factors(self, d, a) -> np.ndarray:
        """Load factors of ``base``: ``a`` with the bolt increments inserted."""
        out = np.zeros(len(self.base.patterns))
        keep = [self.base.patterns.index(p) for p in self.patterns]
        out[keep] = a
        out[_bolt_index(self.base, self.bolts)] = self.bolt_increment(d, a)
        return out

    def bolt_forces(self, d, a) -> np.ndarray:
        """Bolt tensions ``N0 + dN``."""
        return np.array([b.pretension for b in self.bolts]) + self.bolt_increment(d, a)

    def welded_contact_force(self, a) -> np.ndarray:
        return (self.W @ np.asarray(a, dtype=float)).reshape(-1, self.base.dim)

    def interface_displacements(self, d, a):
        return self.base.interface_displacements(d, self.base_factors(d, a))

    def recover(self, d, a):
        return self.base.recover(d, self.base_factors(d, a))

    def tied_forces(self, d, a):
        """The tied interfaces' forces (:meth:`MultiReducedModel.tied_forces`) with the
        locked bolts' forces among the load factors."""
        return self.base.tied_forces(d, self.base_factors(d, a))

    def evaluate(self, name, d, a) -> float:
        c_d, c_a = self.functionals[name]
        return float(c_d @ np.asarray(d).ravel() + c_a @ np.asarray(a, dtype=float))

    def add_pattern(self, name, *loads) -> "LockedModel":
        """One more load pattern (a full load per body of ``base``), bolts locked."""
        return lock(self.base.add_pattern(name, *loads), self.bolts, self.d_pre)

    def with_functionals(self, definitions: dict) -> "LockedModel":
        return lock(self.base.with_functionals(definitions), self.bolts, self.d_pre)


def _bolt_index(base, bolts):
    return [base.patterns.index(b.pattern) for b in bolts]


def lock(base, bolts, d_pre) -> LockedModel:
    """The :class:`LockedModel` of ``base`` (module docstring)."""
    idx = _bolt_index(base, bolts)
    keep = [j for j in range(len(base.patterns)) if j not in idx]
    pre = base.patterns.index("preload")
    E = [base.functionals[b.pattern] for b in bolts]
    E_d = np.array([e[0] for e in E])
    E_full = np.array([e[1] for e in E])
    k = np.array([b.stiffness for b in bolts])
    H = np.linalg.solve(np.eye(len(bolts)) - k[:, None] * E_full[:, idx], np.diag(k))
    d_pre = np.asarray(d_pre, float).ravel()
    E_a = E_full[:, keep]
    E_a[:, keep.index(pre)] = 0.0            # preload factor is 1 before and after
    W_N = base.W[:, idx]
    update = W_N @ H @ E_d
    scale = max(np.abs(base.K).max(initial=0.0), np.abs(update).max(initial=0.0))
    asym = np.abs(update - update.T).max(initial=0.0)      # no contact point: nothing
    if asym > RECIPROCITY_RTOL * scale:
        raise AnalysisError(f"the locked bolts' stiffness is not symmetric (max asymmetry "
                            f"{asym:.3e} against {scale:.3e}): reciprocity failed, the bolt "
                            f"patterns and elongations do not match")
    K = base.K + 0.5 * (update + update.T)
    W = base.W[:, keep] + W_N @ H @ E_a
    W[:, keep.index(pre)] -= W_N @ H @ (E_d @ d_pre)
    funcs = {}
    for name, (c_d, c_a) in base.functionals.items():
        c_N = c_a[idx]
        new_a = c_a[keep] + c_N @ H @ E_a
        new_a[keep.index(pre)] -= c_N @ H @ (E_d @ d_pre)
        funcs[name] = (c_d + c_N @ H @ E_d, new_a)
    return LockedModel(base, tuple(bolts), d_pre, K, W,
                       tuple(base.patterns[j] for j in keep), funcs, H, E_d, E_a)
