"""Old import paths that keep working for one release: a module whose contents moved
forwards each name to its new home, with a :class:`DeprecationWarning` that names it.

:func:`forward` turns a module into such a re-export: ``from qsma.linalg import
schur_complement`` keeps giving the same object as ``from qsma.reduction.schur import
schur_complement``. The warning goes to code outside qsma only; qsma's own modules are
held to the new paths by ``tests/test_architecture.py``, which parses every import.
"""
from __future__ import annotations

import importlib
import sys
import warnings

__all__ = ["forward"]


def forward(old: str, *new: str, names: dict | None = None) -> None:
    """Make module ``old`` forward the names it no longer defines.

    Parameters
    ----------
    old : str
        The module's name (its ``__name__``); the module may still define names of
        its own, which are not forwarded.
    *new : str
        Modules searched, in order, for a name ``old`` does not define.
    names : dict, optional
        ``name -> module`` for names that moved to a module of their own (searched
        first).
    """
    module = sys.modules[old]
    names = dict(names or {})
    own = module.__dict__

    def __getattr__(name):
        if name.startswith("__"):        # import machinery asking (__path__, __spec__...)
            raise AttributeError(f"module {old!r} has no attribute {name!r}")
        target = names.get(name)
        places = [target] if target is not None else list(new)
        for place in places:
            found = importlib.import_module(place)
            if hasattr(found, name):
                if not _from_qsma(sys._getframe(1)):
                    warnings.warn(f"{old}.{name} moved to {place}.{name}; import it from "
                                  f"there (the old path goes in the next release)",
                                  DeprecationWarning, stacklevel=2)
                return getattr(found, name)
        raise AttributeError(f"module {old!r} has no attribute {name!r}")

    def __dir__():
        public = set(own)
        for place in list(new) + list(names.values()):
            public |= set(dir(importlib.import_module(place)))
        return sorted(public)

    own["__getattr__"] = __getattr__
    own["__dir__"] = __dir__


def _from_qsma(frame) -> bool:
    """Whether ``frame`` runs code of the qsma package."""
    name = frame.f_globals.get("__name__", "")
    return name == "qsma" or name.startswith("qsma.")
