"""Finite elements: element descriptions, elasticity assembly, loads, the contact basis and the
discrete static problem."""

from .assembly import assemble_elasticity, lame
from .contact import ContactSystem, contact_system
from .elements import get_element
from .loads import body_force_load, traction_load
from .static import StaticProblem, build, case_problem

__all__ = ["ContactSystem", "StaticProblem", "assemble_elasticity", "body_force_load", "build",
           "case_problem", "contact_system", "get_element", "lame", "traction_load"]
