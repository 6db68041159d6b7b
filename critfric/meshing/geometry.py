"""Polygonal domains with named edges.

A :class:`Polygon` is a simple polygon with counterclockwise vertices; edge ``i`` goes from
``vertices[i]`` to ``vertices[(i + 1) % nv]`` and is called ``edge_names[i]``. Several edges may
share a name: they form one boundary group. Consecutive collinear vertices are allowed, so one
straight side can be split into differently named parts (e.g. a contact zone on part of a side).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..case.checks import MAX_VERTICES
from ..errors import CaseError
from ..fem.mesh import shoelace

#: relative tolerance (times the bounding-box diagonal) for coincidence and collinearity tests
REL_TOL = 1e-10


@dataclass(frozen=True)
class Polygon:
    """A simple polygon: (nv, 2) counterclockwise ``vertices`` and one name per edge."""

    vertices: np.ndarray
    edge_names: tuple[str, ...]

    @property
    def n_vertices(self) -> int:
        return len(self.vertices)

    @property
    def area(self) -> float:
        return signed_area(self.vertices)

    @property
    def segments(self) -> np.ndarray:
        """(nv, 2, 2) edge end points: ``segments[i] = (vertices[i], vertices[i + 1])``."""
        return np.stack([self.vertices, np.roll(self.vertices, -1, axis=0)], axis=1)

    @property
    def group_names(self) -> tuple[str, ...]:
        """Distinct edge names, in order of first appearance."""
        return tuple(dict.fromkeys(self.edge_names))

    def edge_indices(self, names) -> np.ndarray:
        """Indices of the edges whose name is in ``names`` (a name or an iterable of names)."""
        names = {names} if isinstance(names, str) else set(names)
        return np.array([i for i, n in enumerate(self.edge_names) if n in names], dtype=np.int64)


def signed_area(vertices: np.ndarray) -> float:
    """Shoelace area, positive for counterclockwise vertices."""
    return float(shoelace(vertices))


def positive_number(value, key: str) -> float:
    """``value`` as a finite positive float, else :class:`CaseError` naming ``key``."""
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise CaseError(f"must be a number, got {value!r}", key=key) from None
    if not (math.isfinite(v) and v > 0):
        raise CaseError(f"must be a finite positive number, got {value!r}", key=key)
    return v


def rectangle(width: float, height: float) -> Polygon:
    """Rectangle [0, width] x [0, height]; edges "bottom", "right", "top", "left"."""
    w = positive_number(width, "geometry.width")
    h = positive_number(height, "geometry.height")
    vertices = np.array([[0.0, 0.0], [w, 0.0], [w, h], [0.0, h]])
    return Polygon(vertices, ("bottom", "right", "top", "left"))


def parallelogram(base: float, height: float, offset: float) -> Polygon:
    """Parallelogram (0,0), (L,0), (L+offset,H), (offset,H); edges named as for a rectangle."""
    b = positive_number(base, "geometry.base")
    h = positive_number(height, "geometry.height")
    try:
        o = float(offset)
    except (TypeError, ValueError):
        raise CaseError(f"must be a number, got {offset!r}", key="geometry.offset") from None
    if not math.isfinite(o):
        raise CaseError(f"must be finite, got {offset!r}", key="geometry.offset")
    vertices = np.array([[0.0, 0.0], [b, 0.0], [b + o, h], [o, h]])
    return Polygon(vertices, ("bottom", "right", "top", "left"))


def polygon(vertices, edge_names=None) -> Polygon:
    """Validated polygon from (nv, 2) vertices in either orientation.

    ``edge_names`` defaults to "e0", ..., "e{nv-1}". Clockwise input is reversed, and the names
    are permuted with it so that each name stays on the same geometric edge.
    """
    try:
        v = np.array(vertices, dtype=np.float64)
    except (TypeError, ValueError):
        raise CaseError("must be a list of [x, y] pairs of numbers",
                        key="geometry.vertices") from None
    if v.ndim != 2 or v.shape[1] != 2:
        raise CaseError(f"must be a list of [x, y] pairs, got shape {v.shape}",
                        key="geometry.vertices")
    n = len(v)
    names = tuple(f"e{i}" for i in range(n)) if edge_names is None else tuple(edge_names)
    poly = Polygon(v, names)
    validate(poly, require_ccw=False)
    if signed_area(v) < 0:
        # reversed edge j runs along original edge n-2-j (backwards)
        names = tuple(names[(n - 2 - j) % n] for j in range(n))
        poly = Polygon(v[::-1].copy(), names)
    return poly


def validate(poly: Polygon, *, require_ccw: bool = True) -> Polygon:
    """Return ``poly`` if it is a valid simple polygon with named edges, else raise
    :class:`CaseError`."""
    v = np.asarray(poly.vertices, dtype=np.float64)
    key = "geometry.vertices"
    if v.ndim != 2 or v.shape[1] != 2:
        raise CaseError(f"must be a list of [x, y] pairs, got shape {v.shape}", key=key)
    n = len(v)
    if n < 3:
        raise CaseError(f"a polygon needs at least 3 vertices, got {n}", key=key)
    if n > MAX_VERTICES:  # the pairwise check below is O(n^2) in time and memory
        raise CaseError(f"a polygon has at most {MAX_VERTICES} vertices, got {n}", key=key)
    if not np.all(np.isfinite(v)):
        raise CaseError("vertex coordinates must be finite numbers", key=key)
    if len(poly.edge_names) != n:
        raise CaseError(f"expected {n} edge names (one per edge), got {len(poly.edge_names)}",
                        key="geometry.edge_names")
    bad = [name for name in poly.edge_names if not isinstance(name, str) or not name]
    if bad:
        raise CaseError(f"edge names must be non-empty strings, got {bad[0]!r}",
                        key="geometry.edge_names")
    scale = float(np.linalg.norm(v.max(axis=0) - v.min(axis=0)))
    tol = REL_TOL * scale
    dist = np.linalg.norm(v[:, None, :] - v[None, :, :], axis=-1)
    i, j = np.nonzero(np.triu(dist <= tol, k=1))
    if len(i):
        raise CaseError(f"vertices {i[0]} and {j[0]} coincide at {v[i[0]].tolist()}", key=key)
    if np.linalg.svd(v - v.mean(axis=0), compute_uv=False)[-1] <= tol:
        raise CaseError("the polygon has zero area: all vertices lie on one line", key=key)
    hit = _self_intersection(v, tol)
    if hit is not None:
        raise CaseError(f"the polygon intersects itself: edges {hit[0]} and {hit[1]} "
                        "cross, touch or overlap", key=key)
    area = signed_area(v)
    if abs(area) <= REL_TOL * scale**2:  # not reachable for a simple polygon; kept as a guard
        raise CaseError("the polygon has zero area", key=key)
    if require_ccw and area < 0:
        raise CaseError("vertices must be counterclockwise (use geometry.polygon())", key=key)
    return poly


def _cross(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    return a[..., 0] * b[..., 1] - a[..., 1] * b[..., 0]


def _self_intersection(v: np.ndarray, tol: float) -> tuple[int, int] | None:
    """First pair (i, j) of edges that intersect improperly, or None (vectorized, O(nv^2))."""
    n = len(v)
    a, b = v, np.roll(v, -1, axis=0)
    d = b - a
    # adjacent edges i, i+1 folding back onto each other (collinear and opposite)
    nxt = np.roll(d, -1, axis=0)
    fold = (np.abs(_cross(d, nxt)) <= tol * np.linalg.norm(d, axis=1)) & (
        np.einsum("ij,ij->i", d, nxt) < 0)
    if fold.any():
        i = int(np.argmax(fold))
        return i, (i + 1) % n
    i, j = np.triu_indices(n, k=2)
    keep = ~((i == 0) & (j == n - 1))  # edges 0 and n-1 are adjacent
    i, j = i[keep], j[keep]
    if len(i) == 0:
        return None
    len_i = np.linalg.norm(d[i], axis=1)
    len_j = np.linalg.norm(d[j], axis=1)

    def side(p, q, r, length):  # signed distance of r from line p->q, zeroed within tol
        s = _cross(q - p, r - p) / length
        return np.where(np.abs(s) <= tol, 0.0, np.sign(s))

    o1 = side(a[i], b[i], a[j], len_i)
    o2 = side(a[i], b[i], b[j], len_i)
    o3 = side(a[j], b[j], a[i], len_j)
    o4 = side(a[j], b[j], b[i], len_j)
    crossing = (o1 * o2 <= 0) & (o3 * o4 <= 0) & ~((o1 == 0) & (o2 == 0))
    # collinear pairs: overlap of the parameter intervals along edge i
    u = d[i] / len_i[:, None]
    t0 = np.einsum("ij,ij->i", a[j] - a[i], u)
    t1 = np.einsum("ij,ij->i", b[j] - a[i], u)
    overlap = (np.maximum(t0, t1) >= -tol) & (np.minimum(t0, t1) <= len_i + tol)
    collinear = (o1 == 0) & (o2 == 0) & overlap
    hits = np.nonzero(crossing | collinear)[0]
    return (int(i[hits[0]]), int(j[hits[0]])) if len(hits) else None


def collinear_run(points, tol: float = 1e-9, *, key: str | None = None):
    """Check that segments form one straight segment; return (start, end, unit direction).

    ``points`` is either (k, 2) end points or (m, 2, 2) segments. All points must lie on one
    line within ``tol`` times the run length; with segments, their union must also cover the
    run without gaps. ``start`` is the extreme point nearest to the first given point. Raises
    :class:`CaseError` (with ``key``) otherwise.
    """
    p = np.asarray(points, dtype=np.float64)
    segments = p if p.ndim == 3 else None
    p = p.reshape(-1, 2)
    if len(p) < 2 or not np.all(np.isfinite(p)):
        raise CaseError("needs at least one segment with finite end points", key=key)
    # extremes of a collinear set: farthest from any point, then farthest from that one
    a = p[np.argmax(np.linalg.norm(p - p[0], axis=1))]
    b = p[np.argmax(np.linalg.norm(p - a, axis=1))]
    length = float(np.linalg.norm(b - a))
    if length == 0.0:
        raise CaseError("the segments have zero length", key=key)
    if np.linalg.norm(b - p[0]) < np.linalg.norm(a - p[0]):
        a, b = b, a
    u = (b - a) / length
    if np.max(np.abs(_cross(p - a, u))) > tol * length:
        raise CaseError("the edges do not lie on one straight line", key=key)
    if segments is not None:
        t = np.sort(np.einsum("mkj,j->mk", segments - a, u), axis=1)  # (m, 2) intervals
        t = t[np.argsort(t[:, 0])]
        reach = np.maximum.accumulate(t[:, 1])
        if np.any(t[1:, 0] > reach[:-1] + tol * length):
            raise CaseError("the edges do not form one connected straight segment", key=key)
    return a.copy(), b.copy(), u
