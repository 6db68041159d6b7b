"""Guards: refuse a mesh that would not fit in memory, honour Ctrl-C, lock an output file.

Resources: before meshing, the node count is estimated from the domain's area A, perimeter P
and vertex count (``nodes(h) = k (A / (c h^2) + P / (2 h) + n_v)``, c = sqrt(3)/2 for
triangles and 1 for quads, k = 4 for P2/Q2), the DOFs are twice that (three times a node in
3D, from :class:`critfric.meshing.solid.SolidFootprint`), and the peak memory of a solve is
a model per backend and element fitted to measured peaks (:func:`memory_estimate`; 2D at
MODEL_2D: 1.05-1.13 x the peaks of P1/P2 unit squares from 0.1 to 4.2 M DOFs on PARDISO,
1.05-1.26 x on SciPy; 3D at FILL_3D). A solve above the memory available (or above
``max_dofs`` when given) is a :class:`CaseError` that gives the estimate and the finest mesh
size that fits.

Interrupts: :class:`interrupt_guard` makes sure a Ctrl-C is honoured at the next safe point.

Locks: :func:`output_lock` holds an exclusive ``fcntl`` lock on ``.<name>.lock`` next to the
output for the whole solve; a second writer is refused at once.
"""

from __future__ import annotations

import ctypes
import importlib.util
import math
import os
import platform
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .errors import CaseError
from .fem.elements import get_element
from .fem.mesh import shoelace

DENSE_COPIES = 6  # 2D dense stage: S, its Cholesky factor, T, eigenvectors, workspace
SPLIT_MIN_ROWS = 400_000  # SciPy's Schur complement by substructuring from here on (memory)
ESTIMATE_SLACK = 2.0  # --max-dofs against a count before meshing: the 3D estimate ran 1.6x high

#: 2D: peak bytes of a solve with n DOFs and p contact nodes, fitted to the peak RSS of
#: `critfric solve unit-square` (benchmarks/memory2d.py, 58 runs in benchmarks/memory2d.csv:
#: P1 and P2 from 0.1 to 4.2 M DOFs, Q1 and Q2 from 0.1 to 2.1 M, both backends):
#: MODEL_2D[backend][element] = (base, per DOF, fill) gives base + per DOF n (mesh, assembly,
#: vectors) + fill n log2 n (the factor in a nested-dissection order), plus the dense stage
#: (:func:`dense_bytes`). SciPy's one factorization of the whole ("scipy whole", below
#: SPLIT_MIN_ROWS: :func:`model_key_2d`) needs more than its Schur complement by pieces above
#: (1.02 against 1.20 GB at 0.55 and 0.38 M DOFs, P1). Linear programming (memory2d.py
#: --fit): every estimate, from the DOFs and contact nodes predicted before meshing and from
#: the mesh made, at least 1.05 x its peak (repeat runs differ by up to 1.5% on PARDISO, 5%
#: on SciPy), the largest ratio least. Before meshing, the estimates are 1.05-1.13 x the
#: peaks of P1 and P2 on PARDISO, 1.05-1.26 x on SciPy, 1.05-1.27 x for Q1 and Q2 (whose
#: DOF count is estimated up to 18% low); from the mesh made, 1.06-1.29 x for P1 and P2,
#: up to 1.33 x for SciPy's Q2 (its peaks grow slower than its DOFs). The SciPy runs were
#: measured again on the current code: their peaks are 7% below to 10% above the earlier
#: runs'.
MODEL_2D = {
    "pardiso": {"P1": (132e6, 1980.0, 3.79), "P2": (183e6, 1270.0, 62.6),
                "Q1": (193e6, 178.0, 115.0), "Q2": (204e6, 3260.0, 0.0)},
    "scipy": {"P1": (299e6, 126.0, 70.3), "P2": (183e6, 3170.0, 0.0),
              "Q1": (143e6, 1940.0, 0.0), "Q2": (99.8e6, 3540.0, 0.0)},
    "scipy whole": {"P1": (82.1e6, 2170.0, 59.9), "P2": (37.3e6, 1100.0, 177.0),
                    "Q1": (0.0, 2510.0, 93.4), "Q2": (80.1e6, 0.0, 221.0)},
}
_CELL_AREA = {"triangle": math.sqrt(3) / 2, "quad": 1.0}  # cell area / size^2

