"""The static Coulomb problem of a case, meshed and assembled on demand."""

from __future__ import annotations

from ..case.schema import Case
from ..fem.static import StaticProblem
from ..solve import Prepared, prepare
from ..solvers.from_case import case_problem, check_dimension


def static_problem(case: Case, prepared: Prepared | None = None, *,
                   friction: float | None = None) -> StaticProblem:
    """The static problem (2.8) of a case's ``[load]``; ``prepared`` reuses a mesh and its
    assembly (:func:`critfric.solve.prepare`), ``friction`` overrides ``[load] friction``."""
    prepared = prepared if prepared is not None else prepare(case)
    check_dimension(case, prepared.mesh.dim, "the static problem (solutions, verify)")
    return case_problem(case, prepared.system, friction=friction)
