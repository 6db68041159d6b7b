"""User gmsh files are read and meshed in a limited child process (and so are boxes and
prisms whose features are far below the mesh size, :mod:`.solid`, under their own wall time).

The parent copies the file's bytes (read once: what was checked is what is meshed) into a
fresh private directory that holds nothing else (so gmsh finds no sidecar ``.opt`` file and
no other file by a relative name), and runs this module there in a new Python process with

* CPU time, address space and file size limits (``resource.setrlimit``) and a wall-clock
  timeout: an endless loop, a recursive macro or a huge declared mesh ends as an error;
* no standard input, standard output and error captured (gmsh's terminal output can never
  reach critfric's ``--json``), an environment reduced to PATH and the private directory;
* gmsh started without its option files, terminal output off.

While it runs, the parent watches it (:func:`_watch`): the child names its stage in a
``stage`` file; a script's evaluation (stage "geometry": ``For`` loops, macros, booleans) may
take GEOMETRY_SECONDS of wall time, and from the meshing on (stage "meshing 2" or "meshing 3",
the body's dimension) the child's resident memory may grow by WATCH_BYTES_PER_NODE for each
node the resource guard allows (``job["max_nodes"]``, by dimension, from ``--max-dofs`` or the
memory available) plus WATCH_SLACK_BYTES: gmsh needs up to 1.6 kB a node in 2D, 3.1 kB in 3D
(peak resident memory, unit square and cube, 7 k to 290 k nodes), so a script that asks for
far more nodes than allowed (a size field, a transfinite count) is stopped once its mesh
passes about twice the allowance, not at the CPU limit.

The child answers with ``mesh.npz`` (the Mesh arrays; the named boundary facets are edges in
2D, faces in 3D) or ``error.json`` (a CaseError or SolverError to raise again); anything else
(a crash, ``sys.exit`` or ``abort`` in a library, a limit hit) becomes a clear error in the
parent. The directory is removed afterwards.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from ..errors import CaseError, CritfricError, SolverError
from ..fem.elements import get_element
from ..fem.mesh import Mesh
from .cells3d import solid

CPU_SECONDS = 60  # CPU time a child may use to read or mesh one file
WALL_SECONDS = 120  # and wall-clock time, start-up included
MIN_ADDRESS_SPACE = 4 * 2**30  # a child may always map this much (Python, numpy, gmsh)
MSH_BYTES_PER_BYTE = 64  # and, reading a .msh, this much more per byte of the file
MAX_INPUT_BYTES = 1 << 30  # a gmsh file larger than this is refused unread
OUTPUT_BYTES = 4 << 30  # the largest file a child may write (its mesh.npz)
_CAPTURE = 4000  # characters of a failed child's stderr quoted in the message
GEOMETRY_SECONDS = 5.0  # wall time a .geo script's evaluation may take (before any meshing)
# and its meshing: this plus so much a node of what the DOF guard allows (gmsh makes ~1e-5 s
# a node in 2D; mesh-size fields that evaluate each other twice over took 2^k per point)
MESHING_SECONDS, MESHING_SECONDS_PER_NODE = 6.0, {2: 1e-4, 3: 2e-4}
WATCH_BYTES_PER_NODE = {2: 3072, 3: 6144}  # memory a meshing child may add per allowed node
WATCH_SLACK_BYTES = 96 << 20  # and this much more whatever the allowance
POLL_SECONDS = 0.05  # how often the parent looks at the child


def run_in_child(path: Path, data: bytes, job: dict, *, entry: str,
                 source: str | None) -> Mesh:
    """The Mesh that ``entry`` ("module:function", called in the child with the private
    directory and ``job``) makes of ``data``, the bytes of the user file ``path``."""
    with tempfile.TemporaryDirectory(prefix="critfric-mesh-") as tmp:
        work = Path(tmp)
        os.chmod(work, 0o700)
        name = "input" + path.suffix.lower()
        (work / name).write_bytes(data)
        (work / "job.json").write_text(json.dumps({**job, "input": name, "shown": path.name}))
        env = {"PATH": os.defpath, "HOME": tmp, "TMPDIR": tmp, "OMP_NUM_THREADS": "1",
               "OPENBLAS_NUM_THREADS": "1", "MKL_NUM_THREADS": "1", "LC_ALL": "C"}
        code = ("import sys, json; sys.path[:0] = json.loads(sys.argv[1]); from "
                "critfric.meshing.sandbox import child_main; child_main(sys.argv[2], "
                "*map(int, sys.argv[3:6]))")
        # -I leaves out PYTHONPATH and the working directory: the child imports critfric,
        # numpy and gmsh from where this process did (its absolute import path)
        package_root = json.dumps(list(dict.fromkeys(
            [str(Path(__file__).resolve().parents[2])]
            + [p for p in sys.path if os.path.isabs(p) and os.path.isdir(p)])))
        # its own session: a Ctrl-C reaches critfric, which ends it (no preexec_fn: Python
        # code between fork and exec can deadlock on a lock another thread held)
        proc = subprocess.Popen(
            [sys.executable, "-I", "-c", code, package_root, entry, str(CPU_SECONDS),
             str(_space(job, data)), str(int(bool(job.get("trust"))))],
            cwd=tmp, env=env, stdin=subprocess.DEVNULL, stdout=subprocess.PIPE,
            stderr=subprocess.PIPE, start_new_session=True)
        try:
            stderr = _watch(proc, work, job, path)
        finally:
            if proc.poll() is None:
                _stop(proc)
        proc = subprocess.CompletedProcess(proc.args, proc.returncode, b"", stderr)
        error = work / "error.json"
        if error.is_file():
            raise _error_from(json.loads(error.read_text()), path, source)
        result = work / "mesh.npz"
        if proc.returncode != 0 or not result.is_file():
            raise CaseError(_failure(proc), file=str(path), key=job.get("key", "geometry.file"))
        return _mesh_from(result, path)


def _watch(proc: subprocess.Popen, work: Path, job: dict, path: Path) -> bytes:
    """Wait for the child, stopping it (a CaseError) past the wall-clock limit
    (``job["wall_seconds"]``, else WALL_SECONDS; ``job["slow"]`` says why), past
    GEOMETRY_SECONDS in its "geometry" stage, or when its memory grows past what
    ``job["max_nodes"]`` allows in its "meshing" stage (``job["what"]`` is meshed, the
    ``job["suspects"]`` why); its stderr."""
    start = time.monotonic()
    stage, since, base, max_nodes = "", start, 0, None
    while True:
        try:
            return proc.communicate(timeout=POLL_SECONDS)[1]
        except subprocess.TimeoutExpired:
            pass
        now = time.monotonic()
        why = None
        if now - start > job.get("wall_seconds", WALL_SECONDS):
            why = job.get("slow") or (f"reading or meshing this file took more than "
                                      f"{WALL_SECONDS} s and was stopped (an endless loop in "
                                      "a .geo script?)")
        seen = _read_stage(work)
        if seen != stage:
            stage, since = seen, now
            base = _resident(proc.pid)
            dim = int(stage[-1]) if stage in ("meshing 2", "meshing 3") else None
            max_nodes = (job.get("max_nodes") or {}).get(str(dim))
        if max_nodes is not None and now - since > (
                MESHING_SECONDS + MESHING_SECONDS_PER_NODE[dim] * float(max_nodes)):
            why = (f"meshing {job.get('what', 'this gmsh script')} took more than "
                   f"{MESHING_SECONDS + MESHING_SECONDS_PER_NODE[dim] * float(max_nodes):.3g} "
                   f"s of wall time for at most {float(max_nodes):.3g} nodes and was stopped "
                   "(mesh-size fields that evaluate each other over and over?)")
        elif stage == "geometry" and now - since > GEOMETRY_SECONDS:
            why = (f"evaluating this gmsh script took more than {GEOMETRY_SECONDS:g} s of wall "
                   "time before any meshing and was stopped (an endless For loop, a recursive "
                   "macro?); allowed: a script whose geometry is built within "
                   f"{GEOMETRY_SECONDS:g} s")
        elif max_nodes is not None and _resident(proc.pid) - base > (
                WATCH_SLACK_BYTES + WATCH_BYTES_PER_NODE[dim] * float(max_nodes)):
            allows = (f"--max-dofs {job['max_dofs']}" if job.get("max_dofs") is not None
                      else "the memory available")
            why = (f"meshing {job.get('what', 'this gmsh script')} was stopped: its mesh grew "
                   f"past the {float(max_nodes):.3g} nodes that {allows} allows ("
                   + job.get("suspects", "a mesh-size field, a transfinite count or a mesh "
                             "size far finer than the body?") + "). Use a coarser mesh"
                   + (", or a larger --max-dofs" if job.get("max_dofs") is not None
                      else ", or pass --max-dofs N to override"))
        if why is not None:
            _stop(proc)
            raise CaseError(why, file=str(path), key=job.get("key", "geometry.file"))


def _stop(proc: subprocess.Popen) -> None:
    """End the child (its own process group) and reap it."""
    import signal

    try:
        if os.name == "posix":
            os.killpg(proc.pid, signal.SIGKILL)
        else:
            proc.kill()
    except (ProcessLookupError, PermissionError):
        proc.kill()
    proc.communicate()


def _read_stage(work: Path) -> str:
    try:
        return (work / "stage").read_text()
    except (OSError, UnicodeDecodeError):
        return ""


def _resident(pid: int) -> int:
    """Resident bytes of process ``pid`` (0 where /proc is not there)."""
    try:
        with open(f"/proc/{pid}/statm") as f:
            return int(f.read().split()[1]) * os.sysconf("SC_PAGE_SIZE")
    except (OSError, ValueError, IndexError):
        return 0


def max_nodes(max_dofs: int | None, element: str) -> dict[str, float]:
    """The most first-order mesh nodes the resource guard can allow, by dimension ("2",
    "3"): the DOFs of ``max_dofs`` or, without it, the DOFs that fit in the memory available,
    over dim DOFs a node and order^dim nodes per vertex (P2/Q2 add edge and face nodes)."""
    from ..guards import available_memory, dofs_that_fit

    order = 2 if element in ("P2", "Q2") else 1
    memory = available_memory()
    return {str(d): (max_dofs if max_dofs is not None else
                     dofs_that_fit(memory, dim=d, element="Q1" if element[0] == "Q" else "P1"))
            / (d * order**d) for d in (2, 3)}


def set_stage(work: Path, stage: str) -> None:
    """In the child: tell the watching parent the stage ("geometry", "meshing 2" or 3)."""
    tmp = work / "stage.tmp"
    tmp.write_text(stage)
    os.replace(tmp, work / "stage")


def read_input(path: Path) -> bytes:
    """The bytes of a user file, read once (so what is checked is what is meshed)."""
    try:
        size = path.stat().st_size
        if size > MAX_INPUT_BYTES:
            raise CaseError(f"is {size / 2**20:.0f} MB; allowed: gmsh files up to "
                            f"{MAX_INPUT_BYTES >> 20} MB", file=str(path), key="geometry.file")
        with open(path, "rb") as f:
            return f.read(MAX_INPUT_BYTES + 1)
    except FileNotFoundError:
        raise CaseError("no such file; allowed: an existing gmsh .msh or .geo file",
                        file=str(path), key="geometry.file") from None
    except IsADirectoryError:
        raise CaseError("is a directory; allowed: a gmsh .msh or .geo file", file=str(path),
                        key="geometry.file") from None
    except OSError as exc:
        raise CaseError(f"cannot read this file ({exc.strerror})", file=str(path),
                        key="geometry.file") from None


def _space(job: dict, data: bytes) -> int:
    """The address space a child may map: reading a .msh needs memory in proportion to the
    file (a small file that declares a huge node count or sparse tags is stopped there);
    meshing a .geo, what the resource guard allowed."""
    from ..guards import available_memory

    if job["kind"] == "msh":
        return MIN_ADDRESS_SPACE + MSH_BYTES_PER_BYTE * len(data)
    return max(int(available_memory()), MIN_ADDRESS_SPACE)


def _limits(cpu: int, space: int, spawn: bool = False) -> None:
    """The child's limits (``cpu`` seconds, ``space`` bytes of address space, as the parent
    decided them; no new process unless ``spawn``), set by the child itself before it reads
    anything of the job (POSIX; elsewhere only the parent's wall-clock and memory watch
    apply)."""
    try:
        import resource
    except ImportError:
        return
    # no new process either (a second wall behind the .geo allow-list: gmsh's SystemCall
    # is system(), which cannot fork then; the kernel does not hold root to this limit)
    nproc = [] if spawn else [(resource.RLIMIT_NPROC, 0)]
    for limit, value in ((resource.RLIMIT_CPU, cpu), (resource.RLIMIT_AS, space),
                         (resource.RLIMIT_FSIZE, OUTPUT_BYTES), (resource.RLIMIT_CORE, 0),
                         *nproc):
        hard = resource.getrlimit(limit)[1]
        value = value if hard == resource.RLIM_INFINITY else min(value, hard)
        resource.setrlimit(limit, (value, hard))


def _failure(proc: subprocess.CompletedProcess) -> str:
    code = proc.returncode
    if code < 0:
        import signal

        name = signal.Signals(-code).name if -code in signal.Signals._value2member_map_ else code
        why = {"SIGXCPU": f"it used more than {CPU_SECONDS} s of CPU time",
               "SIGKILL": f"it used more than {CPU_SECONDS} s of CPU time or was killed",
               "SIGSEGV": "the reader crashed (out of memory, or a malformed file)",
               "SIGABRT": "the reader aborted"}.get(str(name), f"it ended on signal {name}")
    else:
        why = f"the reader stopped with exit code {code}"
    tail = proc.stderr.decode(errors="replace").strip()[-_CAPTURE:]
    return (f"cannot read or mesh this file: {why}" + (f" ({tail.splitlines()[-1]})"
                                                       if tail else ""))


def _error_from(info: dict, path: Path, source: str | None) -> CritfricError:
    kind, message, key = info.get("kind"), str(info.get("message")), info.get("key")
    if kind == "solver":
        return SolverError(message)
    file = info.get("file")
    return CaseError(message, file=str(path) if file == "input" else (file or source),
                     key=key)


def _mesh_from(result: Path, path: Path) -> Mesh:
    """The child's Mesh arrays (2D: edges, 3D: faces), checked before use."""
    with np.load(result, allow_pickle=False) as z:
        points, cells = z["points"], z["cells"]
        element = str(z["element"])
        names = [str(n) for n in z["edge_names"]]
        groups = {n: z[f"edge_{i}"] for i, n in enumerate(names)}
    dim = points.shape[1] if points.ndim == 2 else 0
    spec = solid(element) if dim == 3 else get_element(element)
    ok = (dim in (2, 3) and points.dtype == np.float64
          and np.all(np.isfinite(points)) and cells.ndim == 2 and cells.shape[1] == spec.n_local
          and cells.dtype.kind == "i" and cells.size and cells.min() >= 0
          and cells.max() < len(points)
          and all(e.ndim == 2 and e.shape[1] == spec.facet_nodes and e.dtype.kind == "i"
                  and (e.size == 0 or (e.min() >= 0 and e.max() < len(points)))
                  for e in groups.values()))
    if not ok:
        raise SolverError(f"the mesh read from {path.name} came back malformed")
    if dim == 3:
        return Mesh(points, cells, element, faces=groups)
    return Mesh(points, cells, element, groups)