#: 3D: peak bytes of a solve with n DOFs and p contact nodes, fitted to the peak RSS of
#: `critfric solve` on boxes (benchmarks/box3d.py, 31 runs in benchmarks/box3d_memory.csv:
#: P1/P2 tetrahedra, Q1/Q2 hexahedra, 20 k to 570 k DOFs, both backends): BASE_BYTES_3D +
#: PER_DOF_3D n (stiffness parts, mesh, vectors) + FILL_3D n^FILL_EXPONENT_3D (the factor:
#: its nonzeros grow as n^1.39-1.47 on every element and backend) + DENSE_BYTES_3D (3p)^2
#: where the eigen stage may form the Schur complement onto the contact DOFs (3p <=
#: DENSE_MAX_ROWS, critfric.solvers.eigen's 2 SCHUR_MAX_CONTACT, what method = "dense" allows;
#: "auto" takes ARPACK from eigen.AUTO_DENSE_ROWS_3D rows on: an upper bound there). Least squares
#: on log(peak) with the exponent fixed, then each backend's FILL_3D and DENSE_BYTES_3D raised
#: until no measured peak is above the estimate (x1.06 PARDISO, x1.21 SciPy, whose SuperLU
#: grows its arrays in steps: 12 bytes per factor entry at 150 k DOFs, 15 at 283 k). The
#: estimates are then 1.00-1.11 x the peaks on PARDISO (a fit to the runs below 280 k DOFs
#: gave 1.07-1.12 x the larger ones), 1.00-1.31 x on SciPy.
FILL_EXPONENT_3D = 1.45
BASE_BYTES_3D = 185e6
PER_DOF_3D = {"P1": 850.0, "P2": 2550.0, "Q1": 4150.0, "Q2": 10850.0}
FILL_3D = {"pardiso": {"P1": 41.0, "P2": 42.5, "Q1": 37.0, "Q2": 23.0},
           "scipy": {"P1": 133.0, "P2": 130.0, "Q1": 113.0, "Q2": 89.0}}
DENSE_BYTES_3D = {"pardiso": 30.5, "scipy": 72.5}
DENSE_MAX_ROWS = 8000


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


#: glibc's malloc settings of :func:`keep_freed_memory` (mallopt's parameter numbers)
M_TRIM_THRESHOLD, M_MMAP_MAX, M_ARENA_MAX = -1, -4, -8
KEPT_FREE = 1 << 30  # free memory kept at the heap's top for reuse, at most
_freed_memory_kept = False


def keep_freed_memory() -> bool:
    """Have glibc's malloc keep freed memory for the next arrays instead of giving it back to
    the system: one arena for every thread, no mmap for large blocks, the heap's top trimmed
    above KEPT_FREE only. For the whole process: ``critfric stability`` asks for it in its
    own process; a library caller may. What the stability stages allocate and free again and
    again (n x 80 bases and their products, sparse matrices of K_rr's size) is then not paid
    once more in page faults, and Newton's runs go in two threads (:func:`freed_memory_kept`;
    with glibc's default arenas each thread's arena keeps what it freed). Measured (P1 unit
    square, in-process): at 295 k DOFs 10.2-11.3 s against 11.5-12.1 s, peak 1.53 GB against
    1.68-1.71 GB with two threads on default arenas (1.43 GB with one); at 1.0 M DOFs 40.3 s
    against 45.6 s, peak 4.89 GB against 4.98 GB. Not for ``solve``: at 1.29 M DOFs it was
    slower (11.6-11.9 s against 10.9-11.0 s) and its peak 30% higher (memory freed below a
    live array is not reused for larger ones). Nothing is done off glibc or where the user
    set glibc's malloc (the MALLOC_* variables or GLIBC_TUNABLES). True if set."""
    global _freed_memory_kept
    if platform.libc_ver()[0] != "glibc" or "glibc.malloc" in os.environ.get(
            "GLIBC_TUNABLES", "") or any(k.startswith("MALLOC_") for k in os.environ):
        return False
    try:
        mallopt = ctypes.CDLL(None).mallopt
    except (OSError, AttributeError):
        return False
    mallopt.argtypes, mallopt.restype = [ctypes.c_int, ctypes.c_int], ctypes.c_int
    _freed_memory_kept = bool(mallopt(M_ARENA_MAX, 1) and mallopt(M_MMAP_MAX, 0)
                              and mallopt(M_TRIM_THRESHOLD, KEPT_FREE))
    return _freed_memory_kept


