"""Units: the critical coefficients do not depend on E, on the density or on the length scale.

The eigenproblem (3.2) and the sliding pencil are solved at E = density = 1 (the schema takes
E and density in [1e-300, 1e300]); frequencies, kappa, contact forces and stresses are scaled
back. A body scaled by L (coordinates, sizes, mesh size) has the same coefficients; its static
solutions follow the physics: displacements scale with L and with force / E, forces with the
loads. Every friction value (critical coefficients, path events, verify's branch) is
invariant."""

from __future__ import annotations

import math

import numpy as np
import pytest
from helpers import four_triangles_alpha, one_triangle_alpha, run_cli

from critfric.case.schema import from_dict, load_case
from critfric.errors import CaseError
from critfric.files.export import mode_fields, read_solve
from critfric.files.results import write_result
from critfric.files.sweepfile import read_sweep
from critfric.multiplicity.enumeration import solutions_of_case
from critfric.multiplicity.path import path_case
from critfric.multiplicity.verify import verify
from critfric.solve import solve_case
from critfric.stability import stability_case
from critfric.sweep.runner import make_grid, run_sweep

MODULI = (1e-300, 1e-150, 1.0, 1e150, 1e300)
LENGTHS = (1e-6, 1e6)
REL = 1e-12


def close(a, b, rel=REL) -> bool:
    a, b = np.asarray(a, dtype=float), np.asarray(b, dtype=float)
    return a.shape == b.shape and bool(np.all(np.abs(a - b) <= rel * np.abs(b)))


def near(a, b, rel) -> bool:
    """Vectors equal to ``rel`` of their largest entry (round-off entries near 0 differ)."""
    a, b = np.asarray(a, dtype=float), np.asarray(b, dtype=float)
    return a.shape == b.shape and bool(np.abs(a - b).max() <= rel * np.abs(b).max())


def rectangle(L=1.0, E=1.0, element="P1", **more) -> dict:
    """A 1 x 0.5 rectangle scaled by L, clamped on top, in contact on the bottom."""
    case = {"geometry": {"shape": "rectangle", "width": 1.0 * L, "height": 0.5 * L},
            "material": {"E": E, "nu": 0.3}, "mesh": {"size": 0.25 * L, "element": element},
            "solve": {"count": 2}}
    for section, keys in more.items():
        case.setdefault(section, {}).update(keys)
    return case


# ------------------------------------------------------------------ the schema's range
@pytest.mark.parametrize("key", ["E", "density"])
def test_material_scales_are_taken_over_the_stated_range_and_refused_beyond(key):
    for value in (1e-300, 1e300):
        assert from_dict(rectangle(material={key: value})).material[key] == value
    for value in (1e-301, 1e301, 0.0, -1.0, math.inf):
        with pytest.raises(CaseError, match=rf"material\.{key}.*\[1e-300, 1e\+300\]"):
            from_dict(rectangle(material={key: value}))


def test_the_cli_names_the_key_and_the_range(tmp_path):
    case = tmp_path / "big.toml"
    case.write_text('[geometry]\nshape = "square"\n[mesh]\nsize = 0.5\n[material]\nE = 1e301\n')
    out = run_cli("solve", case, "-o", tmp_path / "big.h5")
    assert out.exit_code == 2
    assert "material.E" in out.output and "1e+301" in out.output and "1e+300" in out.output


# ------------------------------------------------------------------ solve (2D, 3D)
@pytest.mark.parametrize("element", ["P1", "P2"])
def test_solve_gives_the_E_1_coefficients_at_any_E(element):
    ref = solve_case(rectangle(element=element))
    assert len(ref.positive) == 2
    for E in MODULI:
        r = solve_case(rectangle(E=E, element=element))
        assert close(r.positive, ref.positive) and close(r.negative, ref.negative), E
        assert r.E == E
        # the modes' contact forces are those of the case's E
        assert near(r.modes[0]["theta_n"] / E, ref.modes[0]["theta_n"], 1e-9)


@pytest.mark.parametrize("element", ["P1", "P2"])
def test_solve_gives_the_same_coefficients_for_a_body_scaled_in_length(element):
    ref = solve_case(rectangle(element=element)).positive
    for L in LENGTHS:
        assert close(solve_case(rectangle(L, element=element)).positive, ref, 1e-12), L


