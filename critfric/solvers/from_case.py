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
COMPLIANCE_RANGE = (1e-250, 1e250)  # |nodal force| / E: displacements stay normal floats
RULE_TOL = 1e-9  # [contact] intervals are widened by RULE_TOL * length of Gamma_C


CODES = {"free": FREE, "stuck": STUCK, "slip": SLIP}


def arc_length(system: ContactSystem, contact: list[str]) -> np.ndarray:
    """(p,) position s of each contact node along t, from the first end of Gamma_C."""
    ends = np.unique(np.concatenate([system.mesh.edges[name].ravel() for name in contact]))
    along = system.mesh.points @ system.tangent
    return along[system.nodes] - along[ends].min()


def _inside(case: Case, s: np.ndarray, rule: dict, dim: int) -> np.ndarray:
    """The contact nodes at positions s ((p,) 2D, (p, 2) 3D) that a [contact] rule covers."""
    lo, hi = np.asarray(rule["from"], dtype=float), np.asarray(rule["to"], dtype=float)
    if lo.ndim != dim - 2:
        raise CaseError(f"got from = {rule['from']}; allowed: "
                        + ("numbers (arc length along t)" if dim == 2 else
                           "pairs [s1, s2] (positions along t1, t2 in the contact plane)"),
                        file=case.source, key="contact.rules")
    tol = RULE_TOL * max(float(np.ptp(s)), 1.0)
    inside = (s >= lo - tol) & (s <= hi + tol)
    return inside if dim == 2 else inside.all(axis=1)


def plane_positions(points: np.ndarray, nodes: np.ndarray, normal: np.ndarray,
                    t1: np.ndarray) -> np.ndarray:
    """(p, 2) positions (s1, s2) of 3D contact nodes along t1 and t2 = n x t1, from the
    smallest of each over Gamma_C (the 3D counterpart of :func:`arc_length`)."""
    s = np.asarray(points, dtype=float)[nodes] @ np.column_stack([t1, np.cross(normal, t1)])
    return s - s.min(axis=0)


def contact_positions(case: Case, system: ContactSystem) -> np.ndarray:
    """The positions the rules of [contact] refer to: arc length (2D), (s1, s2) (3D)."""
    if system.dim == 2:
        return arc_length(system, case.boundary["contact"])
    return plane_positions(system.mesh.points, system.nodes, system.normal, system.tangent)


def slip_angles(case: Case, nodes: np.ndarray, positions: np.ndarray) -> np.ndarray:
    """(p,) slip angle of each 3D contact node: [solve] slip_angle, or that of the last rule
    of [contact] with a slip_angle that covers the node."""
    angle = np.full(len(nodes), float(case.solve["slip_angle"]))
    for rule in case.contact["rules"] or []:  # a handful of rules, vectorized over nodes
        if rule["slip_angle"] is not None:
            angle[_inside(case, positions, rule, 3)] = rule["slip_angle"]
    return angle


def check_dimension(case: Case, dim: int, what: str = "") -> None:
    """Refuse the 3D-only keys on a 2D body and, with ``what``, a 2D-only command on a 3D one."""
    if dim == 3 and what:
        raise CaseError(f"{what} is for 2D bodies; allowed here: critfric solve and sweep on "
                        "3D bodies", file=case.source, key="geometry.shape")
    if dim == 2:
        rules = case.contact["rules"] or []
        if case.solve["slip_angle"] != 0 or any(r["slip_angle"] is not None for r in rules):
            raise CaseError("applies to 3D bodies; allowed in 2D: [solve] gamma (+1 or -1) "
                            "for the slip sign", file=case.source, key="solve.slip_angle")
        if case.solve["direction_law"] != "rate":
            raise CaseError("applies to 3D bodies (the law of the slip direction)",
                            file=case.source, key="solve.direction_law")


def contact_state(case: Case, system: ContactSystem) -> ContactState | None:
    """The contact state of ``[contact]`` (None: every node slipping with [solve] gamma)."""
    rules, c = case.contact["rules"] or [], case.contact
    if c["source"] == "coulomb" and system.dim == 3:
        raise CaseError("the static problem (2.8) is solved for 2D bodies only; allowed for "
                        "3D bodies: source = 'rules'", file=case.source, key="contact.source")
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
    s = contact_positions(case, system)
    status = np.full(system.n_contact, CODES[c["default"]], dtype=np.int8)
    gamma = np.full(system.n_contact, float(case.solve["gamma"]))
    for rule in rules:  # loop over rules (a handful), vectorized over nodes
        inside = _inside(case, s, rule, system.dim)
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
    _check_compliance(force, case.material["E"], case.source, key)
    reference = load["reference"]
    if isinstance(reference, list) and len(reference) != system.n_contact:
        raise CaseError(f"got {len(reference)} values for {system.n_contact} contact nodes; "
                        "allowed: one value, or one per contact node (sorted along t)",
                        file=case.source, key="load.reference")
    friction = load["friction"] if friction is None else friction
    return build(system, lam, G, load_xy=force, reference=reference, friction=friction,
                 fixed_xy=_dirichlet_values(case, mesh, load["displacement"], key))


def _check_compliance(force: np.ndarray, E: float, source: str, key: str) -> None:
    """Refuse forces whose displacements (about |nodal force| / E: 1 / E for a unit force)
    would overflow or fall below the normal floats: the static problem is linear in the
    forces and in 1 / E, and float arithmetic holds that only within COMPLIANCE_RANGE."""
    top = float(np.abs(force).max(initial=0.0))
    ratio = top / E if top else 0.0
    if top and not COMPLIANCE_RANGE[0] <= ratio <= COMPLIANCE_RANGE[1]:
        size = f"{ratio:.3g}" if ratio else "below 1e-308"
        raise CaseError(f"the forces against E = {E:g} give displacements of about {size} "
                        "(largest nodal force / E), beyond the floats; allowed: "
                        f"forces and E with a ratio in [{COMPLIANCE_RANGE[0]:g}, "
                        f"{COMPLIANCE_RANGE[1]:g}]", file=source, key=key)


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