def freed_memory_kept() -> bool:
    """Whether :func:`keep_freed_memory` set glibc's malloc in this process (one arena: work
    spread over threads does not leave freed memory in each thread's arena)."""
    return _freed_memory_kept


#: bytes of address space a solve reserves per byte it uses (its VmPeak over its VmHWM,
#: measured on the 615 k-DOF P1 unit square: 1.79 PARDISO, 2.55 SciPy; SciPy's SuperLU
#: reserved 25.7 GB at 8.7 GB resident at 4 M DOFs): what an address-space cap (ulimit -v)
#: must hold beyond the resident peak that the estimates model
ADDRESS_SPACE_FACTOR = {"pardiso": 2.0, "scipy": 3.0}


def available_memory(backend: str | None = None) -> float:
    """Bytes this process may still use: MemAvailable, capped by a cgroup limit if any and
    by an address-space cap (ulimit -v) divided by ``backend``'s ``ADDRESS_SPACE_FACTOR``
    (None: the cap as it is)."""
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
            factor = ADDRESS_SPACE_FACTOR[estimated_backend(backend)] \
                if backend is not None else 1.0
            avail = min(avail, max(soft - size, 0.0) / factor)
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


def estimated_backend(backend: str | None = None) -> str:
    """The sparse solver an estimate models: ``backend`` as a case names it; "auto" (or
    None) is PARDISO wherever its ``pypardiso`` wheel is installed (what
    :func:`critfric.solvers.backends.resolve_backend` picks; MKL is not loaded here), else
    SciPy."""
    if backend in (None, "auto"):
        return "pardiso" if importlib.util.find_spec("pypardiso") is not None else "scipy"
    return backend if backend in DENSE_BYTES_3D else "scipy"


def dense_bytes(n_contact: float, *, dim: int = 2, backend: str | None = None) -> float:
    """Bytes of the dense eigen stage on ``n_contact`` contact nodes: the dim p x dim p Schur
    complement where the dense path may form it (dim p <= DENSE_MAX_ROWS, critfric.solvers.
    eigen's 2 SCHUR_MAX_CONTACT; beyond, ARPACK), about DENSE_COPIES copies in 2D (S, its
    Cholesky factor, the pencil, eigenvectors, LAPACK workspace), DENSE_BYTES_3D a row^2 in 3D."""
    rows = dim * float(n_contact)
    if rows > DENSE_MAX_ROWS:
        return 0.0
    per = DENSE_BYTES_3D[estimated_backend(backend)] if dim == 3 else DENSE_COPIES * 8.0
    return per * rows * rows


def model_key_2d(backend: str, n_dofs: float) -> str:
    """The row of MODEL_2D for ``backend`` at ``n_dofs``: SciPy's Schur complement comes from
    one factorization of the whole below SPLIT_MIN_ROWS free DOFs ("scipy whole", which needs
    more), taken up to 1.1 SPLIT_MIN_ROWS DOFs: a margin for the held DOFs, which the solver
    does not count, and for an estimate before meshing above the mesh's count."""
    whole = backend == "scipy" and n_dofs < 1.1 * SPLIT_MIN_ROWS
    return "scipy whole" if whole else backend


