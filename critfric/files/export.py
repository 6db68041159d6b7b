"""ParaView export of a solve file (meshio): the mesh with every stored critical mode.

For each mode ``positive_0``, ``negative_0``, ... the file holds, on the undeformed mesh,
point data ``<mode>_phi`` (Phi, in 2D padded with a zero z component: ParaView treats only
3-component arrays as vectors), ``<mode>_contact_force`` (the nodal contact force
X n + Y t, 3D: X n + Y s, at the contact nodes, zero elsewhere) and ``<mode>_von_mises``
(nodal average), and cell data ``<mode>_stress`` (the tensor at the cell centroid, 9
components: ParaView's tensor layout; plane strain in 2D) and ``<mode>_von_mises``. Phi is
scaled to ``max |Phi| = 1``, and the stresses and the contact forces are those of that Phi (units
of E per unit length). 3D cells are written in VTK's node order (tetra10, hexahedron27 differ
from gmsh's). The alphas are in the solve file (``critfric table``) and, in a VTU file, in its
field data (with r of each in 3D).
"""

from __future__ import annotations

import tomllib
from dataclasses import dataclass
from pathlib import Path
from xml.sax.saxutils import quoteattr

import h5py
import numpy as np

from ..errors import CaseError
from ..fem.assembly import cell_stress, lame, von_mises
from ..fem.mesh import Mesh
from .opening import open_file
from .results import file_attrs, r_of
from .safety import check_output, staged

FORMATS = ("xdmf", "vtu")
_MESHIO_CELL = {2: {"P1": "triangle", "P2": "triangle6", "Q1": "quad", "Q2": "quad9"},
                3: {"P1": "tetra", "P2": "tetra10", "Q1": "hexahedron", "Q2": "hexahedron27"}}
# VTK's local node order (that of meshio, VTU and XDMF) as gmsh's local indices, where they
# differ: the tetrahedron's edges 31, 32 (gmsh 32, 31); the hexahedron's edges 01, 12, 23, 30,
# 45, 56, 67, 74, 04, 15, 26, 37 and faces x = -1, x = 1, y = -1, y = 1, z = -1, z = 1
# (:mod:`critfric.fem.solids` lists gmsh's order). Triangles and quadrangles agree.
VTK_ORDER = {(3, "P2"): [0, 1, 2, 3, 4, 5, 6, 7, 9, 8],
             (3, "Q2"): [0, 1, 2, 3, 4, 5, 6, 7, 8, 11, 13, 9, 16, 18, 19, 17, 10, 12, 14, 15,
                         22, 23, 21, 24, 20, 25, 26]}


@dataclass
class SolveData:
    """What plots and exports need from a solve file (validated before it is read)."""

    path: Path
    attrs: dict
    mesh: Mesh
    contact_nodes: np.ndarray
    contact_edges: list[str]  # the contact groups' names: edges in 2D, faces in 3D
    alpha: np.ndarray
    positive: np.ndarray
    negative: np.ndarray
    modes: dict[str, dict]  # name -> {"alpha", "phi", "theta_n", "theta_t", "r"}
    r: np.ndarray | None = None  # 3D: r of each eigenvalue of alpha
    slip: np.ndarray | None = None  # 3D: (p, 3) slip direction s of each contact node

    @property
    def dim(self) -> int:
        return self.mesh.dim

    @property
    def normal(self) -> np.ndarray:
        return np.asarray(self.attrs["normal"], dtype=float)

    @property
    def tangent(self) -> np.ndarray:
        """t = (-n2, n1) in 2D, t1 (the direction of slip angle 0) in 3D."""
        return np.asarray(self.attrs["tangent"], dtype=float)

    def r_of(self, values) -> np.ndarray:
        """r of the eigenvalues ``values`` (of ``positive`` or ``negative``; zeros in 2D)."""
        if self.r is None:
            return np.zeros(len(values))
        return r_of(self.alpha, self.r, values)

    def contact_directions(self) -> np.ndarray:
        """(p, dim) direction of Y at each contact node: t in 2D, the slip direction s in 3D."""
        if self.slip is not None:
            return self.slip
        return np.broadcast_to(self.tangent, (len(self.contact_nodes), self.dim))


def _groups(f: h5py.File, name: str) -> dict[str, np.ndarray]:
    group = f.get(name)
    return {k: g[()] for k, g in group.items()} if isinstance(group, h5py.Group) else {}


