"""ParaView export of a solve file (meshio): the mesh with every stored critical mode.

For each mode ``positive_0``, ``negative_0``, ... the file holds, on the undeformed mesh,
point data ``<mode>_phi`` (Phi padded with a zero z component: ParaView treats only
3-component arrays as vectors) and ``<mode>_von_mises`` (nodal average), and cell data
``<mode>_stress`` (the plane-strain tensor at the cell centroid, 9 components: ParaView's
tensor layout) and ``<mode>_von_mises``. Phi is scaled to max |Phi| = 1 and the stresses are
those of that Phi (units of E per unit length). The alphas are in the solve file
(``critfric table``).
"""

from __future__ import annotations

import tomllib
from dataclasses import dataclass
from pathlib import Path

import h5py
import numpy as np

from ..errors import CaseError
from ..fem.assembly import cell_stress, lame, von_mises
from ..fem.mesh import Mesh
from .results import file_attrs
from .safety import check_output, staged

FORMATS = ("xdmf", "vtu")
_MESHIO_CELL = {"P1": "triangle", "P2": "triangle6", "Q1": "quad", "Q2": "quad9"}


@dataclass
class SolveData:
    """What plots and exports need from a solve file."""

    path: Path
    attrs: dict
    mesh: Mesh
    contact_nodes: np.ndarray
    contact_edges: list[str]
    alpha: np.ndarray
    positive: np.ndarray
    negative: np.ndarray
    modes: dict[str, dict]  # name -> {"alpha", "phi", "theta_n", "theta_t"}

    @property
    def lame(self) -> tuple[float, float]:
        return lame(float(self.attrs["E"]), float(self.attrs["nu"]))


def read_solve(path: Path | str) -> SolveData:
    """Read a file written by ``critfric solve``."""
    path = Path(path)
    try:
        with h5py.File(path, "r") as f:
            attrs = file_attrs(f, "solve", path)
            element = f["mesh/cells"].attrs["element"]
            element = element.decode() if isinstance(element, bytes) else str(element)
            edges = {name: g[()] for name, g in f["mesh/edges"].items()}
            mesh = Mesh(f["mesh/points"][()], f["mesh/cells"][()], element, edges)
            modes = {name: {"alpha": float(g.attrs["alpha"]), "phi": g["phi"][()],
                            "theta_n": g["theta_n"][()], "theta_t": g["theta_t"][()]}
                     for name, g in f["modes"].items()}
            data = dict(alpha=f["eigen/alpha"][()], positive=f["critical/positive"][()],
                        negative=f["critical/negative"][()],
                        contact_nodes=f["mesh/contact_nodes"][()])
    except (OSError, KeyError, ValueError, TypeError, IndexError) as exc:
        raise CaseError(f"cannot read this result file ({exc})", file=str(path)) from None
    try:
        contact = tomllib.loads(attrs.get("case_toml", "")).get("boundary", {}).get(
            "contact", ["bottom"])
    except tomllib.TOMLDecodeError:
        contact = ["bottom"]
    contact = [contact] if isinstance(contact, str) else list(contact)
    order = sorted(modes, key=lambda n: (not n.startswith("positive"), int(n.split("_")[-1])))
    return SolveData(path=path, attrs=attrs, mesh=mesh, contact_edges=contact,
                     modes={n: modes[n] for n in order}, **data)


def mode_fields(data: SolveData, mode: dict) -> dict[str, np.ndarray]:
    """Phi (max |Phi| = 1), its centroid stress (n_cells, 4), centroid and nodal von Mises."""
    phi = np.asarray(mode["phi"], dtype=float)
    peak = np.max(np.linalg.norm(phi, axis=1))
    phi = phi / peak if peak > 0 else phi
    lam, G = data.lame
    mesh = data.mesh
    centre = cell_stress(mesh, phi.ravel(), lam, G, at="centroid")[:, 0, :]
    at_nodes = von_mises(cell_stress(mesh, phi.ravel(), lam, G, at="nodes"))  # (n_cells, nl)
    cells = np.asarray(mesh.cells)
    total = np.bincount(cells.ravel(), weights=at_nodes.ravel(), minlength=mesh.n_nodes)
    count = np.bincount(cells.ravel(), minlength=mesh.n_nodes)
    return {"phi": phi, "stress": centre, "von_mises_cell": von_mises(centre),
            "von_mises_node": total / np.maximum(count, 1)}


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
    points = np.column_stack([mesh.points, np.zeros(mesh.n_nodes)])
    point_data, cell_data = {}, {}
    for name, mode in data.modes.items():
        f = mode_fields(data, mode)
        point_data[f"{name}_phi"] = np.column_stack([f["phi"], np.zeros(mesh.n_nodes)])
        point_data[f"{name}_von_mises"] = f["von_mises_node"]
        sxx, syy, sxy, szz = f["stress"].T
        zero = np.zeros_like(sxx)
        tensor = np.column_stack([sxx, sxy, zero, sxy, syy, zero, zero, zero, szz])
        cell_data[f"{name}_stress"] = [tensor]
        cell_data[f"{name}_von_mises"] = [f["von_mises_cell"]]
    # the boundary edges as a second cell block, tagged 1, 2, ... by edge name (field data
    # names the tags), so that ParaView can select the contact and Dirichlet edges
    names = sorted(mesh.edges)
    # (a second-order facet end, end, mid as two 2-node lines: every reader takes those)
    facets = [np.asarray(mesh.edges[n]) for n in names]
    facets = [f if f.shape[1] == 2 else f[:, [0, 2, 2, 1]].reshape(-1, 2) for f in facets]
    edge_cells = np.concatenate(facets) if facets else np.zeros((0, 2), dtype=np.int64)
    tags = np.concatenate([np.full(len(f), i + 1) for i, f in enumerate(facets)]) if facets \
        else np.zeros(0, dtype=np.int64)
    blocks = [(_MESHIO_CELL[mesh.element], np.asarray(mesh.cells))]
    if fmt == "vtu":  # (XDMF readers take no mixed second-order topology: cells only there)
        blocks.append(("line", edge_cells))
        cell_data = {name: [values[0], np.zeros((len(edge_cells),) + np.shape(values[0])[1:])]
                     for name, values in cell_data.items()}
        cell_data["boundary_tag"] = [np.zeros(mesh.n_cells, dtype=np.int64), tags]
    field_data = {n: np.array([i + 1, 1]) for i, n in enumerate(names)}
    field_data.update({"critical_positive": np.atleast_1d(np.asarray(data.positive, float)),
                       "critical_negative": np.atleast_1d(np.asarray(data.negative, float)),
                       "nu": np.array([float(data.attrs["nu"])])})
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

    arrays = "".join(f'<DataArray type="Float64" Name="{n}" NumberOfTuples="{len(v)}" '
                     f'format="ascii">{numbers(v)}</DataArray>' for n, v in fields.items())
    data, anchor = path.read_bytes(), b"<UnstructuredGrid>"
    at = data.find(anchor)
    if at >= 0:
        at += len(anchor)
        path.write_bytes(data[:at] + f"<FieldData>{arrays}</FieldData>".encode() + data[at:])
