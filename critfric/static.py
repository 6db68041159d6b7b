"""The static Coulomb problem (2.8) of a case: loads, Dirichlet data, u^r and contact rules.

:class:`StaticProblem` holds everything the nodal form needs (METHOD.md), on the free DOFs in
the n/t basis of :mod:`critfric.contact`::

    K U = rhs + B_n X + B_t Y,   rhs = L - K_FD u_D,

with L the consistent nodal load (tractions, body force, point forces), u_D the prescribed
Dirichlet values and U^r the reference tangential displacement at the contact nodes.
:func:`static_problem` builds it from the ``[load]`` section of a case; :func:`build` from
arrays. :func:`contact_state` turns ``[contact]`` into the :class:`ContactState` of (3.2).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

from .assembly import body_force_load, lame, traction_load
from .case import Case
from .contact import FREE, SLIP, STUCK, ContactSystem
from .eigen import ContactState
from .elements import facet_quadrature, facet_shape
from .errors import CaseError
from .mesh import Mesh

NODE_TOL = 1e-9  # a point force `at` [x, y] matches a node within NODE_TOL * mesh diameter
RULE_TOL = 1e-9  # [contact] intervals are widened by RULE_TOL * length of Gamma_C
CODES = {"free": FREE, "stuck": STUCK, "slip": SLIP}


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


def static_problem(case: Case, prepared=None, *, friction: float | None = None) -> StaticProblem:
    """The static problem of a case's ``[load]`` (``friction`` overrides ``[load] friction``)."""
    from .solve import prepare  # solve imports this module

    prepared = prepared or prepare(case)
    system, mesh, load = prepared.system, prepared.mesh, case.load
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
def arc_length(system: ContactSystem, contact: list[str]) -> np.ndarray:
    """(p,) position s of each contact node along t, from the first end of Gamma_C."""
    ends = np.unique(np.concatenate([system.mesh.edges[name].ravel() for name in contact]))
    along = system.mesh.points @ system.tangent
    return along[system.nodes] - along[ends].min()


def contact_state(case: Case, system: ContactSystem, *, prepared=None) -> ContactState | None:
    """The contact state of ``[contact]`` (None: every node slipping with [solve] gamma)."""
    rules, c = case.contact["rules"] or [], case.contact
    if c["source"] == "coulomb":
        from .coulomb import solve as coulomb_solve

        problem = static_problem(case, prepared)
        if problem.friction is None:
            raise CaseError("[contact] source = 'coulomb' needs [load] friction; allowed: a "
                            "number >= 0", file=case.source, key="load.friction")
        state = coulomb_solve(problem).state
        if state.n_slip == 0:
            raise CaseError("the static solution of [load] has no slipping contact node, so the "
                            "eigenproblem (3.2) is empty; allowed: a load that makes nodes slip",
                            file=case.source, key="contact.source")
        return state
    if not rules and c["default"] == "slip":
        return None
    s = arc_length(system, case.boundary["contact"])
    tol = RULE_TOL * max(np.ptp(s), 1.0)
    status = np.full(system.n_contact, CODES[c["default"]], dtype=np.int8)
    gamma = np.full(system.n_contact, float(case.solve["gamma"]))
    for rule in rules:  # loop over rules (a handful), vectorized over nodes
        inside = (s >= rule["from"] - tol) & (s <= rule["to"] + tol)
        status[inside] = CODES[rule["status"]]
        gamma[inside] = rule["gamma"] if rule["status"] == "slip" else gamma[inside]
    if not np.any(status == SLIP):
        raise CaseError("no contact node is slipping, so the eigenproblem (3.2) is empty; "
                        f"allowed: rules leaving at least one node with status 'slip' (nodes at "
                        f"s = {np.round(s, 6).tolist()[:8]}...)", file=case.source,
                        key="contact.rules")
    return ContactState(status, gamma)


# ----------------------------------------------------------------------------- facets
_LOCAL_EDGES = {"P1": ([0, 1, 2], [1, 2, 0], None), "P2": ([0, 1, 2], [1, 2, 0], [3, 4, 5]),
                "Q1": ([0, 1, 2, 3], [1, 2, 3, 0], None),
                "Q2": ([0, 1, 2, 3], [1, 2, 3, 0], [4, 5, 6, 7])}


def boundary_facets(mesh: Mesh) -> tuple[np.ndarray, np.ndarray]:
    """Every boundary facet (k, 2) or (k, 3) (end, end[, mid]) and its outward unit normal."""
    a, b, mid = _LOCAL_EDGES[mesh.element]
    cells = np.asarray(mesh.cells)
    facets = np.stack([cells[:, a], cells[:, b]] + ([cells[:, mid]] if mid else []), axis=-1)
    facets = facets.reshape(-1, facets.shape[-1])
    keys = np.sort(facets[:, :2], axis=1)
    _, inverse, count = np.unique(keys, axis=0, return_inverse=True, return_counts=True)
    facets = facets[count[inverse.ravel()] == 1]
    d = mesh.points[facets[:, 1]] - mesh.points[facets[:, 0]]  # cells are counterclockwise
    normal = np.column_stack([d[:, 1], -d[:, 0]]) / np.linalg.norm(d, axis=1)[:, None]
    return facets, normal


def facets_in(facets: np.ndarray, mesh: Mesh, names) -> np.ndarray:
    """Mask of the facets that belong to the edge groups ``names``."""
    groups = np.concatenate([np.sort(mesh.edges[n][:, :2], axis=1) for n in names])
    keys = np.sort(facets[:, :2], axis=1) @ np.array([mesh.n_nodes, 1])
    return np.isin(keys, groups @ np.array([mesh.n_nodes, 1]))


def facet_load(mesh: Mesh, facets: np.ndarray, traction: np.ndarray) -> np.ndarray:
    """Consistent nodal load (2 n_nodes,) of a traction that is constant on each facet."""
    order = facets.shape[1] - 1
    s, w = facet_quadrature(order)
    values, derivs = facet_shape(s, order)
    X = mesh.points[facets]  # (k, n_fnodes, 2)
    jac = np.linalg.norm(np.einsum("fai,aq->fqi", X, derivs), axis=-1)
    weights = np.einsum("fq,q,aq->fa", jac, w, values)  # int N_a ds on each facet
    traction = np.broadcast_to(np.asarray(traction, dtype=float), (len(facets), 2))
    out = np.zeros((mesh.n_nodes, 2))
    for k in range(2):  # x and y components
        out[:, k] = np.bincount(facets.ravel(), (weights * traction[:, k:k + 1]).ravel(),
                                minlength=mesh.n_nodes)
    return out.ravel()