# ------------------------------------------------------------------------------- the child
def child_main(entry: str, cpu: int, space: int, trusted: int = 0) -> None:
    """The child process (cwd: the private directory): within its limits (:func:`_limits`;
    ``trusted``: a script the user trusts may start programs), ``entry`` makes the Mesh."""
    import importlib

    _limits(cpu, space, spawn=bool(trusted))
    work = Path.cwd()
    try:
        job = json.loads((work / "job.json").read_text())
        module, _, function = entry.partition(":")
        mesh = getattr(importlib.import_module(module), function)(work, job)
        groups = mesh.faces if mesh.points.shape[1] == 3 else mesh.edges  # facets of the body
        names = sorted(groups)
        np.savez(work / "mesh.npz", points=np.ascontiguousarray(mesh.points, dtype=np.float64),
                 cells=mesh.cells.astype(np.int64), element=np.str_(mesh.element),
                 edge_names=np.array(names, dtype=str),
                 **{f"edge_{i}": groups[n].astype(np.int64) for i, n in enumerate(names)})
    except CritfricError as exc:
        _answer(work, {"kind": "case" if isinstance(exc, CaseError) else "solver",
                       "message": getattr(exc, "detail", str(exc)),
                       "key": getattr(exc, "key", None),
                       "file": "input" if getattr(exc, "file", None) else None})
    except MemoryError:
        _answer(work, {"kind": "case", "key": "geometry.file", "file": "input",
                       "message": "reading or meshing this file needs more memory than this "
                                  "machine allows (a huge declared size?)"})
    except SystemExit as exc:  # a library that calls sys.exit on a malformed file
        _answer(work, {"kind": "case", "key": "geometry.file", "file": "input",
                       "message": f"the file reader gave up (exit {exc.code}): a malformed "
                                  "or unsupported gmsh file"})
    except Exception as exc:  # a reader's own failure on a malformed file
        _answer(work, {"kind": "case", "key": "geometry.file", "file": "input",
                       "message": f"cannot read this gmsh file ({type(exc).__name__}: {exc})"})


def _answer(work: Path, info: dict) -> None:
    (work / "error.json").write_text(json.dumps(info))
