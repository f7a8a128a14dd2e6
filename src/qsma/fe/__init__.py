"""Finite element assembly (scikit-fem): stiffness, consistent mass, pressure loads."""
from .assembly import (assemble_body, AssembledBody, skfem_mesh, pressure_load,
                       body_load, stress_at_nodes)

__all__ = ["assemble_body", "AssembledBody", "skfem_mesh", "pressure_load", "body_load",
           "stress_at_nodes"]
