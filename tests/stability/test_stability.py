"""Flutter and divergence of steady sliding: a closed form, the friction-0 and
static limits, an independent dense check of the flutter onset, symmetry, files and CLI."""

from __future__ import annotations

import json

import h5py
import numpy as np
import pytest
import scipy.linalg as la
import scipy.sparse as sp
from helpers import case_pencil, run_cli
from threadpoolctl import threadpool_limits

from critfric.case.schema import load_case
from critfric.fem.assembly import assemble_mass, lame
from critfric.solve import prepare, solve_case
from critfric.stability import analysis, fold, locus, stability_case
from critfric.stability.pencil import SlidingPencil
from critfric.stability.sharpen import sharpen


# ----------------------------------------------------------------- a two-DOF closed form
def two_dof(k1, k2, a, b) -> SlidingPencil:
    """L = [[k1 - kappa, f a], [f b, k2 - kappa]]: det = (k1 - kappa)(k2 - kappa) - f^2 a b.

    kappa = (k1 + k2)/2 +- sqrt(((k1 - k2)/2)^2 + f^2 a b). With a b < 0 the two roots meet
    at f* = |k1 - k2| / (2 sqrt(-a b)), kappa* = (k1 + k2)/2 (flutter); with a b > 0 they
    stay real and one crosses 0 at f^2 = k1 k2 / (a b) (divergence, never flutter)."""
    eye = sp.identity(2, format="csr")
    Knr = sp.csr_matrix(np.array([[0.0, -a], [-b, 0.0]]))
    return SlidingPencil(system=None, state=None, kept=np.arange(2), slip=np.arange(2),
                         Krr=sp.csr_matrix(np.diag([k1, k2])), Mrr=eye, Knr=Knr,
                         Mnr=sp.csr_matrix((2, 2)), G=eye)


@pytest.mark.parametrize("k1, k2, a, b", [(1.0, 3.0, 2.0, -0.5), (4.0, 2.5, -1.0, 3.0)])
def test_two_dof_coalescence_closed_form(k1, k2, a, b):
    pencil = two_dof(k1, k2, a, b)
    exact = abs(k1 - k2) / (2 * np.sqrt(-a * b))
    red = locus.reduce(pencil, 2)
    for sign in (1, -1):
        branches = locus.follow(red, 2, sign * np.linspace(0, 3 * exact, 61))
        guess = locus.locate_flutter(red, branches)
        assert guess is not None and abs(guess.friction - sign * exact) < 1e-3 * exact
        found = fold.find_fold(pencil, guess.friction, guess.kappa, guess.right, guess.left)
        assert found.friction == pytest.approx(sign * exact, rel=1e-12)
        assert found.kappa == pytest.approx((k1 + k2) / 2, rel=1e-12)


def test_two_dof_divergence_is_not_flutter():
    k1, k2, a, b = 1.0, 3.0, 2.0, 0.5  # a b > 0: real roots, one crosses 0 at f = sqrt(3)
    pencil = two_dof(k1, k2, a, b)
    red = locus.reduce(pencil, 2)
    branches = locus.follow(red, 2, np.linspace(0, 4, 81))
    assert locus.locate_flutter(red, branches) is None
    assert not locus.is_complex(branches.kappa).any()
    crossing = branches.friction[np.argmax(branches.kappa[:, 0].real < 0)]
    assert np.sqrt(k1 * k2 / (a * b)) <= crossing < np.sqrt(k1 * k2 / (a * b)) + 0.05


# ------------------------------------------------------------------------- real bodies
@pytest.fixture(scope="module")
def square():
    """The unit square, P1, h = 0.1: followed on the reduced model (above FULL_MAX DOFs)."""
    case = load_case("unit-square", overrides={"mesh.size": 0.1, "stability.modes": 6})
    return case, stability_case(case)


@pytest.fixture(scope="module")
def square_pencil(square):
    """The all-slipping pencil of ``square``'s mesh (nu = 0.3)."""
    return case_pencil(square[0])


