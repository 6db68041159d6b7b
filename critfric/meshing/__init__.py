"""Meshing: polygons and shapes, gmsh-built meshes, user gmsh files, inline meshes, Mesh."""

from .geometry import Polygon, parallelogram, polygon, rectangle, validate
from .gmshfile import check_file, file_mesh
from .mesh import build_mesh, inline_mesh

__all__ = ["Polygon", "build_mesh", "check_file", "file_mesh", "inline_mesh",
           "parallelogram", "polygon", "rectangle", "validate"]