def memory_estimate(n_dofs: float, n_contact: float = 0.0, *, dim: int = 2,
                    element: str = "P1", backend: str | None = None) -> float:
    """Peak bytes of a solve with ``n_dofs`` degrees of freedom and ``n_contact`` contact
    nodes, with ``element`` on ``backend`` (:func:`estimated_backend`): the fitted model of
    MODEL_2D (2D) or FILL_3D (``dim`` 3), plus the dense stage (:func:`dense_bytes`)."""
    n = max(float(n_dofs), 2.0)
    if not (math.isfinite(n) and math.isfinite(n_contact)):
        return math.inf
    b = estimated_backend(backend)
    dense = dense_bytes(n_contact, dim=dim, backend=b)
    if dim == 3:
        with np.errstate(over="ignore"):
            fill = FILL_3D[b][element] * np.float64(n) ** FILL_EXPONENT_3D
        return float(BASE_BYTES_3D + PER_DOF_3D[element] * n + fill + dense)
    base, per_dof, fill = MODEL_2D[model_key_2d(b, n)][element]
    return base + per_dof * n + fill * n * math.log2(n) + dense


def dofs_that_fit(memory: float, *, contact=None, **model) -> float:
    """The largest DOF count whose :func:`memory_estimate` (keywords ``model``: dim, element,
    backend; ``contact``: the contact node count as a function of the DOF count, default 0)
    fits in ``memory`` bytes (the first from below, where the estimate is not monotone)."""
    def need(n: float) -> float:
        return memory_estimate(n, contact(n) if contact is not None else 0.0, **model)

    lo, hi = 2.0, 2.0
    while need(hi) <= memory and hi < 1e15:
        lo, hi = hi, hi * 2
    for _ in range(60):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if need(mid) <= memory else (lo, mid)
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
               key: str | None = "mesh.size", footprint=None, max_dofs: int | None = None,
               n_contact: float = 0.0, dim: int | None = None,
               backend: str | None = None, estimate: bool = False) -> None:
    """Refuse ``n_dofs`` above ``max_dofs`` or, without it, above what memory allows.

    ``estimate``: ``n_dofs`` is a count before meshing or one with the Dirichlet DOFs, which
    ``max_dofs`` refuses only beyond ESTIMATE_SLACK times (the free DOFs of the mesh made,
    the count every result reports, are checked exactly).

    ``what`` says where the count comes from (e.g. "mesh.size = 1e-05"); with a
    ``footprint`` (:class:`Footprint`, or a 3D body's ``SolidFootprint``) the message also
    gives the finest mesh size that fits. ``dim``: the body's dimension (default: 3 for a 3D
    footprint, else 2); ``backend``: the case's sparse solver ("auto" if None), for the 3D
    model.
    """
    if dim is None:
        dim = 3 if hasattr(footprint, "volume") else 2
    model = {"dim": dim, "element": element, "backend": backend}
    need = memory_estimate(n_dofs, n_contact, **model)
    if max_dofs is not None:
        if n_dofs <= max_dofs * (ESTIMATE_SLACK if estimate else 1):
            return
        limit, why = float(max_dofs), f"more than --max-dofs {max_dofs}"
    else:
        avail = available_memory(backend or "auto")
        if need <= avail:
            return
        contact = None
        if dim == 3 and n_contact > 0 and math.isfinite(n_dofs):  # a face: ~ n^(2/3)
            contact = lambda n: n_contact * (n / n_dofs) ** (2 / 3)
        limit = dofs_that_fit(avail, contact=contact, **model)
        why = f"needing about {_bytes(need)} of memory; {_bytes(avail)} is available"
    count = (f"{n_dofs:.0f}" if not estimate and float(n_dofs).is_integer()
             else f"about {n_dofs:.3g}")
    message = f"{what} gives {count} DOFs ({element}), {why}"
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


