"""What a case gives the solvers: the static problem of its [load] section (2.8) and the
contact state of its [contact] section for the eigenproblem (3.2)."""

from __future__ import annotations

import numpy as np

from ..case.schema import Case
from ..errors import CaseError
from ..fem.assembly import lame
from ..fem.contact import FREE, SLIP, STUCK, ContactSystem
from ..fem.loads import body_force_load, traction_load
from ..fem.mesh import Mesh
from ..fem.static import StaticProblem, build
from .coulomb import solve as coulomb_solve
from .eigen import ContactState

NODE_TOL = 1e-9  # a point force `at` [x, y] matches a node within NODE_TOL * mesh diameter
RULE_TOL = 1e-9  # [contact] intervals are widened by RULE_TOL * length of Gamma_C


CODES = {"free": FREE, "stuck": STUCK, "slip": SLIP}


def arc_length(system: ContactSystem, contact: list[str]) -> np.ndarray:
    """(p,) position s of each contact node along t, from the first end of Gamma_C."""
    ends = np.unique(np.concatenate([system.mesh.edges[name].ravel() for name in contact]))
    along = system.mesh.points @ system.tangent
    return along[system.nodes] - along[ends].min()


def contact_state(case: Case, system: ContactSystem) -> ContactState | None:
    """The contact state of ``[contact]`` (None: every node slipping with [solve] gamma)."""
    rules, c = case.contact["rules"] or [], case.contact
    if c["source"] == "coulomb":
        problem = case_problem(case, system)
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



LOAD_KEYS = ("traction", "body_force", "points", "displacement")  # what makes a load


def case_problem(case: Case, system: ContactSystem, *, friction: float | None = None,
                 load: dict | None = None, key: str = "load") -> StaticProblem:
    """The static problem of a case's ``[load]`` on the mesh and contact basis of ``system``
    (``friction`` overrides ``[load] friction``; ``load``: another load, with the keys
    LOAD_KEYS, in place of [load]'s, with U^r = 0; ``key``: its name in messages)."""
    mesh = system.mesh
    load = case.load if load is None else {**dict.fromkeys(LOAD_KEYS), **load,
                                           "reference": 0.0, "friction": None}
    lam, G = lame(case.material["E"], case.material["nu"])
    force = np.zeros(2 * mesh.n_nodes)
    for name, vector in (load["traction"] or {}).items():
        if name not in mesh.edges:
            raise CaseError(f"got edge {name!r}, which the mesh does not have; allowed: "
                            + ", ".join(sorted(mesh.edges)), file=case.source,
                            key=f"{key}.traction")
        force += traction_load(mesh, name, vector)
    if load["body_force"] is not None:
        force += body_force_load(mesh, load["body_force"])
    fixed = set(system.fixed.tolist())
    for i, point in enumerate(load["points"] or []):
        node = point["node"] if "node" in point else _node_at(mesh, point["at"], case.source,
                                                               f"{key}.points.{i}")
        if 2 * node in fixed:
            raise CaseError(f"node {node} is on a Dirichlet edge, where a force has no effect; "
                            "allowed: a node that is not clamped", file=case.source,
                            key=f"{key}.points.{i}")
        force[2 * node: 2 * node + 2] += point["force"]
    reference = load["reference"]
    if isinstance(reference, list) and len(reference) != system.n_contact:
        raise CaseError(f"got {len(reference)} values for {system.n_contact} contact nodes; "
                        "allowed: one value, or one per contact node (sorted along t)",
                        file=case.source, key="load.reference")
    friction = load["friction"] if friction is None else friction
    return build(system, lam, G, load_xy=force, reference=reference, friction=friction,
                 fixed_xy=_dirichlet_values(case, mesh, load["displacement"], key))


def _node_at(mesh: Mesh, at, source: str, key: str) -> int:
    d = np.linalg.norm(mesh.points - np.asarray(at), axis=1)
    node = int(np.argmin(d))
    if d[node] > NODE_TOL * np.ptp(mesh.points, axis=0).max():
        raise CaseError(f"no mesh node at {at} (nearest: {mesh.points[node].tolist()}, at "
                        f"distance {d[node]:.3g}); allowed: the coordinates of a node, such as a "
                        "vertex of the geometry", file=source, key=key)
    return node


def _dirichlet_values(case: Case, mesh: Mesh, fields: dict | None, key: str) -> np.ndarray:
    """Prescribed displacements (2 n_nodes,): the affine field of each Dirichlet edge, else 0."""
    u = np.zeros((mesh.n_nodes, 2))
    given = np.zeros(mesh.n_nodes, dtype=bool)
    fields = fields or {}
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
                            "agree at shared nodes", file=case.source, key=f"{key}.displacement")
        u[nodes], given[nodes] = value, True
    return u.ravel()
