"""The friction coefficients a model may give (:func:`check_mu`), shared by the model
(its default ``mu``) and each interface (its own)."""
from __future__ import annotations

from ..errors import InputError

#: Largest friction coefficient taken: a pair slips only where its tangential force
#: exceeds this many times its normal force, that is, as it opens. Larger values (a
#: deck's 1e20 for "no slip") change no answer and cost the contact solve its digits
#: (the cone's test then subtracts numbers 1e20 apart).
MU_NO_SLIP = 1e4


def check_mu(mu, where=""):
    """Refuse a friction coefficient above :data:`MU_NO_SLIP`, with the fix."""
    if mu > MU_NO_SLIP:
        raise InputError(f"{where}friction coefficient mu = {mu:g} is above {MU_NO_SLIP:g}: "
                         f"for a joint that does not slip give mu = {MU_NO_SLIP:g} (a pair "
                         f"then slips only where its tangential force exceeds {MU_NO_SLIP:g} "
                         f"times its normal force, as it opens); larger values change no "
                         f"answer and only cost the contact solve its accuracy")
