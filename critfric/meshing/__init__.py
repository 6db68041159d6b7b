"""Meshing: polygons and shapes, gmsh-built meshes (2D bodies; 3D boxes and prisms), user gmsh
files, inline meshes, Mesh."""

from .cells3d import inline_solid
from .geometry import Polygon, parallelogram, polygon, rectangle, validate
from .gmshfile import check_file, file_mesh
from .mesh import build_mesh, inline_mesh
from .solid import build_solid, check_solid, is_solid, solid_mesh

__all__ = ["Polygon", "build_mesh", "build_solid", "check_file", "check_solid", "file_mesh",
           "inline_mesh", "inline_solid", "is_solid", "parallelogram", "polygon", "rectangle",
           "solid_mesh", "validate"]