def _dense_pencil(case):
    """An independent assembly of the sliding pencil with multipliers, by dense blocks:
    [[K - kappa M, -(B_n + f B_t)], [-B_n^T, 0]] over the free DOFs (xy basis)."""
    prep = prepare(case)
    s = prep.system
    K = s.stiffness(*lame(1.0, case.material["nu"])).toarray()
    M = s.restrict(assemble_mass(prep.mesh)).toarray()
    m, p = len(K), s.n_contact
    Bn = np.zeros((m, p))
    Bt = np.zeros((m, p))
    Bn[s.cn, np.arange(p)] = 1.0
    Bt[s.ct, np.arange(p)] = 1.0

    def eigenvalues(f):
        A = np.block([[K, -(Bn + f * Bt)], [-Bn.T, np.zeros((p, p))]])
        B = np.block([[M, np.zeros((m, p))], [np.zeros((p, m + p))]])
        w = la.eigvals(A, B)
        return w[np.isfinite(w)]

    return K, M, Bn, eigenvalues


def test_frequencies_at_zero_friction_are_the_constrained_vibrations(square):
    case, result = square
    K, M, Bn, _ = _dense_pencil(case)
    keep = np.flatnonzero(Bn.sum(axis=1) == 0)  # slipping normal DOFs clamped
    omega2 = la.eigh(K[np.ix_(keep, keep)], M[np.ix_(keep, keep)], eigvals_only=True)
    assert np.allclose(result.frequencies, np.sqrt(omega2[:6]), rtol=1e-10)


def test_divergence_is_the_static_critical_coefficient(square):
    case, result = square
    static = solve_case(case)
    assert result.divergence["positive"] == pytest.approx(static.positive[0], rel=1e-12)
    assert result.divergence["negative"] == pytest.approx(static.negative[0], rel=1e-12)
    assert result.first("positive") == "flutter"


def test_thresholds_are_reported_within_the_friction_range_only(square):
    """Divergence at +-1.95 is outside [-0.05, 1]: null, with a note; flutter at +-0.064 is
    the first instability, and none is followed below 0 on [0, 1]."""
    case, _ = square
    near = stability_case(case.with_overrides({"stability.friction": [-0.05, 1.0]}))
    assert near.divergence == {"positive": None, "negative": None}
    assert near.flutter["positive"] is not None and near.flutter["negative"] is not None
    assert near.first("positive") == near.first("negative") == "flutter"
    assert any("outside the friction range" in n for n in near.notes)
    up = stability_case(case.with_overrides({"stability.friction": [0.0, 1.0]}))
    assert up.divergence["negative"] is None and up.flutter["negative"] is None
    assert up.first("negative") is None


def test_flutter_onset_against_an_independent_dense_pencil(square):
    case, result = square
    *_, eigenvalues = _dense_pencil(case)
    for d in ("positive", "negative"):
        f, kappa = result.flutter[d], result.flutter_kappa[d]
        assert (f > 0) == (d == "positive")

        def near(friction, kappa=kappa):
            w = eigenvalues(friction)
            return w[np.argsort(np.abs(w - kappa))[:2]]

        before, after = near(f * (1 - 1e-7)), near(f * (1 + 1e-7))
        assert np.all(np.abs(before.imag) <= 1e-9 * abs(kappa))  # two real, about to meet
        assert np.abs(after.imag).min() > 1e-7 * abs(kappa)  # a complex pair
        assert np.allclose(before.real, kappa, rtol=1e-4)
        # and nothing flutters earlier among the followed modes
        lowest = eigenvalues(f * 0.999)
        lowest = lowest[np.argsort(np.abs(lowest))][:8]
        assert np.all(np.abs(lowest.imag) <= 1e-9 * np.abs(lowest))


def test_symmetric_body_gives_symmetric_thresholds():
    result = stability_case("unit-square", overrides={
        "mesh.size": 0.1, "mesh.element": "Q1", "mesh.structured": True, "stability.modes": 6})
    assert result.flutter["positive"] == pytest.approx(-result.flutter["negative"], rel=1e-9)
    assert result.divergence["positive"] == pytest.approx(-result.divergence["negative"],
                                                          rel=1e-9)
    assert result.flutter["positive"] == pytest.approx(0.0744918684105, rel=1e-9)


def test_density_scales_frequencies_not_thresholds(square):
    case, result = square
    heavy = stability_case(case.with_overrides({"material.density": 4.0}))
    assert np.allclose(heavy.frequencies, result.frequencies / 2, rtol=1e-10)
    assert heavy.flutter["positive"] == pytest.approx(result.flutter["positive"], rel=1e-9)


