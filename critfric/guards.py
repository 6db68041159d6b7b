"""Guards: refuse a mesh that would not fit in memory, honour Ctrl-C, lock an output file.

Resources: before meshing, the node count is estimated from the domain's area A, perimeter P
and vertex count (``nodes(h) = k (A / (c h^2) + P / (2 h) + n_v)``, c = sqrt(3)/2 for
triangles and 1 for quads, k = 4 for P2/Q2), the DOFs are twice that, and the peak memory of
a solve is ``BASE_BYTES + BYTES_PER_DOF_LOG * n log2 n`` (sparse LU fill with SuperLU:
fitted to P1, P2, Q1 and Q2 unit squares near 1e5 DOFs and to 1e6 DOFs, conservative by
15-30%; the faster backends need less). A solve above the
memory available (or above ``max_dofs`` when given) is a :class:`CaseError` that gives the
estimate and the finest mesh size that fits.

Interrupts: :class:`interrupt_guard` makes sure a Ctrl-C is honoured at the next safe point.

Locks: :func:`output_lock` holds an exclusive ``fcntl`` lock on ``.<name>.lock`` next to the
output for the whole solve; a second writer is refused at once.
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .errors import CaseError
from .fem.elements import get_element
from .fem.mesh import shoelace

BYTES_PER_DOF_LOG = 250.0
BASE_BYTES = 150e6
DENSE_COPIES = 6  # dense stage: S, its Cholesky factor, T, eigenvectors, workspace
_CELL_AREA = {"triangle": math.sqrt(3) / 2, "quad": 1.0}  # cell area / size^2


@dataclass(frozen=True)
class Footprint:
    """What the node count of a mesh depends on: area, perimeter and corner count."""

    area: float
    perimeter: float
    n_vertices: int

    def nodes(self, h: float, element: str) -> float:
        """Estimated node count at mesh size ``h`` (a float: may be huge or inf): vertices
        area / (c h^2) + perimeter / (2 h) + corners (c = sqrt(3)/2 for triangles, 1 for
        quads), times order^2 for the edge and interior nodes of second-order elements."""
        spec = get_element(element)
        with np.errstate(over="ignore", divide="ignore", invalid="ignore"):
            x = np.float64(1.0) / np.float64(h)
            nodes = spec.order**2 * (self.area / _CELL_AREA[spec.reference] * x * x
                                     + self.perimeter / 2 * x + self.n_vertices)
        return float(nodes) if np.isfinite(nodes) else math.inf

    def dofs(self, h: float, element: str) -> float:
        """Estimated DOF count at mesh size ``h``: two per node."""
        return 2.0 * self.nodes(h, element)

    def graded_nodes(self, h: float, element: str, grading: float, radius: float,
                     points: int = 2) -> float:
        """Extra nodes of a mesh graded to size g h at ``points`` points, growing linearly to
        h at distance ``radius``: per point on the boundary, the integral of theta r / (c s(r)^2)
        over a sector of angle theta = 3 pi / 2 (a corner of up to 270 degrees), theta R^2
        (ln(1/g) - 1 + g) / (c h^2 (1 - g)^2) (theta R^2 / (2 c h^2) as g -> 1)."""
        spec, g = get_element(element), float(grading)
        if g >= 1.0:
            return 0.0
        with np.errstate(over="ignore", divide="ignore", invalid="ignore"):
            per = 1.5 * math.pi * radius**2 * (math.log(1 / g) - 1 + g) / (
                _CELL_AREA[spec.reference] * h * h * (1 - g) ** 2)
        return float(points * spec.order**2 * per)

    def finest_size(self, max_dofs: float, element: str) -> float:
        """The smallest h with ``dofs(h) <= max_dofs`` (inf if even one cell is too many)."""
        spec = get_element(element)
        k = spec.order**2
        a, b = self.area / _CELL_AREA[spec.reference], self.perimeter / 2
        c = self.n_vertices - max_dofs / (2 * k)
        if c >= 0:
            return math.inf
        x = (-b + math.sqrt(b * b - 4 * a * c)) / (2 * a)  # positive root in x = 1/h
        return 1.0 / x


def usable_cpus() -> int:
    """The CPUs this process may run on (its affinity mask where the system has one)."""
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # not on Linux
        return os.cpu_count() or 1


def available_memory() -> float:
    """Bytes this process may still use: MemAvailable, capped by a cgroup limit if any."""
    avail = math.inf
    try:
        for line in Path("/proc/meminfo").read_text().splitlines():
            if line.startswith("MemAvailable:"):
                avail = float(line.split()[1]) * 1024
    except OSError:
        pass
    if not math.isfinite(avail):
        try:
            avail = float(os.sysconf("SC_PHYS_PAGES") * os.sysconf("SC_PAGE_SIZE"))
        except (ValueError, OSError, AttributeError):
            avail = 8e9
    try:  # an address-space cap (ulimit -v): what is left of it
        import resource

        soft = resource.getrlimit(resource.RLIMIT_AS)[0]
        if soft != resource.RLIM_INFINITY:
            size = float(Path("/proc/self/statm").read_text().split()[0]) * os.sysconf(
                "SC_PAGE_SIZE")
            avail = min(avail, max(soft - size, 0.0))
    except (ImportError, OSError, ValueError, IndexError):
        pass
    try:
        limit = Path("/sys/fs/cgroup/memory.max").read_text().strip()
        used = Path("/sys/fs/cgroup/memory.current").read_text().strip()
        if limit.isdigit() and used.isdigit():
            avail = min(avail, float(int(limit) - int(used)))
    except OSError:
        pass
    return avail


def memory_estimate(n_dofs: float, n_contact: float = 0.0) -> float:
    """Peak bytes of a solve with ``n_dofs`` degrees of freedom and ``n_contact`` contact
    nodes: the sparse factorization, plus the dense stage (the 2p x 2p Schur complement and
    the p x p pencil with its eigenvectors and LAPACK workspace, about DENSE_COPIES copies)."""
    n = max(float(n_dofs), 2.0)
    if not (math.isfinite(n) and math.isfinite(n_contact)):
        return math.inf
    dense = DENSE_COPIES * 8.0 * (2.0 * n_contact) ** 2
    return BASE_BYTES + BYTES_PER_DOF_LOG * n * math.log2(n) + dense


def dofs_that_fit(memory: float) -> float:
    """The largest DOF count whose :func:`memory_estimate` fits in ``memory`` bytes."""
    lo, hi = 2.0, 2.0
    while memory_estimate(hi) <= memory and hi < 1e15:
        lo, hi = hi, hi * 2
    for _ in range(60):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if memory_estimate(mid) <= memory else (lo, mid)
    return lo


def _bytes(b: float) -> str:
    if not math.isfinite(b):
        return "unbounded"
    for unit in ("B", "kB", "MB", "GB", "TB", "PB"):
        if b < 1000 or unit == "PB":
            return f"{b:.3g} {unit}"
        b /= 1000
    return f"{b:.3g} PB"


def check_dofs(n_dofs: float, *, element: str, what: str, source: str | None,
               key: str | None = "mesh.size", footprint: Footprint | None = None,
               max_dofs: int | None = None, n_contact: float = 0.0) -> None:
    """Refuse ``n_dofs`` above ``max_dofs`` or, without it, above what memory allows.

    ``what`` says where the count comes from (e.g. "mesh.size = 1e-05"); with a
    ``footprint`` the message also gives the finest mesh size that fits.
    """
    need = memory_estimate(n_dofs, n_contact)
    if max_dofs is not None:
        if n_dofs <= max_dofs:
            return
        limit, why = float(max_dofs), f"more than --max-dofs {max_dofs}"
    else:
        avail = available_memory()
        if need <= avail:
            return
        limit = dofs_that_fit(avail)
        why = f"needing about {_bytes(need)} of memory; {_bytes(avail)} is available"
    message = f"{what} gives about {n_dofs:.3g} DOFs ({element}), {why}"
    if footprint is not None:
        finest = footprint.finest_size(limit, element)
        if math.isfinite(finest):
            message += (f"; the finest mesh size that fits is about {finest:.3g} "
                        f"({footprint.dofs(finest, element):.3g} DOFs)")
    override = "a larger --max-dofs" if max_dofs is not None else "--max-dofs N to override"
    raise CaseError(f"{message}. Use a coarser mesh, or pass {override}", file=source, key=key)


def polygon_footprint(vertices: np.ndarray) -> Footprint:
    """Footprint of a closed polygon (n, 2), either orientation."""
    v = np.asarray(vertices, dtype=np.float64)
    with np.errstate(over="ignore", invalid="ignore"):
        perimeter = float(np.linalg.norm(np.roll(v, -1, axis=0) - v, axis=1).sum())
    return Footprint(abs(float(shoelace(v))), perimeter, len(v))


# ------------------------------------------------------------------------------ interrupts


# ---------------------------------------------------------------------------------- locks


