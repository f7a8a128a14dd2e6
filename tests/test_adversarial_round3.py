"""An adversarial user of the newer surfaces: several bodies and interfaces, parts and
instances, sweeps, fits and the folders of every command.

Each test is one way a wrong answer could be reported as success, a folder left
inconsistent, an internal error, or a bad input refused only after computing.
"""
from dataclasses import replace

import numpy as np
import pytest

import qsma
from qsma.cli import main
from qsma.errors import AnalysisError
from qsma.examples import stack_2d
from qsma.model import Pressure

STACK_LEVELS = qsma.Levels.log("tip", 1e-6, 1e-4, 3)


# ---- wrong answers reported as success --------------------------------------------

def test_a_stack_whose_second_interface_opens_is_refused():
    """The top plate's bolt pressure pulls (negative): the preload opens every pair of
    the second interface and the top plate vibrates alone. Refused as the two-body
    path refuses a preload that opens the whole interface."""
    model = stack_2d(1)
    top = model.bodies[2]
    pulled = replace(top, pressures=(Pressure("bolt", -top.pressures[0].p),))
    model = replace(model, bodies=model.bodies[:2] + (pulled,))
    with pytest.raises(AnalysisError, match="no pair of interface middle.upper / top.lower"):
        qsma.run(model, levels=STACK_LEVELS)
