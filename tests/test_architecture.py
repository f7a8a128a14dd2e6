"""The layout of the package: old import paths forward to the new ones."""
import importlib
import warnings

import pytest

#: module that moved -> (a name it held, the module that holds it now)
MOVED = {
    "qsma.linalg": ("schur_complement", "qsma.reduction.schur"),
    "qsma.multifrontal": ("front_structure", "qsma.reduction.schur.multifrontal"),
    "qsma.congruence": ("find_congruence", "qsma.reduction.congruence"),
    "qsma.condense": ("reduce_two_bodies", "qsma.reduction.two_bodies"),
    "qsma.rigid": ("free_motions", "qsma.reduction.rigid"),
    "qsma.pretension": ("lock", "qsma.reduction.pretension"),
    "qsma.multibody": ("reduce_model", "qsma.reduction.multibody"),
}


@pytest.mark.parametrize("old", sorted(MOVED))
def test_old_paths_forward_with_a_deprecation_warning(old):
    name, new = MOVED[old]
    module = importlib.import_module(old)
    with pytest.warns(DeprecationWarning, match=f"{old}.{name} moved to {new}.{name}"):
        found = getattr(module, name)
    assert found is getattr(importlib.import_module(new), name)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        with pytest.raises(AttributeError, match="no attribute 'no_such_name'"):
            getattr(module, "no_such_name")


def test_private_names_forward_too():
    """Code that reached into a moved module keeps working for one release."""
    with pytest.warns(DeprecationWarning):
        from qsma.linalg import _superlu_trailing_schur, symmetrised
    from qsma._infra.dense import symmetrised as new
    from qsma.reduction.schur.superlu_schur import _superlu_trailing_schur as new_private
    assert symmetrised is new and _superlu_trailing_schur is new_private