def box(L=1.0, E=1.0) -> dict:
    return {"geometry": {"shape": "box", "size": [1.0 * L, 0.5 * L, 1.0 * L]},
            "boundary": {"contact": ["y0"], "dirichlet": ["y1"]},
            "material": {"E": E}, "mesh": {"element": "P1", "size": 0.5 * L}}


def test_a_3d_box_gives_the_same_coefficient_at_any_E_and_length():
    ref = solve_case(box()).positive
    assert len(ref)
    for E in (1e-300, 1e300):
        assert close(solve_case(box(E=E)).positive, ref), E
    for L in LENGTHS:
        assert close(solve_case(box(L)).positive, ref), L


def test_the_paper_cases_keep_their_closed_forms_at_extreme_E_and_lengths():
    for name, exact in (("one-triangle", one_triangle_alpha(0.3)),
                        ("four-triangles", four_triangles_alpha(0.3))):
        case = load_case(name)
        for E in (1e-300, 1e300):
            r = solve_case(case.with_overrides({"material.E": E}))
            assert r.critical == pytest.approx(exact, rel=1e-12), (name, E)
        for L in LENGTHS:  # the inline nodes scaled
            nodes = (np.asarray(case.geometry["nodes"]) * L).tolist()
            r = solve_case(case.with_overrides({"geometry.nodes": nodes}))
            assert r.critical == pytest.approx(exact, rel=1e-12), (name, L)


def test_a_sweep_gives_the_E_1_rows_at_any_E(tmp_path):
    rows = []
    for E in (1.0, 1e-300, 1e300):
        case = from_dict(rectangle(E=E))
        grid = make_grid(case, nu="0.2,0.3", size="0.5")
        run_sweep(case, grid, output=tmp_path / f"{E:g}.h5", jobs=1)
        rows.append(sorted((r["nu"], *r["positive"], *r["negative"]) for r in
                           read_sweep(tmp_path / f"{E:g}.h5")["rows"]))
    assert len(rows[0]) == 2
    for got in rows[1:]:
        assert close(got, rows[0])


# ------------------------------------------------------------------ stability
def unstable(L=1.0, E=1.0, density=1.0) -> dict:
    return rectangle(L, E, material={"density": density}, mesh={"size": 0.5 * L},
                     stability={"steps": 10, "modes": 4})


def test_stability_thresholds_do_not_depend_on_E_density_or_length():
    ref = stability_case(unstable())
    assert ref.flutter["positive"] is not None
    for E, rho in ((1e-300, 1.0), (1.0, 1e300), (1e150, 1e-150)):
        r = stability_case(unstable(E=E, density=rho))
        for kind in ("positive", "negative"):
            assert close(r.flutter[kind], ref.flutter[kind]), (E, rho)
            assert close(r.divergence[kind], ref.divergence[kind]), (E, rho)
        # frequencies scale as sqrt(E / density), kappa = omega^2 as E / density
        factor = math.sqrt(E) / math.sqrt(rho)
        assert close(r.frequencies / factor, ref.frequencies), (E, rho)
        assert close(r.flutter_kappa["positive"] / (E / rho), ref.flutter_kappa["positive"])
    for L in LENGTHS:  # frequencies as 1 / L
        r = stability_case(unstable(L))
        assert close(r.flutter["positive"], ref.flutter["positive"], 1e-9), L
        assert close(r.frequencies * L, ref.frequencies, 1e-9), L


def test_stability_refuses_squared_frequencies_beyond_the_floats():
    with pytest.raises(CaseError, match=r"material\.density.*E / density"):
        stability_case(unstable(E=1e300, density=1e-300))


# ------------------------------------------------------------------ the static problem
def pressed(E=1.0, force=1.0, L=1.0) -> dict:
    """A square of side L under its own weight: body force (0.3, -1) x force / L (forces
    per unit area: the same stresses at every L), no prescribed displacement, U^r = 0."""
    return {"geometry": {"shape": "square", "side": L}, "material": {"E": E},
            "mesh": {"size": 0.25 * L},
            "load": {"friction": 0.5, "body_force": [0.3 * force / L, -force / L]},
            "path": {"parameter": "friction", "range": [0.0, 2.0]}}