def test_a_contact_state_with_stuck_nodes():
    """Stuck and free nodes on Gamma_C: friction-0 frequencies are those with stuck nodes
    clamped and slipping nodes held normally, divergence the static coefficient."""
    case = load_case("unit-square", overrides={"mesh.size": 0.125, "stability.modes": 4})
    case = case.with_overrides({"contact.rules": [{"from": 0.0, "to": 0.3, "status": "stuck"}]})
    result = stability_case(case)
    static = solve_case(case)
    assert result.divergence["positive"] == pytest.approx(static.positive[0], rel=1e-12)
    from critfric.solvers.from_case import contact_state

    pencil = case_pencil(case, lambda system: contact_state(case, system))
    omega2 = la.eigh(pencil.Krr.toarray(), pencil.Mrr.toarray(), eigvals_only=True)
    assert np.allclose(result.frequencies, np.sqrt(omega2[:4]), rtol=1e-10)


# ---------------------------------------------------------------------- files and CLI
def test_cli_json_file_and_plot(tmp_path):
    out = tmp_path / "s.h5"
    res = run_cli("stability", "four-triangles", "--json", "-o", out, "--plot")
    assert res.exit_code == 0, res.output
    summary = json.loads(res.stdout)
    assert set(summary) >= {"flutter", "divergence", "frequencies", "n_dofs", "element", "h",
                            "seconds"}
    assert summary["divergence"]["positive"] == pytest.approx(1.8358568491, rel=1e-9)
    assert len(summary["frequencies"]) == 4  # 4 DOFs once the normal DOFs are held
    assert (tmp_path / "s_locus.png").exists()
    from critfric.files.stabilityfile import read_stability_summary

    assert read_stability_summary(out)["divergence"] == summary["divergence"]
    res = run_cli("stability", "four-triangles", "-o", out)
    assert res.exit_code == 2 and "--force" in res.output


@pytest.mark.parametrize("bad", ["1:2", "a:b", "0", "-1:0:2"])
def test_bad_friction_range(bad, tmp_path):
    res = run_cli("stability", "four-triangles", "--friction", bad, "-o", tmp_path / "x.h5")
    assert res.exit_code == 2 and "friction" in res.output
    assert not (tmp_path / "x.h5").exists()


def test_a_request_of_hours_is_refused_up_front(tmp_path, monkeypatch):
    # 200 modes, 101 contact nodes: a reduced model of 513, 5000 steps each way ~3e12 flops;
    # refused before the static stage factors anything
    def no_factorization(*args, **kwargs):
        raise AssertionError("factored before the refusal")

    monkeypatch.setattr(analysis.eigen, "solve", no_factorization)
    res = run_cli("stability", "unit-square", "--size", "0.01", "--modes", "200",
                  "--steps", "5000", "-o", tmp_path / "x.h5")
    assert res.exit_code == 2 and "stability.steps" in res.output, res.output
    assert not (tmp_path / "x.h5").exists()
    res = run_cli("stability", "four-triangles", "--steps", "5001", "-o", tmp_path / "x.h5")
    assert res.exit_code == 2 and "steps" in res.output, res.output


def test_table_lists_stability_files_in_their_own_table(tmp_path):
    out = tmp_path / "s.h5"
    assert run_cli("stability", "four-triangles", "-o", out).exit_code == 0
    res = run_cli("table", out, "--json")
    assert res.exit_code == 0, res.output
    (row,) = json.loads(res.stdout)
    assert row["kind"] == "stability" and row["file"] == str(out)
    assert row["flutter"]["positive"] == pytest.approx(1.3263339950523856, rel=1e-9)
    text = run_cli("table", out).stdout
    assert "flutter > 0" in text and "1.326334" in text and "flutter" in text.split()[-2:]


def test_crafted_stability_file_is_refused(tmp_path):
    out = tmp_path / "s.h5"
    assert run_cli("stability", "four-triangles", "-o", out).exit_code == 0
    with h5py.File(out, "a") as f:
        del f["stability/kappa"]
        f["stability/kappa"] = np.zeros((3, 99), dtype=complex)
    for command in (["plot", out], ["table", out]):
        res = run_cli(*command)
        assert res.exit_code == 2, res.output


