"""The contact state of a case ([contact] rules, or the static Coulomb solution) for (3.2)."""

from __future__ import annotations

import numpy as np

from ..case.schema import Case
from ..errors import CaseError
from ..fem.contact import FREE, SLIP, STUCK, ContactSystem
from ..fem.static import case_problem
from .coulomb import solve as coulomb_solve
from .eigen import ContactState

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