def read_solve(path: Path | str) -> SolveData:
    """Read a file written by ``critfric solve`` (2D or 3D)."""
    path = Path(path)
    try:
        with open_file(path) as f:
            attrs = file_attrs(f, "solve", path)
            element = f["mesh/cells"].attrs["element"]
            element = element.decode() if isinstance(element, bytes) else str(element)
            mesh = Mesh(f["mesh/points"][()], f["mesh/cells"][()], element,
                        _groups(f, "mesh/edges"), _groups(f, "mesh/faces"))
            modes = {name: {"alpha": float(g.attrs["alpha"]), "phi": g["phi"][()],
                            "theta_n": g["theta_n"][()], "theta_t": g["theta_t"][()],
                            "r": float(g.attrs.get("r", 0.0))}
                     for name, g in f["modes"].items()}
            data = dict(alpha=f["eigen/alpha"][()], positive=f["critical/positive"][()],
                        negative=f["critical/negative"][()],
                        contact_nodes=f["mesh/contact_nodes"][()])
            if mesh.dim == 3:
                data.update(r=f["eigen/r"][()], slip=f["mesh/slip"][()])
    except (OSError, KeyError, ValueError, TypeError, IndexError) as exc:
        raise CaseError(f"cannot read this result file ({exc})", file=str(path)) from None
    try:
        contact = tomllib.loads(attrs.get("case_toml", "")).get("boundary", {}).get(
            "contact", ["bottom"])
    except tomllib.TOMLDecodeError:
        contact = ["bottom"]
    contact = [contact] if isinstance(contact, str) else list(contact)
    contact = [c for c in contact if isinstance(c, str)]
    order = sorted(modes, key=lambda n: (not n.startswith("positive"), int(n.split("_")[-1])))
    return SolveData(path=path, attrs=attrs, mesh=mesh, contact_edges=contact,
                     modes={n: modes[n] for n in order}, **data)


def mode_fields(data: SolveData, mode: dict) -> dict[str, np.ndarray]:
    """Phi (max |Phi| = 1), its centroid stress (n_cells, 4 in 2D, 6 in 3D), centroid and
    nodal von Mises, and the nodal contact forces (n_nodes, dim) of that Phi."""
    phi = np.asarray(mode["phi"], dtype=float)
    peak = np.max(np.linalg.norm(phi, axis=1))
    phi = phi / peak if peak > 0 else phi
    E, (lam, G) = float(data.attrs["E"]), lame(1.0, float(data.attrs["nu"]))
    mesh = data.mesh  # stresses at E = 1, then scaled (squares of E = 1e300 would overflow)
    unit = cell_stress(mesh, phi.ravel(), lam, G, at="centroid")[:, 0, :]
    centre = E * unit
    at_nodes = E * von_mises(cell_stress(mesh, phi.ravel(), lam, G, at="nodes"))  # (n_cells, nl)
    cells = np.asarray(mesh.cells)
    total = np.bincount(cells.ravel(), weights=at_nodes.ravel(), minlength=mesh.n_nodes)
    count = np.bincount(cells.ravel(), minlength=mesh.n_nodes)
    force = np.zeros((mesh.n_nodes, mesh.dim))
    scale = 1.0 / peak if peak > 0 else 1.0
    force[data.contact_nodes] = scale * (np.outer(mode["theta_n"], data.normal)
                                         + mode["theta_t"][:, None] * data.contact_directions())
    return {"phi": phi, "stress": centre, "von_mises_cell": E * von_mises(unit),
            "von_mises_node": total / np.maximum(count, 1), "contact_force": force}


def stress_tensor(stress: np.ndarray) -> np.ndarray:
    """(n, 9) row-major symmetric tensors (ParaView's layout) of (n, 4) plane-strain
    components (sxx, syy, sxy, szz) or (n, 6) 3D components (sxx, syy, szz, syz, sxz, sxy)."""
    if stress.shape[1] == 4:
        sxx, syy, sxy, szz = stress.T
        syz = sxz = np.zeros_like(sxx)
    else:
        sxx, syy, szz, syz, sxz, sxy = stress.T
    return np.column_stack([sxx, sxy, sxz, sxy, syy, syz, sxz, syz, szz])


def vtk_cells(mesh: Mesh) -> tuple[str, np.ndarray]:
    """The meshio cell type of ``mesh`` and its cells in VTK's local node order."""
    cells = np.asarray(mesh.cells)
    order = VTK_ORDER.get((mesh.dim, mesh.element))
    return _MESHIO_CELL[mesh.dim][mesh.element], cells if order is None else cells[:, order]


def default_export(path: Path, fmt: str) -> Path:
    return path.with_name(f"{path.stem}_modes.{fmt}")