@pytest.mark.slow
def test_sweep_of_flutter_thresholds(tmp_path):
    from critfric.sweep.runner import make_grid, run_sweep

    case = load_case("unit-square", overrides={"stability.modes": 6})
    grid = make_grid(case, nu="0.25,0.3", size="0.25", element="P1", quantity="flutter")
    sweep = run_sweep(case, grid, output=tmp_path / "f.h5", jobs=1)
    for row in sweep.rows:
        direct = stability_case(case, overrides={"mesh.size": row["size"],
                                                 "material.nu": row["nu"]})
        assert row["positive"] == [pytest.approx(direct.flutter["positive"], rel=1e-10)]
        assert row["negative"] == [pytest.approx(direct.flutter["negative"], rel=1e-10)]
    res = run_cli("sweep", "unit-square", "--quantity", "bogus", "-o", tmp_path / "g.h5")
    assert res.exit_code == 2 and "--quantity" in res.output
    table = run_cli("table", tmp_path / "f.h5").output  # the values say what they are
    assert "flutter (lowest > 0)" in table and "critical" not in table


@pytest.mark.parametrize("basis", ["contact", "modal"])
def test_both_reduced_bases_lead_to_the_same_onset(square, square_pencil, basis):
    """The reduced model only locates: either basis, Newton ends on the same coalescence."""
    _, result = square
    pencil = square_pencil
    red = locus.reduce(pencil, 6, basis=basis)
    assert red.V.shape[1] < pencil.size
    for d, end in (("positive", 2.0), ("negative", -2.0)):
        guess = locus.locate_flutter(red, locus.follow(red, 6, np.linspace(0, end, 201)))
        assert guess.friction == pytest.approx(result.flutter[d], rel=1e-4)
        found = fold.find_fold(pencil, guess.friction, guess.kappa, guess.right, guess.left)
        assert found.friction == pytest.approx(result.flutter[d], rel=1e-11)
        assert found.steps <= 5


@pytest.mark.slow
def test_flutter_threshold_converges_with_the_mesh():
    """A 2 x 1 rectangle on its long side, P2 on structured meshes h = 0.2, 0.1, 0.05: the
    threshold converges (differences shrink by more than 3 each halving; measured 0.2418,
    0.2522, 0.2544), and Q1 at h = 0.05 lies within the last P2 difference's reach."""
    case = {"geometry": {"shape": "rectangle", "width": 2.0, "height": 1.0},
            "mesh": {"size": 0.2, "element": "P2", "structured": True},
            "stability": {"modes": 4, "friction": [-1.0, 1.0]}}
    values = [stability_case(case, overrides={"mesh.size": h}).flutter["positive"]
              for h in (0.2, 0.1, 0.05)]
    d1, d2 = values[1] - values[0], values[2] - values[1]
    assert 0 < d2 < d1 / 3
    limit = values[2] + d2 / (d1 / d2 - 1)  # Richardson with the observed ratio
    assert limit == pytest.approx(0.2550, abs=5e-4)


def test_sharpened_guess_needs_one_newton_step(square, square_pencil):
    """The reduced model, enlarged at its coalescence until it stops moving, lands within
    Newton's tolerance of the full pencil's onset: Newton confirms it in one step."""
    _, result = square
    pencil = square_pencil
    assert result.newton_steps == {"positive": 1, "negative": 1}
    red = locus.reduce(pencil, 6)
    guess = locus.locate_flutter(red, locus.follow(red, 6, np.linspace(0, 2.0, 201)))
    sharp = sharpen(red, pencil, locus.factor_of(pencil, "scipy", None), [guess])[0]
    assert abs(guess.friction - result.flutter["positive"]) > 1e-7  # the model alone: off
    assert sharp.friction == pytest.approx(result.flutter["positive"], rel=1e-9)
    found = fold.find_fold(pencil, sharp.friction, sharp.kappa, sharp.right, sharp.left)
    assert found.steps == 1 and found.friction == pytest.approx(sharp.friction, rel=1e-9)


