"""The sliding state's small motions as a pencil in the friction coefficient.

Notation of METHOD.md, n/t basis of :mod:`critfric.fem.contact`. About the steady sliding
state (every slipping contact node slides with sign gamma_i, signed friction coefficient f:
f > 0 the state's own direction, f < 0 the opposite one), small motions phi e^{st} solve

    (s^2 M + K) phi = B_n X + f B_t Gamma X,   Phi_n = 0 on slipping nodes,

stuck nodes clamped, free nodes traction-free, exactly as in the static eigenproblem (3.2),
which is the case s = 0. Eliminating the slipping normal DOFs (their rows give X) and the
stuck DOFs leaves, on the kept DOFs r, with kappa = -s^2,

    L(f, kappa) phi = 0,   L = (K_rr - kappa M_rr) - f G (K_nr - kappa M_nr),

G = E Gamma putting gamma_i X_i on node i's tangential row. At f = 0 this is the symmetric
problem K_rr phi = kappa M_rr phi (kappa = omega^2 > 0: the constrained free vibrations); at
kappa = 0 it is (3.2) with alpha = f (divergence: the static critical coefficients).
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import numpy as np
import scipy.sparse as sp

from ..errors import SolverError
from ..fem.contact import FREE, SLIP, STUCK, ContactSystem
from ..solvers.eigen import ContactState


@dataclass
class SlidingPencil:
    """The sparse blocks of L(f, kappa) for one contact state."""

    system: ContactSystem
    state: ContactState
    kept: np.ndarray  # free-DOF positions of the kept DOFs r
    slip: np.ndarray  # contact indices of the slipping nodes
    Krr: sp.csr_matrix
    Mrr: sp.csr_matrix
    Knr: sp.csr_matrix  # slipping normal rows, kept columns
    Mnr: sp.csr_matrix
    G: sp.csr_matrix  # (n_r, p0): gamma_i on the tangential row of slipping node i

    @property
    def size(self) -> int:
        return len(self.kept)

    @cached_property
    def GKnr(self) -> sp.csr_matrix:
        """G K_nr: the slipping normal rows of K on the tangential rows (-dA/df)."""
        return (self.G @ self.Knr).tocsr()

    @cached_property
    def GMnr(self) -> sp.csr_matrix:
        return (self.G @ self.Mnr).tocsr()

    def A(self, f: float) -> sp.csr_matrix:
        """L = A(f) - kappa B(f)."""
        return (self.Krr - f * self.GKnr).tocsr()

    def B(self, f: float) -> sp.csr_matrix:
        """-dL/dkappa."""
        return (self.Mrr - f * self.GMnr).tocsr()

    def L(self, f: float, kappa: float) -> sp.csr_matrix:
        return (self.A(f) - kappa * self.B(f)).tocsr()

    def L_f(self, kappa: float) -> sp.csr_matrix:
        """dL/df."""
        return (kappa * self.GMnr - self.GKnr).tocsr()

    def L_kappa_f(self) -> sp.csr_matrix:
        """d2L/(dkappa df)."""
        return self.GMnr

    def apply_A(self, f: float, v: np.ndarray, transpose: bool = False) -> np.ndarray:
        """A(f) v (A(f)^T v) from the blocks, no sum matrix formed (K_rr is symmetric)."""
        return self.Krr @ v - f * ((self.GKnr.T if transpose else self.GKnr) @ v)

    def apply_B(self, f: float, v: np.ndarray, transpose: bool = False) -> np.ndarray:
        """B(f) v (B(f)^T v) from the blocks (M_rr is symmetric)."""
        return self.Mrr @ v - f * ((self.GMnr.T if transpose else self.GMnr) @ v)

    def apply_L(self, f: float, kappa: float, v: np.ndarray) -> np.ndarray:
        """L(f, kappa) v from the blocks."""
        return self.apply_A(f, v) - kappa * self.apply_B(f, v)

    def free_vector(self, v: np.ndarray) -> np.ndarray:
        """Kept-DOF vector(s) -> free-DOF vector(s) (zeros on the eliminated DOFs)."""
        v = np.asarray(v)
        out = np.zeros(v.shape[:-1] + (self.system.n_dofs,), dtype=v.dtype)
        out[..., self.kept] = v
        return out

    def shape_xy(self, v: np.ndarray) -> np.ndarray:
        """A kept-DOF mode as nodal displacements (n_nodes, 2), max |phi| = 1, its largest
        component positive (a real mode) or with a real largest component (a complex one)."""
        u = self.system.to_xy(self.free_vector(v))
        flat = u.reshape(-1)
        j = int(np.argmax(np.abs(flat)))
        return u * (np.abs(flat[j]) / flat[j]) / np.abs(flat[j]) if flat[j] != 0 else u


def kept_dofs(system: ContactSystem, state: ContactState) -> tuple[np.ndarray, np.ndarray]:
    """The slipping contact nodes of a state and the free-DOF positions of its kept DOFs."""
    if len(state.status) != system.n_contact:
        raise SolverError("the contact state does not match the number of contact nodes")
    slip = np.flatnonzero(state.status == SLIP)
    if len(slip) == 0:
        raise SolverError("no slipping contact node: the sliding state is empty")
    stuck = state.status == STUCK
    elim = np.concatenate([system.cn[slip], system.cn[stuck], system.ct[stuck]])
    keep = np.ones(system.n_dofs, dtype=bool)
    keep[elim] = False
    return slip, np.flatnonzero(keep)


def sliding_pencil(system: ContactSystem, K: sp.spmatrix, M: sp.spmatrix,
                   state: ContactState, Krr: sp.csr_matrix | None = None) -> SlidingPencil:
    """The pencil of a contact state (stiffness K and mass M on the free DOFs, n/t basis;
    ``Krr``: K on the kept DOFs of :func:`kept_dofs`, if already taken)."""
    slip, kept = kept_dofs(system, state)
    position = np.full(system.n_dofs, -1)
    position[kept] = np.arange(len(kept))
    K, M = sp.csr_matrix(K), sp.csr_matrix(M)
    n_rows = system.cn[slip]
    G = sp.csr_matrix((state.gamma[slip].astype(float),
                       (position[system.ct[slip]], np.arange(len(slip)))),
                      shape=(len(kept), len(slip)))
    assert np.all(state.status[slip] != FREE)
    return SlidingPencil(system=system, state=state, kept=kept, slip=slip,
                         Krr=K[kept][:, kept].tocsr() if Krr is None else Krr,
                         Mrr=M[kept][:, kept].tocsr(),
                         Knr=K[n_rows][:, kept].tocsr(), Mnr=M[n_rows][:, kept].tocsr(), G=G)
