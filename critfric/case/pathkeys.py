"""The consistency of the loads: ``[load]`` and ``[path]`` (``critfric path``), whose second
load L1 (``[path] load``) has the keys of ``[load]`` that describe a load."""

from __future__ import annotations

from ..errors import CaseError

PARAMETERS = ("friction", "load")  # as critfric.multiplicity.pathresult.PARAMETERS
STARTS = ("auto", "newton", "enumerate")
LOAD_KEYS = ("traction", "body_force", "points", "displacement")


def check_loads(s: dict, names: set | None, source: str) -> None:
    """[load] and [path] load on edges that exist and carry the right condition; [path] keys
    that fit together. ``s``: the checked sections; ``names``: the edge names (None: those of
    a gmsh file, checked when it is read)."""
    path = s["path"]
    check_load(s["load"], s, names, source, "load")
    if path["load"] is not None:
        check_load(path["load"], s, names, source, "path.load")
    elif path["parameter"] == "load":
        raise CaseError("missing; allowed: a load path needs the second load L1 of L0 + t L1 "
                        "(L0: the load of [load]): a table [path.load] with one or more of "
                        + ", ".join(LOAD_KEYS), file=source, key="path.load")
    if path["parameter"] == "friction" and path["range"] is not None and path["range"][0] < 0:
        raise CaseError(f"got {path['range']}; allowed: [a, b] with 0 <= a < b (a friction "
                        "coefficient is not negative)", file=source, key="path.range")


def check_load(load: dict, s: dict, names: set | None, source: str, key: str) -> None:
    """A load's edges exist and carry the right condition; its node indices exist (inline
    meshes). ``key``: its dotted name in messages (load, path.load)."""
    bnd, geo = s["boundary"], s["geometry"]
    for name in load["traction"] or {}:
        if (names is not None and name not in names) or name in bnd["contact"] + bnd["dirichlet"]:
            free = sorted((names or set()) - set(bnd["contact"]) - set(bnd["dirichlet"]))
            raise CaseError(f"got edge {name!r}; allowed: a traction-free edge ("
                            + (", ".join(free) or "none") + ")", file=source,
                            key=f"{key}.traction")
    for name in load["displacement"] or {}:
        if name not in bnd["dirichlet"]:
            raise CaseError(f"got edge {name!r}; allowed: a Dirichlet edge ("
                            + ", ".join(bnd["dirichlet"]) + ")", file=source,
                            key=f"{key}.displacement")
    for i, point in enumerate(load["points"] or []):
        if "node" in point and (geo["shape"] != "mesh" or point["node"] >= len(geo["nodes"])):
            allowed = (f"a node index < {len(geo['nodes'])}" if geo["shape"] == "mesh" else
                       "at = [x, y] (node numbers of generated meshes are not stable)")
            raise CaseError(f"got node = {point['node']}; allowed: {allowed}", file=source,
                            key=f"{key}.points.{i}")