def events(result) -> list[tuple[str, float]]:
    return [(e.kind, e.value) for e in result.events]


def at(result, value):
    """The point of the first curve nearest the parameter value ``value``."""
    return min(result.curves[0].points, key=lambda q: abs(q.value - value))


def test_path_events_do_not_depend_on_E_the_size_of_the_loads_or_the_length():
    """Fixed loads: the displacements scale as 1 / E, the friction of every event stays; the
    loads scaled (by 1e-99 ... 1e99): the solutions scale with them (U^r = 0), events stay."""
    ref = path_case(pressed())
    assert len(ref.events) >= 4
    kinds = [k for k, _ in events(ref)]
    variants = [{"E": 1e-100}, {"E": 1e100}, {"force": 1e-99}, {"force": 1e99},
                {"E": 1e100, "force": 1e99}, *({"L": L} for L in LENGTHS)]
    for v in variants:
        r = path_case(pressed(**v))
        assert [k for k, _ in events(r)] == kinds, v
        assert close([t for _, t in events(r)], [t for _, t in events(ref)], 1e-10), v
        force = v.get("force", 1.0) * v.get("L", 1.0)  # nodal forces: stress x length
        a, b = at(r, 0.1), at(ref, 0.1)  # all slipping there
        assert near(a.Ut / (force / v.get("E", 1.0)), b.Ut, 1e-8) and near(a.X / force, b.X, 1e-8)


def test_a_load_path_with_loads_scaled_with_E_is_the_same_path():
    """unit-square's load path (prescribed displacements): E scales the forces only."""
    base = load_case("unit-square").with_overrides({"mesh.size": 0.25})
    ref = path_case(base)
    for E in (1e-300, 1e300):
        r = path_case(base.with_overrides({"material.E": E}))
        assert [k for k, _ in events(r)] == [k for k, _ in events(ref)]
        assert close([t for _, t in events(r)], [t for _, t in events(ref)], 1e-10), E
        a, b = r.curves[0].points[-1], ref.curves[0].points[-1]
        assert near(a.Ut, b.Ut, 1e-8) and near(a.X / E, b.X, 1e-8)


def test_solutions_and_verify_do_not_depend_on_E():
    ref = [len(e.solutions) for e in solutions_of_case(from_dict(pressed()), [0.3, 1.0])]
    for E in (1e-100, 1e100):
        got = solutions_of_case(from_dict(pressed(E=E)), [0.3, 1.0])
        assert [len(e.solutions) for e in got] == ref
    square = rectangle(mesh={"size": 0.5})
    v1 = verify(from_dict(square))
    assert v1.passed
    for E in (1e-300, 1e300):
        v = verify(from_dict(rectangle(E=E, mesh={"size": 0.5})))
        assert v.passed and close(v.critical.friction, v1.critical.friction)
        assert close(v.critical.delta0, v1.critical.delta0, 1e-9)
        assert near(v.critical.points[0].X / E, v1.critical.points[0].X, 1e-9)


def test_an_export_at_E_1e300_has_finite_stresses(tmp_path):
    """Stresses and von Mises are computed at E = 1 and scaled (squares of 1e300 overflow)."""
    fields = []
    for E in (1.0, 1e300):
        path = write_result(solve_case(rectangle(E=E)), tmp_path / f"{E:g}.h5")
        data = read_solve(path)
        fields.append(mode_fields(data, next(iter(data.modes.values()))))
    for key in ("stress", "von_mises_cell", "von_mises_node", "contact_force"):
        assert np.all(np.isfinite(fields[1][key])), key
        assert near(fields[1][key] / 1e300, fields[0][key], 1e-9), key


def test_forces_whose_displacements_leave_the_floats_are_refused():
    for E, force in ((1e300, 1.0), (1e-300, 1.0), (1e-300, 1e99)):
        with pytest.raises(CaseError, match=r"load.*displacements of about"):
            path_case(pressed(E=E, force=force))