def test_newton_takes_the_sharpened_models_jacobian_only_where_it_agrees(square_pencil,
                                                                         monkeypatch):
    """From a sharpened guess, the first Newton step takes its Jacobian's second row from the
    sharpened model (no solves for it) and lands where the solved row leads (the row only
    scales a correction of ~1e-10); a model whose first row is off is not taken."""
    pencil = square_pencil
    red = locus.reduce(pencil, 6)
    guess = locus.locate_flutter(red, locus.follow(red, 6, np.linspace(0, 2.0, 201)))
    sharp = sharpen(red, pencil, locus.factor_of(pencil, "scipy", None), [guess])[0]
    assert sharp.jacobian is not None and sharp.jacobian.shape == (2, 2)
    solved = []
    original = fold._second_row

    def counted(*args):
        solved.append(len(args[4]))  # v: the full pencil's, or the small model's
        return (yield from original(*args))

    monkeypatch.setattr(fold, "_second_row", counted)
    start = (sharp.friction, sharp.kappa, sharp.right, sharp.left)
    alone = fold.find_fold(pencil, *start)
    assert solved == [pencil.size] and alone.steps == 1
    solved.clear()
    given = fold.find_fold(pencil, *start, sharp.jacobian)
    assert solved == [] and given.steps == 1
    assert given.friction == pytest.approx(alone.friction, rel=1e-12)
    assert given.kappa == pytest.approx(alone.kappa, rel=1e-10)
    off = sharp.jacobian.copy()
    off[0] *= 1.01  # its first row 1 % from the full pencil's: not the same Jacobian
    fold.find_fold(pencil, *start, off)
    assert solved == [pencil.size]


def test_root_locus_labels_do_not_depend_on_rounding(square_pencil):
    """QZ gives a complex pair as two quotients that are conjugate only to rounding; made
    exactly conjugate (Im > 0 first), which branch takes which half is the matching rule's
    alone: the same labels from the model perturbed at the rounding level (PARDISO's
    parallel solves round differently from run to run), the same values to 1e-9."""
    pencil = square_pencil
    red = locus.reduce(pencil, 6)
    kappa, _, _ = red.eigenvalues(0.5, vectors=True)
    pairs = np.flatnonzero(kappa.imag > 0)
    assert len(pairs) and np.array_equal(kappa[pairs + 1], np.conj(kappa[pairs]))
    grid = np.linspace(0, 2.0, 201)
    reference = locus.follow(red, 6, grid).kappa
    assert locus.is_complex(reference).any()
    rng = np.random.default_rng(3)
    for _ in range(6):
        noisy = locus.Reduced(red.V, *(m * (1 + 4e-16 * rng.standard_normal(m.shape))
                                       for m in (red.A0, red.A1, red.B0, red.B1)),
                              red.omega2, red.modes0)
        kappa = locus.follow(noisy, 6, grid).kappa
        np.testing.assert_allclose(kappa, reference, rtol=1e-9, atol=1e-9 * abs(reference).max())


def test_openblas_threads_follow_the_model_size_and_are_given_back():
    """Dense eigenproblems below size 400 run on one OpenBLAS thread, larger ones on the
    count the caller had (a sweep worker's one thread is not raised); a run gives the
    caller's count back."""
    eye = lambda n: np.eye(n)
    with threadpool_limits(limits=1):  # the most a test machine is sure to have
        for n, threads, inside in ((10, 2, 1), (400, 1, 1)):
            red = locus.Reduced(None, eye(n), eye(n), eye(n), eye(n), np.ones(n), eye(n),
                                threads=threads)
            with red.blas():
                assert locus.openblas_threads() == inside
        stability_case("four-triangles")
        assert locus.openblas_threads() == 1
    before = locus.openblas_threads()
    stability_case("four-triangles")
    assert locus.openblas_threads() == before


@pytest.mark.parametrize("few", [True, False])
@pytest.mark.parametrize("transpose", [False, True])
def test_block_products_written_in_place(few, transpose):
    """Block.product: b X (b^T X) into a column-major slice, through the few rows and columns
    where b has them, over all rows where not; the same numbers as the sparse product."""
    rng = np.random.default_rng(3)
    n = 400
    if few:  # nonzero rows and columns on a tenth of the DOFs (a friction block)
        rows, cols = rng.choice(n, 30, replace=False), rng.choice(n, 30, replace=False)
        b = sp.csr_matrix((rng.standard_normal(90), (rng.choice(rows, 90), rng.choice(cols, 90))),
                          shape=(n, n))
    else:
        b = sp.random(n, n, density=0.05, random_state=4, format="csr")
    block = locus.Block(b, symmetric=False)
    assert (block.sub is not None) == few
    X = rng.standard_normal((n, 3))
    out = np.full((n, 7), np.nan, order="F")
    block.product(X, out[:, 2:5], transpose)
    np.testing.assert_array_equal(out[:, 2:5], (b.T if transpose else b) @ X)
    assert np.isnan(out[:, [0, 1, 5, 6]]).all()