def export_file(path: Path | str, *, fmt: str = "xdmf", output: Path | str | None = None,
                force: bool = False) -> Path:
    """Write the mesh and every stored mode of solve file ``path`` for ParaView."""
    import meshio

    path = Path(path)
    if fmt not in FORMATS:
        raise CaseError(f"got {fmt!r}; allowed: " + ", ".join(FORMATS), key="--format")
    out = Path(output) if output is not None else default_export(path, fmt)
    if out.suffix != f".{fmt}":
        raise CaseError(f"must end in .{fmt} for --format {fmt}", file=str(out),
                        key="--output")
    if fmt == "xdmf" and out.with_suffix(".h5").resolve() == path.resolve():
        raise CaseError(f"would overwrite the input: XDMF keeps its arrays in "
                        f"{out.with_suffix('.h5').name}; choose another name", file=str(out),
                        key="--output")
    written = [out] + ([out.with_suffix(".h5")] if fmt == "xdmf" else [])
    for target in written:  # the export and its companion: neither clobbered without --force
        check_output(target, force=force, inputs=[path])
    data = read_solve(path)
    if not data.modes:
        raise CaseError("holds no mode (solved with [output] modes = false, or no real "
                        "eigenvalue); nothing to export", file=str(path))
    mesh = data.mesh
    pad = lambda v: v if mesh.dim == 3 else np.column_stack([v, np.zeros(len(v))])
    point_data, cell_data = {}, {}
    for name, mode in data.modes.items():
        f = mode_fields(data, mode)
        point_data[f"{name}_phi"] = pad(f["phi"])
        point_data[f"{name}_contact_force"] = pad(f["contact_force"])
        point_data[f"{name}_von_mises"] = f["von_mises_node"]
        cell_data[f"{name}_stress"] = [stress_tensor(f["stress"])]
        cell_data[f"{name}_von_mises"] = [f["von_mises_cell"]]
    # the boundary edges (faces in 3D) as a second cell block, tagged 1, 2, ... by group name
    # (field data names the tags), so that ParaView can select the contact and Dirichlet ones
    names = sorted(mesh.facets)
    facets = [np.asarray(mesh.facets[n]) for n in names]
    if mesh.dim == 2:  # a second-order edge end, end, mid as two 2-node lines: every reader
        facets = [f if f.shape[1] == 2 else f[:, [0, 2, 2, 1]].reshape(-1, 2) for f in facets]
        facet_type, width = "line", 2
    else:  # faces in the facet element's order, which is VTK's for triangles and quadrangles
        facet_type, width = _MESHIO_CELL[2][mesh.element], mesh.fe.facet_nodes
    edge_cells = np.concatenate(facets) if facets else np.zeros((0, width), dtype=np.int64)
    tags = np.concatenate([np.full(len(f), i + 1) for i, f in enumerate(facets)]) if facets \
        else np.zeros(0, dtype=np.int64)
    blocks = [vtk_cells(mesh)]
    if fmt == "vtu":  # (XDMF readers take no mixed second-order topology: cells only there)
        blocks.append((facet_type, edge_cells))
        cell_data = {name: [values[0], np.zeros((len(edge_cells),) + np.shape(values[0])[1:])]
                     for name, values in cell_data.items()}
        cell_data["boundary_tag"] = [np.zeros(mesh.n_cells, dtype=np.int64), tags]
    field_data = {n: np.array([i + 1, mesh.dim - 1]) for i, n in enumerate(names)}
    field_data.update({"critical_positive": np.atleast_1d(np.asarray(data.positive, float)),
                       "critical_negative": np.atleast_1d(np.asarray(data.negative, float)),
                       "nu": np.array([float(data.attrs["nu"])])})
    if mesh.dim == 3:
        field_data.update({f"r_{family}": np.atleast_1d(data.r_of(values)) for family, values
                           in (("positive", data.positive), ("negative", data.negative))})
    points = pad(np.asarray(mesh.points, dtype=float))
    out_mesh = meshio.Mesh(points, blocks, point_data=point_data, cell_data=cell_data,
                           field_data=field_data)
    with staged(written) as stage:  # written aside, then renamed: never half an export
        if fmt == "xdmf":
            meshio.xdmf.write(stage[0], out_mesh, data_format="HDF")
        else:
            meshio.vtu.write(stage[0], out_mesh, binary=True)
        if fmt == "vtu":  # (XDMF readers such as meshio refuse extra elements: VTU only)
            _add_field_data(stage[0], field_data)
    return out


def _add_field_data(path: Path, fields: dict) -> None:
    """Write ``fields`` (name -> 1-D array) as the VTK FieldData of a .vtu file (meshio
    leaves it out); ParaView shows it as the dataset's field data."""
    def numbers(v) -> str:
        return " ".join(f"{x:.17g}" for x in np.asarray(v, dtype=float))

    arrays = "".join(f'<DataArray type="Float64" Name={quoteattr(n)} '
                     f'NumberOfTuples="{len(v)}" format="ascii">{numbers(v)}</DataArray>'
                     for n, v in fields.items())
    data, anchor = path.read_bytes(), b"<UnstructuredGrid>"
    at = data.find(anchor)
    if at >= 0:
        at += len(anchor)
        path.write_bytes(data[:at] + f"<FieldData>{arrays}</FieldData>".encode() + data[at:])
