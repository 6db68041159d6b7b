"""The discrete static Coulomb problem (2.8): loads, Dirichlet data, u^r and contact rules.

:class:`StaticProblem` holds everything the nodal form needs (METHOD.md), on the free DOFs in
the n/t basis of :mod:`critfric.fem.contact`::

    K U = rhs + B_n X + B_t Y,   rhs = L - K_FD u_D,

with L the consistent nodal load (tractions, body force, point forces), u_D the prescribed
Dirichlet values and U^r the reference tangential displacement at the contact nodes.
:func:`build` makes it from arrays; :func:`critfric.solvers.from_case.case_problem` from the
``[load]`` section of a case.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

from .contact import ContactSystem


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


# ----------------------------------------------------------------------------- contact rules


# ----------------------------------------------------------------------------- facets


