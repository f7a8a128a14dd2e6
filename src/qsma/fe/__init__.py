"""Finite element assembly (scikit-fem): stiffness, consistent mass, pressure loads,
element formulations (plane strain / stress, quadratic cells, incompatible modes)."""
from .assembly import (assemble_body, AssembledBody, skfem_mesh, pressure_load,
                       body_load, stress_at_nodes, stiffness_matrix, mass_matrix)
from .formulation import (Formulation, MixedFormulation, resolve_formulation,
                          resolve_formulations)

__all__ = ["assemble_body", "AssembledBody", "skfem_mesh", "pressure_load", "body_load",
           "stress_at_nodes", "stiffness_matrix", "mass_matrix", "Formulation",
           "MixedFormulation", "resolve_formulation", "resolve_formulations"]
