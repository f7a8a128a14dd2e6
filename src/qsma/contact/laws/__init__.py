"""Interface laws: the contact of a pair besides rigid Coulomb friction.

Every law is a compliant layer in series with a rigid Coulomb slider
(:mod:`qsma.contact.laws.base`, docs/theory.md "Interface laws"); the solvers of
:mod:`qsma.contact` solve the slider (:mod:`qsma.contact.layer`). One module per law:

========================  ====================================================
normal                    ``hard`` (default), ``linear``, ``exponential``,
                          ``tabular``, ``rough`` (asperities of rough surfaces)
tangential                ``rigid`` (default), ``elastic`` (stick stiffness);
                          ``rough`` implies its own stick stiffness
========================  ====================================================

:func:`law_from_table` builds a law from the plain table of a TOML file or of
results.json (:meth:`InterfaceLaw.as_dict` is its inverse).
"""
from .base import NormalLaw, TangentialLaw
from .interface import InterfaceLaw
from .exponential import ExponentialPressure
from .hard import Hard
from .linear import LinearPressure
from .rough import RoughStick, RoughSurface
from .tabular import TabularPressure
from .tangential import ElasticStick, RigidStick
from .table import NORMAL_KEYS, TANGENTIAL_KEYS, law_from_table

__all__ = ["InterfaceLaw", "NormalLaw", "TangentialLaw", "Hard", "LinearPressure",
           "ExponentialPressure", "TabularPressure", "RoughSurface", "RoughStick",
           "RigidStick", "ElasticStick",
           "law_from_table", "NORMAL_KEYS", "TANGENTIAL_KEYS"]
