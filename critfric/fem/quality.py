"""The shape of the cells along Gamma_C: a warning where skewed cells there can give
eigenvalues of their own (mesh-scale contact modes, whatever the mesh size)."""

from __future__ import annotations

import numpy as np

#: a cell touching Gamma_C with a corner above this (degrees) can carry mesh-scale contact
#: modes whose real eigenvalues fall below the body's coefficient at any mesh size (measured
#: on skewed cells along Gamma_C, Q1 and P1: the lowest spurious value 2.52 at 125, 2.02 at
#: 135, 1.77 at 145 degrees, where the L-shaped body's coefficient is 2.33)
SKEWED_ANGLE = 120.0


def skewed_contact_cells(mesh, nodes: np.ndarray) -> str | None:
    """A warning if a 2D cell with a vertex on Gamma_C (contact ``nodes``) has a corner
    above SKEWED_ANGLE, not counting the corners at the two ends of Gamma_C (the body's own
    corners there); None otherwise and in 3D."""
    if mesh.dim != 2 or len(nodes) < 3:
        return None
    cells = np.asarray(mesh.cells)[:, :mesh.fe.n_vertices]
    cells = cells[np.isin(cells, nodes).any(axis=1)]
    v = mesh.points[cells]
    a, b = np.roll(v, 1, axis=1) - v, np.roll(v, -1, axis=1) - v
    cos = np.einsum("ckx,ckx->ck", a, b) / (np.linalg.norm(a, axis=-1)
                                           * np.linalg.norm(b, axis=-1))
    angle = np.degrees(np.arccos(np.clip(cos, -1.0, 1.0)))
    angle[np.isin(cells, [nodes[0], nodes[-1]])] = 0.0
    worst = float(angle.max(initial=0.0))
    if worst <= SKEWED_ANGLE:
        return None
    return (f"cells along Gamma_C have corners of up to {worst:.0f} degrees (above "
            f"{SKEWED_ANGLE:.0f}): on skewed cells there, eigenvalues of mesh-scale modes can "
            "fall below the body's critical coefficient, at any mesh size; check the values on "
            "a mesh with cells near right angles along Gamma_C (another size or element, or a "
            "structured layer of cells there)")
