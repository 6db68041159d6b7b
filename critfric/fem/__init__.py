"""Finite elements: element descriptions, elasticity assembly, loads, the contact basis and the
discrete static problem."""

from .assembly import assemble_elasticity, assemble_mass, assemble_stiffness, lame
from .contact import ContactSystem, contact_system
from .elements import ELEMENTS, get_element
from .loads import body_force_load, traction_load
from .mesh import Mesh
from .static import StaticProblem, build

__all__ = ["ELEMENTS", "ContactSystem", "Mesh", "StaticProblem", "assemble_elasticity", "assemble_mass",
           "assemble_stiffness", "body_force_load", "build",
           "contact_system", "get_element", "lame", "traction_load"]
