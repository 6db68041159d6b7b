"""The static Coulomb problem (2.8) of a case: loads, Dirichlet data, u^r and contact rules.

:class:`StaticProblem` holds everything the nodal form needs (METHOD.md), on the free DOFs in
the n/t basis of :mod:`critfric.contact`::

    K U = rhs + B_n X + B_t Y,   rhs = L - K_FD u_D,

with L the consistent nodal load (tractions, body force, point forces), u_D the prescribed
Dirichlet values and U^r the reference tangential displacement at the contact nodes.
:func:`case_problem` builds it from the ``[load]`` section of a case; :func:`build` from
arrays.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

from ..case.schema import Case
from ..errors import CaseError
from ..meshing.mesh import Mesh
from .assembly import lame
from .contact import ContactSystem
from .loads import body_force_load, traction_load

NODE_TOL = 1e-9  # a point force `at` [x, y] matches a node within NODE_TOL * mesh diameter


@dataclass
class StaticProblem:
    """The discrete static problem: K U = rhs + B_n X + B_t Y and (2.9)-(2.11) on Gamma_C.

    K, load, rhs : stiffness and loads on the free DOFs (n/t basis at contact nodes).
    dirichlet    : (d,) prescribed values at the Dirichlet DOFs ``system.fixed`` (xy).
    reference    : (p,) reference tangential displacement U^r at the contact nodes.
    """

    system: ContactSystem
    K: sp.csr_matrix
    load: np.ndarray
    rhs: np.ndarray
    dirichlet: np.ndarray
    reference: np.ndarray
    friction: float | None
    lam: float
    G: float

    def displacement(self, U: np.ndarray) -> np.ndarray:
        """Free-DOF vector (n/t) -> nodal displacements (n_nodes, 2) with the Dirichlet data."""
        u = self.system.to_xy(U)
        u.reshape(-1)[self.system.fixed] = self.dirichlet
        return u

    def equilibrium(self, U: np.ndarray, X: np.ndarray, Y: np.ndarray) -> float:
        """Relative residual |K U - rhs - B_n X - B_t Y|_inf of the equilibrium rows."""
        s = self.system
        KU = self.K @ U
        force = np.zeros_like(KU)
        force[s.cn], force[s.ct] = X, Y
        scale = max(np.abs(KU).max(), np.abs(self.rhs).max(), np.abs(force).max(), 1e-300)
        return float(np.abs(KU - self.rhs - force).max() / scale)


def build(system: ContactSystem, lam: float, G: float, *, load_xy=None, fixed_xy=None,
          reference=0.0, friction: float | None = None) -> StaticProblem:
    """A static problem from a nodal load (2 n_nodes,) and Dirichlet values (2 n_nodes,), xy."""
    n2 = 2 * system.mesh.n_nodes
    load_xy = np.zeros(n2) if load_xy is None else np.asarray(load_xy, dtype=float)
    fixed_xy = np.zeros(n2) if fixed_xy is None else np.asarray(fixed_xy, dtype=float)
    K = system.stiffness(lam, G)
    L = system.from_xy(load_xy)
    uD = fixed_xy[system.fixed]
    rhs = L - system.coupling(lam, G) @ uD if np.any(uD) else L.copy()
    ref = np.broadcast_to(np.asarray(reference, dtype=float), (system.n_contact,)).copy()
    return StaticProblem(system, K, L, rhs, uD, ref, friction, lam, G)


def case_problem(case: Case, system: ContactSystem, *,
                 friction: float | None = None) -> StaticProblem:
    """The static problem of a case's ``[load]`` on the mesh and contact basis of ``system``
    (``friction`` overrides ``[load] friction``)."""
    mesh, load = system.mesh, case.load
    lam, G = lame(case.material["E"], case.material["nu"])
    force = np.zeros(2 * mesh.n_nodes)
    for name, vector in (load["traction"] or {}).items():
        if name not in mesh.edges:
            raise CaseError(f"got edge {name!r}, which the mesh does not have; allowed: "
                            + ", ".join(sorted(mesh.edges)), file=case.source, key="load.traction")
        force += traction_load(mesh, name, vector)
    if load["body_force"] is not None:
        force += body_force_load(mesh, load["body_force"])
    fixed = set(system.fixed.tolist())
    for i, point in enumerate(load["points"] or []):
        node = point["node"] if "node" in point else _node_at(mesh, point["at"], case.source, i)
        if 2 * node in fixed:
            raise CaseError(f"node {node} is on a Dirichlet edge, where a force has no effect; "
                            "allowed: a node that is not clamped", file=case.source,
                            key=f"load.points.{i}")
        force[2 * node: 2 * node + 2] += point["force"]
    reference = load["reference"]
    if isinstance(reference, list) and len(reference) != system.n_contact:
        raise CaseError(f"got {len(reference)} values for {system.n_contact} contact nodes; "
                        "allowed: one value, or one per contact node (sorted along t)",
                        file=case.source, key="load.reference")
    friction = load["friction"] if friction is None else friction
    return build(system, lam, G, load_xy=force, reference=reference, friction=friction,
                 fixed_xy=_dirichlet_values(case, mesh))


def _node_at(mesh: Mesh, at, source: str, i: int) -> int:
    d = np.linalg.norm(mesh.points - np.asarray(at), axis=1)
    node = int(np.argmin(d))
    if d[node] > NODE_TOL * np.ptp(mesh.points, axis=0).max():
        raise CaseError(f"no mesh node at {at} (nearest: {mesh.points[node].tolist()}, at "
                        f"distance {d[node]:.3g}); allowed: the coordinates of a node, such as a "
                        "vertex of the geometry", file=source, key=f"load.points.{i}")
    return node


def _dirichlet_values(case: Case, mesh: Mesh) -> np.ndarray:
    """Prescribed displacements (2 n_nodes,): the affine field of each Dirichlet edge, else 0."""
    u = np.zeros((mesh.n_nodes, 2))
    given = np.zeros(mesh.n_nodes, dtype=bool)
    fields = case.load["displacement"] or {}
    for name in case.boundary["dirichlet"]:  # loop over edge names (a handful)
        nodes = mesh.edge_nodes([name])
        coef = np.asarray(fields.get(name, np.zeros((2, 3))))
        x = mesh.points[nodes]
        value = coef[:, 0] + x @ coef[:, 1:].T
        clash = given[nodes] & (np.abs(u[nodes] - value).max(axis=1)
                                > 1e-12 * max(np.abs(value).max(), np.abs(u).max(), 1e-300))
        if clash.any():
            raise CaseError(f"node {int(nodes[clash][0])} of Dirichlet edge {name!r} gets two "
                            "different displacements from two edges; allowed: fields that "
                            "agree at shared nodes", file=case.source, key="load.displacement")
        u[nodes], given[nodes] = value, True
    return u.ravel()


# ----------------------------------------------------------------------------- contact rules


# ----------------------------------------------------------------------------- facets


