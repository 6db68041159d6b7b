"""The contact boundary: Dirichlet and contact nodes, the outward normal, the n/t DOF basis.

:func:`contact_system` turns a mesh and its two material-independent stiffness parts into a
:class:`ContactSystem`: the stiffness restricted to the free DOFs (Dirichlet DOFs removed),
written in a basis where each contact node has a normal and a tangential DOF. Changing the
Poisson ratio then costs one linear combination ``lam * K_lam + G * K_G``, no re-assembly.
The same type holds a 3D system (:mod:`.contact3d`): there each contact node has a normal, a
slip (s) and a third (e = n x s) DOF.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import cached_property

import numpy as np
import scipy.sparse as sp

from ..errors import CaseError
from .arrays import ranges
from .mesh import Mesh

FREE, STUCK, SLIP = 0, 1, 2  # contact status of a node (I_f, I_s, I_c)
STRAIGHT_TOL = 1e-9  # relative distance to the line allowed on a straight Gamma_C


@dataclass(frozen=True)
class ContactSystem:
    """Stiffness parts on the free DOFs, with contact DOFs in the (n, t) basis.

    free    : (m,) global DOF indices (dim * node + component) that are not Dirichlet.
    nodes   : (p,) contact node indices, sorted along the tangent t (3D: along t1, then t2).
    normal, tangent : outward unit normal n of Gamma_C and t = (-n2, n1) (3D: t1, the
              direction of slip angle 0, :func:`.contact3d.plane_axes`).
    cn, ct  : (p,) positions, within the free DOFs, of the normal and tangential DOF of each
              contact node (3D: the DOF along the node's slip direction s).
    K_lam, K_G : (m, m) CSR parts, K = lam * K_lam + G * K_G; or K_lam the whole K at the
              Lame parameters ``lame``, and K_G None (a system for one Poisson ratio: any
              (lam, G) proportional to ``lame``, i.e. any E).
    fixed   : (d,) global DOF indices of the Dirichlet nodes (xy components).
    D_lam, D_G : (m, d) CSR parts of the coupling of the free DOFs (rows, n/t basis) to the
              Dirichlet DOFs (columns): prescribed values u_D add -K_FD u_D to the load.
    ce      : 3D only: (p,) positions of the DOF along e = n x s of each contact node.
    slip    : 3D only: (p, 3) unit slip directions s in the contact plane.
    """

    mesh: Mesh
    free: np.ndarray
    nodes: np.ndarray
    normal: np.ndarray
    tangent: np.ndarray
    cn: np.ndarray
    ct: np.ndarray
    K_lam: sp.csr_matrix
    K_G: sp.csr_matrix
    fixed: np.ndarray | None = None
    D_lam: sp.csr_matrix | None = None
    D_G: sp.csr_matrix | None = None
    ce: np.ndarray | None = None
    slip: np.ndarray | None = None
    lame: tuple[float, float] | None = None  # (lam, G) of K_lam where K_G is None

    @property
    def dim(self) -> int:
        """2 or 3, the mesh's dimension."""
        return self.mesh.dim

    @property
    def frames(self) -> np.ndarray:
        """(p, dim, dim): the contact basis of each node as rows, (n, t) or (n, s, e)."""
        if self.slip is None:
            return np.broadcast_to(np.stack([self.normal, self.tangent]), (len(self.nodes), 2, 2))
        return contact_frames(self.normal, self.slip)

    @property
    def n_dofs(self) -> int:
        return len(self.free)

    @property
    def contact_dofs(self) -> np.ndarray:
        """The contact DOFs in the order of the Schur complement onto them: cn, ct (3D: then
        ce)."""
        return np.concatenate([self.cn, self.ct] + ([self.ce] if self.ce is not None else []))

    @property
    def n_contact(self) -> int:
        return len(self.nodes)

    def stiffness(self, lam: float, G: float, *, keep_zeros: bool = False) -> sp.csr_matrix:
        """lam K_lam + G K_G; parts of one sparsity (as assembled) combine entry by entry.
        ``keep_zeros``: keep that sparsity's zero entries (a pattern known in advance)."""
        A, B = self.K_lam, self.K_G
        if B is None:  # assembled at one Poisson ratio: any E by a scale
            scale = self._scale(lam, G)
            K = A.copy() if scale == 1.0 else A * scale
            if not keep_zeros:
                K.eliminate_zeros()
            return K
        if (A.shape == B.shape and A.nnz == B.nnz and A.has_sorted_indices
                and B.has_sorted_indices and np.array_equal(A.indptr, B.indptr)
                and np.array_equal(A.indices, B.indices)):
            K = sp.csr_matrix((lam * A.data + G * B.data, A.indices.copy(), A.indptr.copy()),
                              shape=A.shape)
            K.has_sorted_indices = True
            # without the pattern's zero entries, as the sparse sum gives it: the same
            # factorization bit for bit (kept zeros moved the Newton check of the inclined
            # body's branch by 2e-10 on SuperLU)
            if not keep_zeros:
                K.eliminate_zeros()
            return K
        return (lam * A + G * B).tocsr()

    def restrict(self, A: sp.spmatrix) -> sp.csr_matrix:
        """A matrix over all dim * n_nodes xy(z) DOFs (a mass matrix, say) -> its free-DOF
        block in the contact basis, as the stiffness parts are."""
        if self.dim == 3:
            Q = frame_rotation(self.mesh.n_nodes, self.nodes, self.frames)
        else:
            Q = rotation(self.mesh.n_nodes, self.nodes, self.normal, self.tangent)
        return (Q.T @ sp.csr_matrix(A) @ Q).tocsr()[self.free][:, self.free].tocsr()

    def coupling(self, lam: float, G: float) -> sp.csr_matrix:
        """K_FD (m, d): free rows (n/t basis) x Dirichlet columns (xy)."""
        if self.D_G is None:
            scale = self._scale(lam, G)
            return self.D_lam.tocsr(copy=True) if scale == 1.0 else (self.D_lam * scale).tocsr()
        return (lam * self.D_lam + G * self.D_G).tocsr()

    def _scale(self, lam: float, G: float) -> float:
        """s with (lam, G) = s ``lame`` (the same Poisson ratio, any E); ValueError if none."""
        lam0, G0 = self.lame
        scale = 1.0 if (lam, G) == (lam0, G0) else G / G0
        if not math.isclose(lam, scale * lam0, rel_tol=1e-12, abs_tol=1e-300):
            raise ValueError(f"this contact system was assembled at (lam, G) = {self.lame}, "
                             f"for one Poisson ratio; not at {(lam, G)}")
        return scale

    def from_xy(self, full: np.ndarray) -> np.ndarray:
        """Nodal vector(s) (..., dim * n_nodes) in xy(z) -> free-DOF vector(s) in the contact
        basis."""
        u = np.array(full, dtype=float).reshape(np.shape(full)[:-1]
                                                + (self.mesh.n_nodes, self.dim))
        if self.dim == 3:
            u[..., self.nodes, :] = np.einsum("pba,...pa->...pb", self.frames,
                                              u[..., self.nodes, :])
            return u.reshape(np.shape(full))[..., self.free]
        c = u[..., self.nodes, :].copy()
        u[..., self.nodes, 0], u[..., self.nodes, 1] = c @ self.normal, c @ self.tangent
        return u.reshape(np.shape(full))[..., self.free]

    def to_xy(self, u_free: np.ndarray) -> np.ndarray:
        """Free-DOF vector(s) in the contact basis -> nodal displacements (..., n_nodes, dim)."""
        u_free = np.asarray(u_free)
        d = self.dim
        full = np.zeros(u_free.shape[:-1] + (d * self.mesh.n_nodes,), dtype=u_free.dtype)
        full[..., self.free] = u_free
        u = full.reshape(u_free.shape[:-1] + (self.mesh.n_nodes, d))
        if d == 3:
            u[..., self.nodes, :] = np.einsum("pba,...pb->...pa", self.frames,
                                              u[..., self.nodes, :])
            return u
        un, ut = u[..., self.nodes, 0].copy(), u[..., self.nodes, 1].copy()
        u[..., self.nodes, :] = (un[..., None] * self.normal + ut[..., None] * self.tangent)
        return u


def contact_geometry(mesh: Mesh, contact: list[str], dirichlet_nodes: np.ndarray,
                     *, source: str = "") -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Contact nodes (sorted along t), the outward normal n and the tangent t of Gamma_C."""
    facets = np.concatenate([mesh.edges[name] for name in contact])
    on_line = np.unique(facets)
    pts = mesh.points[on_line]
    start = pts[np.argmax(np.linalg.norm(pts - pts[0], axis=1))]  # an end of the run
    far = pts[np.argmax(np.linalg.norm(pts - start, axis=1))]  # the other end
    length = np.linalg.norm(far - start)
    if length == 0.0:
        raise CaseError("the contact edges have zero length", file=source, key="boundary.contact")
    direction = (far - start) / length
    normal = np.array([direction[1], -direction[0]])
    offset = (pts - start) @ normal
    if np.max(np.abs(offset)) > STRAIGHT_TOL * length:
        raise CaseError(
            f"edges {contact} are not one straight segment (a node is "
            f"{np.max(np.abs(offset)):.3g} off the line); allowed: collinear edges only",
            file=source, key="boundary.contact")
    # Orient n outwards: cells with an edge on Gamma_C lie on the inner side.
    on = np.zeros(mesh.n_nodes, dtype=bool)
    on[on_line] = True
    touching = on[mesh.cells[:, :mesh.fe.n_vertices]].sum(axis=1) >= 2
    side = (mesh.points[mesh.cells[touching]].mean(axis=1) - start) @ normal
    if touching.sum() == 0 or not (np.all(side > 0) or np.all(side < 0)):
        raise CaseError(f"edges {contact} are not on the boundary of the body (cells on both "
                        "sides)", file=source, key="boundary.contact")
    if side[0] > 0:
        normal = -normal
    tangent = np.array([-normal[1], normal[0]])
    nodes = np.setdiff1d(on_line, dirichlet_nodes)
    if len(nodes) == 0:
        raise CaseError("the contact boundary has no node that is not also on a Dirichlet "
                        "edge; allowed: a contact edge with at least one free node",
                        file=source, key="boundary.contact")
    nodes = nodes[np.argsort(mesh.points[nodes] @ tangent, kind="stable")]
    return nodes, normal, tangent


def rotation(n_nodes: int, nodes: np.ndarray, normal, tangent) -> sp.csr_matrix:
    """Q with u_xy = Q u_nt: identity except a [n t] block at each contact node."""
    dofs = np.arange(2 * n_nodes)
    keep = np.ones(2 * n_nodes, dtype=bool)
    keep[2 * nodes] = keep[2 * nodes + 1] = False
    rows = [dofs[keep]]
    cols = [dofs[keep]]
    vals = [np.ones(keep.sum())]
    for a in range(2):          # xy component
        for b in range(2):      # n (0) or t (1) component
            rows.append(2 * nodes + a)
            cols.append(2 * nodes + b)
            vals.append(np.full(len(nodes), (normal, tangent)[b][a]))
    return sp.coo_matrix((np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))),
                         shape=(2 * n_nodes, 2 * n_nodes)).tocsr()


def contact_frames(normal: np.ndarray, slip: np.ndarray) -> np.ndarray:
    """(p, 3, 3): the rows n, s_i, e_i = n x s_i of each contact node (a rotation, det +1)."""
    n = np.broadcast_to(normal, np.shape(slip))
    return np.stack([n, slip, np.cross(n, slip)], axis=1)


def frame_rotation(n_nodes: int, nodes: np.ndarray, frames: np.ndarray) -> sp.csr_matrix:
    """Q with u_xyz = Q u_local over dim * n_nodes DOFs: the identity, except at each contact
    node i the block whose column b is its basis vector ``frames[i, b]``."""
    p, d = len(nodes), frames.shape[1]
    keep = np.ones(d * n_nodes, dtype=bool)
    keep[(d * np.asarray(nodes)[:, None] + np.arange(d)).ravel()] = False
    base = d * np.asarray(nodes)[:, None, None]
    rows = np.broadcast_to(base + np.arange(d)[:, None], (p, d, d))  # [i, a, b]: xyz a
    cols = np.broadcast_to(base + np.arange(d)[None, :], (p, d, d))  # basis vector b
    vals = np.swapaxes(frames, 1, 2)
    dofs = np.flatnonzero(keep)
    return sp.coo_matrix((np.concatenate([np.ones(len(dofs)), vals.ravel()]),
                          (np.concatenate([dofs, rows.ravel()]),
                           np.concatenate([dofs, cols.ravel()]))),
                         shape=(d * n_nodes, d * n_nodes)).tocsr()


def rotated_free(mats: list, layout: Layout) -> list:
    """(A_FF, A_FD) (:func:`_split_free`) of Q^T A Q (Q: :func:`rotation` of the ``layout``'s
    contact nodes) for each matrix A of ``mats`` (one sparsity; ValueError otherwise), without
    forming Q: the free rows and columns are taken first,
    then the two rows, then the two columns, of each contact node are combined in place by
    the same two-term sums as the sparse products (the same numbers; exact zeros stay
    stored). The matrices must hold full 2 x 2 node blocks, as an assembled stiffness does;
    they are left as they are."""
    mats = summed_alike(mats, "rotated_free")  # sorted: columns 2j, 2j + 1 of a block adjacent
    nodes, position = layout.nodes, layout.position
    r = position[2 * nodes]  # the rows 2i (and 2i + 1 = r + 1) of the free DOFs
    if np.any(r < 0) or np.any(position[2 * nodes + 1] != r + 1):
        raise RuntimeError("internal: a contact node has a Dirichlet DOF")
    split = _split_free(mats, layout.fixed)  # new arrays: combined in place below
    # R[a, b]: xy component a of n (b = 0), t (b = 1)
    R = np.column_stack([layout.normal, layout.tangent])
    ff = split[0][0]
    contact = np.zeros(ff.shape[1], dtype=bool)
    contact[r] = True
    col0 = np.flatnonzero(contact[ff.indices])  # entries of the columns 2j of the contact nodes
    rows = []
    for A in split[0]:  # the same rows of A_FF and A_FD: rows 2i, 2i + 1
        length = A.indptr[r + 1] - A.indptr[r]
        if np.any(A.indptr[r + 2] - A.indptr[r + 1] != length):
            raise RuntimeError("internal: the stiffness is not made of full 2 x 2 node blocks")
        row0 = ranges(A.indptr[r], length)  # entries of the rows 2i of the contact nodes
        rows.append((row0, row0 + np.repeat(length, length)))
    if np.any(ff.indices[col0 + 1] != ff.indices[col0] + 1):
        raise RuntimeError("internal: the stiffness is not made of full 2 x 2 node blocks")
    for FF, FD in split:
        for A, (e0, e1) in zip((FF, FD), rows):
            _combine(A.data, e0, e1, R)  # rows 2i, 2i + 1
        _combine(FF.data, col0, col0 + 1, R)  # then columns 2j, 2j + 1 (none is Dirichlet)
    return split


def summed_alike(mats: list, what: str, *, copy: bool = False) -> list:
    """The matrices as CSR with sorted, summed entries (copies with ``copy``, else only where
    one is not so already); ValueError naming ``what`` unless they share one sparsity."""
    out = []
    for A in mats:
        A = sp.csr_matrix(A, copy=copy)
        if not A.has_canonical_format:
            A = A if copy else A.copy()
            A.sum_duplicates()
        out.append(A)
    ip, col = out[0].indptr, out[0].indices
    if any(not (np.array_equal(A.indptr, ip) and np.array_equal(A.indices, col))
           for A in out[1:]):
        raise ValueError(f"{what}: the matrices must have the same sparsity")
    return out


def _combine(data: np.ndarray, e0: np.ndarray, e1: np.ndarray, R: np.ndarray) -> None:
    """(data[e0], data[e1]) <- R^T (data[e0], data[e1]): xy components -> n, t."""
    x0, x1 = data[e0], data[e1]
    data[e0] = R[0, 0] * x0 + R[1, 0] * x1
    data[e1] = R[0, 1] * x0 + R[1, 1] * x1


def _split_free(mats: list, fixed: np.ndarray) -> list:
    """(A_FF, A_FD) of each matrix A of ``mats`` (one sparsity, sorted CSR): its free rows
    (``fixed``: mask of the Dirichlet DOFs) with its free columns, and with its Dirichlet
    columns, renumbered in order. The Dirichlet rows and columns hold few entries: they are
    found by index and dropped in one pass."""
    ip, col = mats[0].indptr, mats[0].indices
    free, itype = ~fixed, col.dtype
    m, d = int(free.sum()), int(fixed.sum())
    in_fixed_col = np.flatnonzero(fixed[col])
    fixed_rows = np.flatnonzero(fixed)
    dropped = np.union1d(in_fixed_col, ranges(ip[fixed_rows], np.diff(ip)[fixed_rows]))
    row_of = lambda entries: np.searchsorted(ip, entries, side="right") - 1
    keep = np.ones(len(col), dtype=bool)
    keep[dropped] = False
    count = np.diff(ip) - np.bincount(row_of(dropped), minlength=len(ip) - 1)
    ff_ptr = np.concatenate([[0], np.cumsum(count[free])]).astype(itype)
    ff_col = (np.cumsum(free) - 1).astype(itype)[col[keep]]
    fd = in_fixed_col[free[row_of(in_fixed_col)]]  # Dirichlet columns of the free rows
    fd_ptr = np.concatenate([[0], np.cumsum(np.bincount(np.cumsum(free)[row_of(fd)] - 1,
                                                        minlength=m))]).astype(itype)
    fd_col = (np.cumsum(fixed) - 1).astype(itype)[col[fd]]
    return [(sp.csr_matrix((A.data[keep], ff_col, ff_ptr), shape=(m, m)),
             sp.csr_matrix((A.data[fd], fd_col, fd_ptr), shape=(m, d))) for A in mats]


@dataclass(frozen=True)
class Layout:
    """Which DOFs a contact system keeps, known from the mesh alone (before any assembly).

    nodes, normal, tangent, slip : as in :class:`ContactSystem`.
    fixed : (dim * n_nodes,) mask of the Dirichlet DOFs.
    dim   : 2 or 3.
    """

    nodes: np.ndarray
    normal: np.ndarray
    tangent: np.ndarray
    fixed: np.ndarray
    dim: int = 2
    slip: np.ndarray | None = None

    @cached_property
    def free(self) -> np.ndarray:
        """(m,) global indices of the free DOFs."""
        return np.flatnonzero(~self.fixed)

    @cached_property
    def position(self) -> np.ndarray:
        """(dim * n_nodes,) position of each DOF within the free DOFs (-1: Dirichlet)."""
        position = np.full(len(self.fixed), -1, dtype=np.int64)
        position[self.free] = np.arange(len(self.free))
        return position

    @property
    def contact_dofs(self) -> np.ndarray:
        """Positions within the free DOFs of the normal, then the tangential, contact DOFs
        (``cn`` then ``ct`` of the contact system; then ``ce`` in 3D)."""
        return np.concatenate([self.position[self.dim * self.nodes + k] for k in range(self.dim)])


def contact_layout(mesh: Mesh, *, contact: list[str], dirichlet: list[str],
                   source: str = "") -> Layout:
    """Classify the boundary nodes of a mesh: contact nodes and basis, Dirichlet DOFs."""
    for key, names in (("boundary.contact", contact), ("boundary.dirichlet", dirichlet)):
        missing = [n for n in names if n not in mesh.edges or len(mesh.edges[n]) == 0]
        if missing:
            raise CaseError(f"edge {missing[0]!r} has no mesh facet; known edges: "
                            + ", ".join(sorted(mesh.edges)), file=source, key=key)
    dirichlet_nodes = mesh.edge_nodes(dirichlet)
    nodes, normal, tangent = contact_geometry(mesh, contact, dirichlet_nodes, source=source)
    fixed = np.zeros(2 * mesh.n_nodes, dtype=bool)
    fixed[2 * dirichlet_nodes] = fixed[2 * dirichlet_nodes + 1] = True
    return Layout(nodes, normal, tangent, fixed)


def contact_system(mesh: Mesh, K_lam: sp.spmatrix, K_G: sp.spmatrix | None, *,
                   contact: list[str], dirichlet: list[str], source: str = "",
                   layout: Layout | None = None,
                   lame: tuple[float, float] | None = None) -> ContactSystem:
    """Classify the boundary nodes (or take ``layout``, :func:`contact_layout` of the same
    arguments) and restrict the stiffness parts to the free DOFs. K_G None: K_lam is the
    whole stiffness at the Lame parameters ``lame`` (:func:`.assembly.assemble_stiffness`)."""
    if (K_G is None) == (lame is None):
        raise ValueError("contact_system: give K_G, or the Lame parameters of a whole K_lam "
                         "(exactly one of the two)")
    if layout is None:
        layout = contact_layout(mesh, contact=contact, dirichlet=dirichlet, source=source)
    nodes, normal, tangent, fixed = layout.nodes, layout.normal, layout.tangent, layout.fixed
    position = layout.position
    # K_FF and K_FD (Q is the identity on the Dirichlet DOFs) of Q^T K Q, for each part
    mats = [K_lam] if K_G is None else [K_lam, K_G]
    try:  # assembled parts share one sparsity: one pass of index work for both
        split = rotated_free(mats, layout)
    except ValueError:
        split = [ff_fd for A in mats for ff_fd in rotated_free([A], layout)]
    (ff_lam, fd_lam), (ff_G, fd_G) = split[0], (split[1] if len(split) > 1 else (None, None))
    return ContactSystem(mesh=mesh, free=layout.free, nodes=nodes, normal=normal,
                         tangent=tangent, cn=position[2 * nodes], ct=position[2 * nodes + 1],
                         K_lam=ff_lam, K_G=ff_G, fixed=np.flatnonzero(fixed), D_lam=fd_lam,
                         D_G=fd_G, lame=lame)


def check_held(mesh, dirichlet_nodes: np.ndarray, *, source: str | None = None) -> None:
    """Refuse a mesh with a connected piece that touches no Dirichlet node: it would float
    (a rigid motion left, a singular stiffness matrix)."""
    import scipy.sparse as sp
    from scipy.sparse.csgraph import connected_components

    cells = np.asarray(mesh.cells)
    n = len(mesh.points)
    star = sp.coo_matrix((np.ones(cells.size), (np.repeat(cells[:, 0], cells.shape[1]),
                                                cells.ravel())), shape=(n, n))
    count, labels = connected_components(star, directed=False)
    held = np.zeros(count, dtype=bool)
    held[labels[np.asarray(dirichlet_nodes, dtype=np.int64)]] = True
    if not held.all():
        node = int(np.flatnonzero(~held[labels])[0])
        raise CaseError(f"{np.count_nonzero(~held)} of the {count} connected pieces of the body "
                        f"touch no Dirichlet edge (e.g. node {node} at "
                        f"{mesh.points[node].tolist()}), so they float freely; allowed: every "
                        "piece clamped on some edge", file=source, key="boundary.dirichlet")

