"""Linear-solver backends and the Schur-complement eigen path agree with SciPy and with an
independent dense formulation, for every contact state (stuck, free and slipping nodes)."""

from __future__ import annotations

import time

import numpy as np
import pytest
import scipy.linalg as la
import scipy.sparse as sp
from helpers import CASES, run_python, square_case
from typer.testing import CliRunner

import critfric
from critfric.case import schema as case_module
from critfric.case.schema import load_case, loads_case
from critfric.cli.app import app
from critfric.errors import CaseError, SolverError
from critfric.fem.assembly import lame
from critfric.fem.contact import FREE, SLIP, STUCK
from critfric.solve import prepare
from critfric.solvers import backends as linsolve
from critfric.solvers import eigen, ordering
from critfric.solvers.eigen import ContactState
from critfric.solvers.pardiso import upper_triangle

AVAILABLE = linsolve.available_backends()


def backends():
    """Every backend; the ones missing here are skipped with the reason."""
    return [pytest.param(b, marks=pytest.mark.skipif(
        b not in AVAILABLE, reason=f"backend {b!r} not installed (pip install critfric[fast])"))
        for b in linsolve.BACKENDS]


@pytest.fixture(scope="module", params=["P1", "P2"])
def square(request):
    prep = prepare(loads_case(square_case(element=request.param, size=0.125)))
    return prep.system, prep.system.stiffness(*lame(1.0, 0.3))


def mixed_state(p: int) -> ContactState:
    """Stuck, free and slipping nodes mixed, slip signs of both kinds."""
    status = np.full(p, SLIP, dtype=np.int8)
    status[[0, p // 2]] = STUCK
    status[[1, 2, p - 1]] = FREE
    gamma = np.where(np.arange(p) % 3 == 0, -1.0, 1.0)
    return ContactState(status, gamma)


def pencil_reference(K, system, state):
    """Independent formulation: K_c Phi = alpha M Phi with M = E_t gamma R_n, dense QZ."""
    slip = np.flatnonzero(state.status == SLIP)
    stuck = np.flatnonzero(state.status == STUCK)
    elim = np.concatenate([system.cn[slip], system.cn[stuck], system.ct[stuck]])
    keep = np.setdiff1d(np.arange(K.shape[0]), elim)
    Kd = K.toarray()
    M = np.zeros((len(keep), len(keep)))
    rows = np.searchsorted(keep, system.ct[slip])
    M[rows] = state.gamma[slip, None] * Kd[np.ix_(system.cn[slip], keep)]
    w = la.eigvals(Kd[np.ix_(keep, keep)], M)
    return w[np.isfinite(w) & (np.abs(w) < 1e6)]


@pytest.mark.parametrize("backend", backends())
def test_factorize_and_schur_match_dense_algebra(backend):
    rng = np.random.default_rng(1)
    n = 60
    R = sp.random(n, n, density=0.1, random_state=2)
    A = (R @ R.T + 5 * sp.eye(n)).tocsr()
    b = rng.standard_normal((n, 3))
    f = linsolve.factorize(A, symmetric=True, backend=backend)
    assert f.backend == backend
    np.testing.assert_allclose(f.solve(b), np.linalg.solve(A.toarray(), b), rtol=1e-10)
    np.testing.assert_allclose(f.solve(b[:, 0]), np.linalg.solve(A.toarray(), b[:, 0]),
                               rtol=1e-10)
    N = (A + sp.random(n, n, density=0.05, random_state=3)).tocsr()
    g = linsolve.factorize(N, symmetric=False, backend=backend)
    np.testing.assert_allclose(g.solve(b), np.linalg.solve(N.toarray(), b), rtol=1e-9)
    index = np.array([50, 3, 17, 40, 8])  # unsorted on purpose
    sc = linsolve.schur(A, index, backend=backend)
    Ad = A.toarray()
    inner = np.setdiff1d(np.arange(n), index)
    S = Ad[np.ix_(index, index)] - Ad[np.ix_(index, inner)] @ np.linalg.solve(
        Ad[np.ix_(inner, inner)], Ad[np.ix_(inner, index)])
    np.testing.assert_allclose(sc.S, S, rtol=1e-10, atol=1e-12 * np.abs(S).max())
    xc = rng.standard_normal((len(index), 2))
    x = sc.extend(xc)
    np.testing.assert_array_equal(x[index], xc)
    np.testing.assert_allclose((Ad @ x)[index], S @ xc, rtol=1e-9)
    assert np.abs((Ad @ x)[inner]).max() < 1e-10 * np.abs(Ad @ x).max()
    np.testing.assert_allclose(sc.extend(xc[:, 1]), x[:, 1], rtol=1e-12)


@pytest.mark.parametrize("backend", backends())
def test_singular_matrix_is_a_solver_error(backend):
    for A in (np.diag([1.0, 2.0, 0.0, 3.0]), [[1.0, 1.0, 0.0], [1.0, 1.0, 0.0], [0, 0, 1.0]]):
        with pytest.raises(SolverError, match="singular"):
            linsolve.factorize(sp.csr_matrix(A), backend=backend).solve(np.ones(len(A)))


@pytest.mark.parametrize("backend", backends())
def test_every_path_of_every_backend_agrees_on_a_mixed_contact_state(square, backend):
    system, K = square
    state = mixed_state(system.n_contact)
    ref = pencil_reference(K, system, state)
    dense = eigen.solve(K, system, state, method="dense", count=2, backend=backend)
    arpack = eigen.solve(K, system, state, method="arpack", count=1, backend=backend)
    scipy = eigen.solve(K, system, state, method="dense", count=2, backend="scipy")
    assert dense.backend == arpack.backend == backend
    assert len(dense.alpha) == len(ref)
    for a in dense.alpha:  # the Schur path gives the whole spectrum of the pencil
        assert np.min(np.abs(ref - a)) <= 1e-8 * abs(a)
    np.testing.assert_allclose(dense.positive, scipy.positive, rtol=1e-9)
    np.testing.assert_allclose(dense.negative, scipy.negative, rtol=1e-9)
    np.testing.assert_allclose(arpack.positive[0], scipy.positive[0], rtol=1e-9)
    for mode in dense.modes:  # the mode obeys the contact state
        assert np.all(mode.phi[system.cn[state.status != FREE]] == 0.0)
        assert np.all(mode.phi[system.ct[state.status == STUCK]] == 0.0)
        assert np.abs(mode.X[state.status == FREE]).max() <= 1e-10 * np.abs(mode.X).max()
        assert mode.residual <= 1e-9


@pytest.mark.parametrize("backend", backends())
def test_shifted_pencil_with_each_backend(square, backend):
    system, K = square
    ref = eigen.solve(K, system, method="dense", count=1, backend="scipy").positive[0]
    near = eigen.solve(K, system, method="arpack", count=1, shift=ref + 0.2, backend=backend)
    assert near.method == "arpack-shift"
    np.testing.assert_allclose(near.positive[0], ref, rtol=1e-9)


@pytest.mark.parametrize("backend", backends())
def test_schur_path_finds_the_real_eigenvalue_behind_the_complex_cluster(backend):
    nu = 0.02  # the lowest real alpha lies beyond nearly imaginary ones: ARPACK at k = 2 misses it
    text = square_case(size=0.04, nu=nu, extra=f'backend = "{backend}"')
    d = critfric.solve_case(loads_case(text), overrides={"solve.method": "dense"})
    a = critfric.solve_case(loads_case(text), overrides={"solve.method": "arpack"})
    assert d.solver == "dense" and d.backend == backend
    assert d.positive[0] > 2 * (1 - nu) / (1 - 2 * nu)
    np.testing.assert_allclose(d.positive[0], a.positive[0], rtol=1e-9)


def test_auto_backend_is_named_in_the_result_and_the_file(tmp_path):
    r = critfric.solve_case(loads_case(square_case(size=0.25)))
    assert r.backend == AVAILABLE[0] and r.backend in linsolve.BACKENDS
    assert r.summary()["backend"] == r.backend
    path = critfric.write_result(r, tmp_path / "r.h5")
    assert critfric.read_summary(path)["backend"] == r.backend


@pytest.mark.parametrize("backend", backends())
def test_auto_takes_every_eigenvalue_on_every_backend(backend, monkeypatch):
    """One spectrum on every install: the Schur path, whatever the backend; ARPACK only
    beyond SCHUR_MAX_CONTACT contact nodes, and then it says how complete it is."""
    case = loads_case(square_case(size=0.1, extra=f'backend = "{backend}"\ncount = 2'))
    r = critfric.solve_case(case)
    assert r.solver == "dense" and r.backend == backend and r.complete
    monkeypatch.setattr(eigen, "SCHUR_MAX_CONTACT", 4)
    a = critfric.solve_case(case)
    assert a.solver.startswith("arpack") and a.complete == (a.solver == "arpack+explicit")
    np.testing.assert_allclose(a.positive[:2], r.positive[:2], rtol=1e-9)
    np.testing.assert_allclose(a.negative[:2], r.negative[:2], rtol=1e-9)


def test_backend_names_agree_between_schema_and_solvers():
    assert case_module.BACKENDS == ("auto",) + linsolve.BACKENDS


def test_unknown_backend_is_a_case_error_naming_the_key():
    with pytest.raises(CaseError, match=r"solve\.backend.*'mkl'|solve\.backend") as err:
        loads_case(square_case(extra='backend = "mkl"'))
    assert "scipy" in str(err.value)
    result = CliRunner().invoke(app, ["solve", "unit-square", "--backend", "nope"])
    assert result.exit_code == 2 and "solve.backend" in result.output


def test_a_backend_not_installed_is_a_case_error(monkeypatch):
    monkeypatch.setattr(linsolve, "pardiso_library", lambda: None)
    assert linsolve.available_backends() == ("scipy",)
    assert linsolve.resolve_backend("auto") == "scipy"
    with pytest.raises(CaseError, match="not installed here.*critfric\\[fast\\]"):
        linsolve.resolve_backend("pardiso")


def test_nested_dissection_is_a_fill_reducing_permutation():
    prep = prepare(loads_case(square_case(size=0.01)))
    s, mesh = prep.system, prep.mesh
    rank = ordering.nested_dissection(mesh.points, mesh.cells)
    np.testing.assert_array_equal(np.sort(rank), np.arange(mesh.n_nodes))
    K = s.stiffness(*lame(1.0, 0.3))
    nd = linsolve.ScipyFactor(K, symmetric=True, order=ordering.dof_order(s.free // 2, rank))
    mmd = linsolve.ScipyFactor(K, symmetric=True)
    fill = [f._lu.L.nnz + f._lu.U.nnz for f in (nd, mmd)]
    assert fill[0] <= 1.2 * fill[1]  # minimum degree's fill or better (2x less at 1 M DOFs)
    b = np.random.default_rng(1).standard_normal(K.shape[0])
    x = mmd.solve(b)
    np.testing.assert_allclose(nd.solve(b), x, rtol=1e-9, atol=1e-12 * np.abs(x).max())


def test_ordered_solves_of_row_and_column_major_columns_agree():
    """SuperLU with a given order: right-hand sides gathered row by row (row-major) or
    column by column (column-major) give the same solution, bit for bit."""
    prep = prepare(loads_case(square_case(size=0.05)))
    K = prep.system.stiffness(*lame(1.0, 0.3))
    order = np.random.default_rng(2).permutation(K.shape[0])
    factor = linsolve.ScipyFactor(K, symmetric=True, order=order)
    B = np.random.default_rng(3).standard_normal((K.shape[0], 5))
    x = factor.solve(B)
    np.testing.assert_array_equal(factor.solve(np.asfortranarray(B)), x)
    np.testing.assert_array_equal(factor.solve(np.asfortranarray(B)[:, 1:3]),
                                  factor.solve(B[:, 1:3]))  # SuperLU's kernels differ by width
    np.testing.assert_allclose(K @ x, B, atol=1e-10 * np.abs(B).max())


@pytest.mark.parametrize("element", ["P1", "Q1"])
def test_scipy_paths_with_nested_dissection_agree(element, monkeypatch):
    system = prepare(loads_case(square_case(element=element, size=0.125))).system
    K = system.stiffness(*lame(1.0, 0.3))
    state = mixed_state(system.n_contact)
    ref = [eigen.solve(K, system, state, method=m, count=1, backend="scipy")
           for m in ("dense", "arpack")]
    monkeypatch.setattr(ordering, "ND_MIN_DOFS", 0)
    rank = ordering.mesh_rank(system.mesh)
    np.testing.assert_array_equal(ordering.fill_order(system),
                                  ordering.dof_order(system.free // 2, rank))
    got = [eigen.solve(K, system, state, method=m, count=1, backend="scipy")
           for m in ("dense", "arpack")]
    for a, b in zip(got, ref):
        np.testing.assert_allclose(a.positive[:1], b.positive[:1], rtol=1e-10)
        np.testing.assert_allclose(a.modes[0].phi, b.modes[0].phi, atol=1e-9)


def test_scipy_install_finds_the_inclined_body_negative_family():
    """Without MKL the default path is the same Schur complement + dense pencil as with it:
    the shipped inclined body's negative coefficient (-5.2584 on its mesh, found by PARDISO and the dense
    method) is not dropped, and ARPACK, now widened until both families are found, agrees."""
    case = critfric.load_case(CASES / "inclined_body.toml")
    r = critfric.solve_case(case, overrides={"solve.backend": "scipy"})
    assert r.solver == "dense" and r.backend == "scipy" and r.complete
    assert r.negative[0] == pytest.approx(-5.2583800, rel=1e-6)
    assert r.positive[0] == pytest.approx(0.5853334, rel=1e-6)
    a = critfric.solve_case(case, overrides={"solve.backend": "scipy", "solve.method": "arpack"})
    np.testing.assert_allclose([a.positive[0], a.negative[0]], [r.positive[0], r.negative[0]],
                               rtol=1e-9)


@pytest.mark.skipif("pardiso" not in linsolve.available_backends(),
                    reason="backend 'pardiso' not installed (pip install critfric[fast])")
def test_pardiso_factors_freed_by_the_collector_in_another_thread():
    """ctypes lets other threads run during a PARDISO call; a factor in a reference cycle is
    released (phase -1) by whichever thread collects it. Factors of many sizes made and left
    to the collector while another thread keeps collecting: every solve stays exact."""
    import gc
    import threading

    stop = threading.Event()

    def collect():
        while not stop.is_set():
            junk = [[i] for i in range(100)]
            for item in junk:
                item.append(junk)  # cycles: the collector runs in this thread too
            gc.collect(0)
            stop.wait(0.001)

    thread = threading.Thread(target=collect, daemon=True)
    thread.start()
    rng = np.random.default_rng(7)
    try:
        for _ in range(30):
            n = int(rng.integers(6, 3000))
            e = np.ones(n)
            A = sp.diags([-e[:-1], 2.5 * e, -e[:-1]], [-1, 0, 1], format="csc")
            index = np.sort(rng.choice(n, size=min(n - 2, 40), replace=False))
            sc = linsolve.schur(A, index, backend="pardiso")
            sc.cycle = sc
            x = sc.extend(np.ones(len(index)))
            assert np.allclose(x[index], 1.0)
            free = np.setdiff1d(np.arange(n), index)
            assert np.abs((A @ x)[free]).max() < 1e-10
            F = linsolve.factorize(A, symmetric=True, backend="pardiso")
            F.cycle = F
            b = rng.standard_normal(n)
            assert np.abs(A @ F.solve(b) - b).max() < 1e-10
            del sc, F
    finally:
        stop.set()
        thread.join()


@pytest.mark.skipif("pardiso" not in linsolve.available_backends(),
                    reason="backend 'pardiso' not installed (pip install critfric[fast])")
def test_every_pardiso_call_runs_in_one_thread(monkeypatch):
    """A handle analysed with Schur rows in one thread and factored in another corrupted MKL's
    heap (a later analysis segfaulted in a quarter of the runs of a stability run followed
    by sweeps). A plan's analysis, its factorization, solves from the caller's and from
    another thread, and releases by the collector all run in the one MKL thread."""
    import gc
    import threading

    from critfric.solvers import pardiso

    seen = []
    original = pardiso._phase
    monkeypatch.setattr(pardiso, "_phase", lambda lib, threads, pt, mtype, phase, *rest: (
        seen.append((threading.get_ident(), phase))
        or original(lib, threads, pt, mtype, phase, *rest)))
    prep = prepare(loads_case(square_case(element="P1", size=0.25)))
    K = prep.system.stiffness(*lame(1.0, 0.3), keep_zeros=True)
    index = np.concatenate([prep.system.cn, prep.system.ct])
    U = upper_triangle(K)
    sc = linsolve.PardisoPlan(U.indptr, U.indices, index).schur(K, index)
    x = sc.extend(np.ones(len(index)))
    assert np.abs(np.delete(K @ x, index)).max() < 1e-10
    b = np.arange(K.shape[0], dtype=float)
    solved = []
    other = threading.Thread(target=lambda: solved.append(
        linsolve.factorize(K, symmetric=True, backend="pardiso").solve(b)))
    other.start()
    other.join()
    assert np.abs(K @ solved[0] - b).max() < 1e-9 * np.abs(b).max()
    sc.cycle = sc
    del sc
    gc.collect()
    pardiso.MKL_THREAD.call(int)  # the release is posted: done once the calls before are
    assert {11, 22, 33, 333, -1} <= {phase for _, phase in seen}
    assert len({ident for ident, _ in seen}) == 1
    assert seen[0][0] not in (threading.get_ident(), other.ident)
    with pytest.raises(ValueError, match="shape"):  # PARDISO would read past it
        linsolve.factorize(K, symmetric=True, backend="pardiso").solve(b[:-1])


@pytest.mark.skipif("pardiso" not in linsolve.available_backends(),
                    reason="backend 'pardiso' not installed (pip install critfric[fast])")
def test_a_pardiso_factor_is_released_with_its_own_settings(monkeypatch):
    """Symmetric factors are two-level (iparm[23] = 1); one released with iparm[23] = 0
    segfaulted, from 50 rows on. Each handle's release gets the settings of its analysis."""
    import gc

    from critfric.solvers import pardiso

    seen = []
    original = pardiso._phase
    monkeypatch.setattr(pardiso, "_phase", lambda lib, threads, pt, mtype, phase, a, ia, ja,
                        perm, nrhs, iparm, *rest: (
        seen.append((pt.ctypes.data, phase, iparm[1], iparm[23], iparm[35]))
        or original(lib, threads, pt, mtype, phase, a, ia, ja, perm, nrhs, iparm, *rest)))
    n = 60
    e = np.ones(n)
    A = sp.diags([-e[:-1], 2.5 * e, -e[:-1]], [-1, 0, 1], format="csr")
    made = [linsolve.factorize(A, symmetric=True, backend="pardiso"),
            linsolve.schur(A, np.array([0, n - 1]), backend="pardiso"),
            linsolve.factorize(A, symmetric=False, backend="pardiso")]
    for f in made:
        assert np.abs(A @ f.solve(np.ones(n)) - 1.0).max() < 1e-12
    del made, f
    gc.collect()
    pardiso.MKL_THREAD.call(int)  # the releases are posted: done once the calls before are
    analysed = {pt: rest for pt, phase, *rest in seen if phase == 11}
    # (factors of earlier tests collected meanwhile are released too: only these are read)
    released = {pt: rest for pt, phase, *rest in seen if phase == -1 and pt in analysed}
    assert len(analysed) == 3 and released == analysed
    assert sorted(rest[1] for rest in analysed.values()) == [0, 1, 1]  # mtype 11: classic


@pytest.mark.skipif("pardiso" not in linsolve.available_backends(),
                    reason="backend 'pardiso' not installed (pip install critfric[fast])")
def test_a_released_factor_does_not_wait_for_the_mkl_thread(monkeypatch):
    """Dropping a factor posts its release (phase -1) to the MKL thread and returns at once,
    even while that thread is busy; the next call runs after the release, and at exit the
    process waits for the releases still queued."""
    import threading

    from critfric.solvers import pardiso

    seen = []
    original = pardiso._phase
    monkeypatch.setattr(pardiso, "_phase", lambda lib, threads, pt, mtype, phase, *rest: (
        seen.append(phase) or original(lib, threads, pt, mtype, phase, *rest)))
    K = (sp.diags([4.0] * 50) + sp.diags([-1.0] * 49, 1) + sp.diags([-1.0] * 49, -1)).tocsr()
    factor = linsolve.factorize(K, symmetric=True, backend="pardiso")
    busy, go = threading.Event(), threading.Event()
    blocker = pardiso.MKL_THREAD.submit(lambda: busy.set() or go.wait(10))
    assert busy.wait(10)
    del factor  # the finalizer runs here, with the MKL thread blocked
    assert -1 not in seen and not pardiso.MKL_THREAD.idle
    go.set()
    assert blocker.result() is True
    assert linsolve.factorize(K, symmetric=True, backend="pardiso").solve(np.ones(50)).shape
    assert seen.index(-1) < seen.index(11, seen.index(-1))  # released before the next one
    assert pardiso.MKL_THREAD.idle
    script = (
        "import numpy as np, scipy.sparse as sp\n"
        "from critfric.solvers import backends as linsolve, pardiso\n"
        "original = pardiso._phase\n"
        "def phase(lib, threads, pt, mtype, phase, *rest):\n"
        "    err = original(lib, threads, pt, mtype, phase, *rest)\n"
        "    if phase == -1:\n"
        "        print('released', flush=True)\n"
        "    return err\n"
        "pardiso._phase = phase\n"
        "K = sp.diags([2.0] * 30, format='csr')\n"
        "kept = linsolve.factorize(K, symmetric=True, backend='pardiso')\n"
        "print('exit', flush=True)\n")
    out = run_python(script, timeout=60)
    assert out.returncode == 0, out.stderr
    assert out.stdout.split() == ["exit", "released"]


@pytest.mark.parametrize("k", [1, 2, 9, 200, 600])
def test_trailing_product_is_l_times_u(k):
    """The trailing blocks' product L U of a symmetric positive definite factorization (L unit
    lower, U = D L^T) by lauum equals the plain product to rounding, and is symmetric; a
    non-positive pivot falls back on the plain product."""
    rng = np.random.default_rng(k)
    A = rng.standard_normal((k, k))
    A = A @ A.T + k * np.eye(k)
    c = la.cholesky(A, lower=True)
    d = np.diag(c)
    L, U = np.asfortranarray(c / d), np.asfortranarray(d[:, None] * c.T)
    blocks = [L, U]
    S = linsolve._trailing_product(blocks)
    assert blocks == []  # freed once read
    assert np.abs(S - L @ U).max() <= 1e-14 * np.abs(A).max()
    np.testing.assert_array_equal(S, S.T)
    lower = np.tril(S)  # the mirrored upper triangle, block by block: what S + tril(S, -1)^T is
    np.testing.assert_array_equal(S, lower + np.tril(lower, -1).T)
    U[0, 0] = -U[0, 0]
    np.testing.assert_array_equal(linsolve._trailing_product([L, U]), L @ U)


@pytest.mark.parametrize("density", [0.0, 0.003, 0.05])
def test_upper_triangle_is_triu(density):
    A = sp.random(300, 300, density=density, format="csr", random_state=3)
    A = (A + A.T + sp.eye(300)).tocsr()
    # the rows of A in reverse, each with its entries in reverse: unsorted CSR
    A.indices, A.data = A.indices[::-1].copy(), A.data[::-1].copy()
    A.indptr = A.indptr[-1] - A.indptr[::-1]
    A.has_sorted_indices = False
    U, T = upper_triangle(A), sp.triu(A, format="csr")
    T.sort_indices()
    np.testing.assert_array_equal(U.indptr, T.indptr)
    np.testing.assert_array_equal(U.indices, T.indices)
    np.testing.assert_array_equal(U.data, T.data)


@pytest.mark.parametrize("element", ["P1", "Q1", "P2"])
def test_substructured_schur_equals_one_factorization(element, monkeypatch):
    """SplitSchur (each piece factored alone, one or two at a time, the separators eliminated
    densely) gives the Schur complement and the extensions of one factorization of the
    whole, and is what the SciPy dense path takes from SPLIT_MIN_ROWS rows on, with the same
    spectrum and modes."""
    system = prepare(loads_case(square_case(element=element, size=0.05))).system
    K = system.stiffness(*lame(1.0, 0.3))
    index = np.concatenate([system.cn, system.ct])
    monkeypatch.setattr(ordering, "ND_MIN_DOFS", 0)  # P1/Q1 dissected, P2 minimum degree
    pieces, order = ordering.pieces(system), ordering.fill_order(system)
    assert set(np.unique(pieces)) == set(range(-1, 2**ordering.PIECE_LEVELS))
    assert np.count_nonzero(pieces == -1) < 0.3 * len(pieces)  # a small mesh: 20% on P2
    whole = linsolve.ScipySchur(K, index, order=order)
    xc = np.random.default_rng(3).standard_normal((len(index), 3))
    interior = np.ones(K.shape[0], dtype=bool)
    interior[index] = False
    for workers in (1, 2):
        split = linsolve.SplitSchur(K, index, pieces, order=order, workers=workers)
        np.testing.assert_allclose(split.S, whole.S, rtol=0, atol=1e-11 * np.abs(whole.S).max())
        for _ in range(2):  # the second time without the kept factors
            x = split.extend(xc)
            np.testing.assert_array_equal(x[index], xc)
            np.testing.assert_allclose(x, whole.extend(xc), rtol=0,
                                       atol=1e-10 * np.abs(x).max())
            assert np.abs((K @ x)[interior]).max() < 1e-10 * abs(K).max() * np.abs(x).max()
    state = mixed_state(system.n_contact)
    ref = eigen.solve(K, system, state, method="dense", count=2, backend="scipy")
    monkeypatch.setattr(linsolve, "SPLIT_MIN_ROWS", 0)
    assert isinstance(linsolve.schur(K, index, order=order, pieces=pieces), linsolve.SplitSchur)
    # pieces that K joins, or one piece, are no partition: one factorization instead
    for no_split in (np.arange(len(pieces)) % 2, np.zeros_like(pieces)):
        assert isinstance(linsolve.schur(K, index, order=order, pieces=no_split),
                          linsolve.ScipySchur)
    got = eigen.solve(K, system, state, method="dense", count=2, backend="scipy")
    np.testing.assert_allclose(got.positive[:2], ref.positive[:2], rtol=1e-10)
    np.testing.assert_allclose(got.negative[:2], ref.negative[:2], rtol=1e-10)
    for a, b in zip(got.modes, ref.modes):
        np.testing.assert_allclose(a.phi, b.phi, atol=1e-9)


@pytest.mark.parametrize("element", ["P1", "Q1", "P2", "Q2"])
def test_stiffness_pattern_is_known_before_its_values(element):
    """upper_pattern (of the mesh's DOF pattern, restricted by the Dirichlet mask alone) is the
    pattern of the upper triangle of the free stiffness with its zeros kept, and the layout's
    contact DOFs are the system's [cn, ct]; contact_system with the layout given is the same."""
    from critfric.fem.assembly import assemble_elasticity
    from critfric.fem.contact import contact_layout, contact_system
    from critfric.fem.pattern import upper_pattern

    case = loads_case(square_case(element=element, size=0.2))
    mesh = prepare(case).mesh
    bc = dict(contact=case.boundary["contact"], dirichlet=case.boundary["dirichlet"])
    layout = contact_layout(mesh, **bc)
    seen = []
    K_lam, K_G = assemble_elasticity(mesh, on_pattern=seen.append)
    ptr, col, _ = upper_pattern(seen[0].indptr, seen[0].indices, layout.position)
    given, own = contact_system(mesh, K_lam, K_G, layout=layout, **bc), contact_system(
        mesh, K_lam, K_G, **bc)
    for a, b in ((given.K_lam, own.K_lam), (given.K_G, own.K_G), (given.D_G, own.D_G)):
        assert (a != b).nnz == 0
    np.testing.assert_array_equal(layout.contact_dofs, np.concatenate([own.cn, own.ct]))
    np.testing.assert_array_equal(layout.free, own.free)
    U = upper_triangle(own.stiffness(*lame(1.0, 0.3), keep_zeros=True))
    np.testing.assert_array_equal(U.indptr, ptr)
    np.testing.assert_array_equal(U.indices, col)
    K = own.stiffness(*lame(1.0, 0.3))  # without keep_zeros, the zeros go
    assert K.nnz == np.count_nonzero(own.stiffness(*lame(1.0, 0.3), keep_zeros=True).data)


@pytest.mark.parametrize("backend", AVAILABLE)
def test_a_kept_analysis_serves_the_next_poisson_ratios(backend, monkeypatch):
    """solve_prepared(keep_analysis=True): PARDISO analyses K once for a sweep over nu (K has
    one pattern for every nu, nu = 0 included) and factors on that analysis, with the values
    of fresh solves; the Schur complement and its Cholesky are those of the new values. SciPy
    keeps nothing."""
    from critfric.solve import solve_prepared
    from critfric.solvers import pardiso

    case = loads_case(square_case(element="P1", size=0.1)).with_overrides(
        {"solve.backend": backend})
    analyses = []
    if backend == "pardiso":
        original = pardiso.PardisoFactor._analyse
        monkeypatch.setattr(pardiso.PardisoFactor, "_analyse",
                            lambda self, index: analyses.append(1) or original(self, index))
    kept, fresh = prepare(case), prepare(case)
    for nu in (0.0, 0.3, 0.45, 0.2):
        at = case.with_overrides({"material.nu": nu})
        got = solve_prepared(kept, at, keep_analysis=True)
        assert (kept.plan is not None) == (backend == "pardiso")
        want = solve_prepared(fresh, at)
        assert fresh.plan is None
        for a, b in ((got.positive, want.positive), (got.negative, want.negative)):
            np.testing.assert_allclose(a, b, rtol=1e-10)
        assert len(got.alpha) == len(want.alpha)
    if backend == "pardiso":
        assert len(analyses) == 1 + 4  # the kept one, and each fresh solve's own
    kept.plan = None  # frees the kept factor


@pytest.mark.skipif("pardiso" not in AVAILABLE,
                    reason="backend 'pardiso' not installed (pip install critfric[fast])")
def test_pardiso_analysis_started_from_the_pattern_gives_the_same_factorization():
    """A PardisoPlan (phase 11 in the MKL thread from the pattern, phase 22 on the values later)
    gives PardisoFactor's S and extensions; a plan of another pattern or index is declined
    (None: the caller factors afresh), a plan serves once, and solve_case uses one."""
    prep = prepare(loads_case(square_case(element="P1", size=0.1)))
    system = prep.system
    K = system.stiffness(*lame(1.0, 0.3), keep_zeros=True)
    index = np.concatenate([system.cn, system.ct])
    U = upper_triangle(K)
    whole = linsolve.PardisoFactor(K, symmetric=True, schur_index=index)
    plan = linsolve.PardisoPlan(U.indptr, U.indices, index)
    planned = plan.schur(K, index)
    np.testing.assert_allclose(planned.S, whole.S, rtol=0, atol=1e-13 * np.abs(whole.S).max())
    xc = np.random.default_rng(5).standard_normal((len(index), 2))
    np.testing.assert_allclose(planned.extend(xc), whole.extend(xc), rtol=0,
                               atol=1e-12 * np.abs(whole.extend(xc)).max())
    assert plan.schur(K, index) is None  # used once
    assert linsolve.PardisoPlan(U.indptr, U.indices, index[::-1]).schur(K, index) is None
    sparser = K.tolil()  # one coupling less: another pattern
    i, j = U.indices[U.indptr[5] + 1], 5
    sparser[i, j] = sparser[j, i] = 0.0
    sparser = sparser.tocsr()
    sparser.eliminate_zeros()
    assert sparser.nnz == K.nnz - 2
    assert linsolve.PardisoPlan(U.indptr, U.indices, index).schur(sparser, index) is None
    S = linsolve.schur(K, index, backend="pardiso",  # declined: factored afresh
                       plan=linsolve.PardisoPlan(U.indptr, U.indices, index[1:]))
    np.testing.assert_allclose(S.S, whole.S, rtol=0, atol=1e-13 * np.abs(whole.S).max())


@pytest.mark.skipif("pardiso" not in AVAILABLE,
                    reason="backend 'pardiso' not installed (pip install critfric[fast])")
def test_pardiso_analysis_failure_is_raised_in_the_callers_thread(monkeypatch):
    prep = prepare(loads_case(square_case(element="P1", size=0.25)))
    K = prep.system.stiffness(*lame(1.0, 0.3), keep_zeros=True)
    index = np.concatenate([prep.system.cn, prep.system.ct])
    U = upper_triangle(K)

    def fail(self, schur_index):
        raise SolverError("PARDISO phase 11 failed with error -2 (not enough memory)")

    monkeypatch.setattr(linsolve.PardisoFactor, "_analyse", fail)
    plan = linsolve.PardisoPlan(U.indptr, U.indices, index)
    with pytest.raises(SolverError, match="phase 11 failed"):
        plan.schur(K, index)


@pytest.mark.skipif("pardiso" not in AVAILABLE,
                    reason="backend 'pardiso' not installed (pip install critfric[fast])")
@pytest.mark.parametrize("element", ["P1", "Q2"])
def test_solve_case_overlaps_the_analysis_and_gives_the_same_result(element, monkeypatch):
    """solve_case starts PARDISO's analysis from the pattern (its plan is taken) and reports
    what solve_prepared without a plan reports."""
    from critfric.solve import solve_case, solve_prepared

    taken = []
    original = linsolve.PardisoPlan.schur
    monkeypatch.setattr(linsolve.PardisoPlan, "schur",
                        lambda self, A, i: taken.append(original(self, A, i)) or taken[-1])
    case = load_case(CASES / "inclined_body.toml").with_overrides(
        {"mesh.element": element, "solve.count": 2})
    got = solve_case(case)
    assert len(taken) == 1 and taken[0] is not None
    ref = solve_prepared(prepare(case), case)
    np.testing.assert_allclose(got.positive, ref.positive, rtol=1e-11)
    np.testing.assert_allclose(got.negative, ref.negative, rtol=1e-11)
    for a, b in zip(got.modes, ref.modes):
        np.testing.assert_allclose(a["phi"], b["phi"], atol=1e-10)


@pytest.mark.skipif("pardiso" not in AVAILABLE,
                    reason="backend 'pardiso' not installed (pip install critfric[fast])")
def test_pardiso_phases_keep_one_thread_count_whatever_the_caller_sets():
    """Every PARDISO call runs in the MKL thread, and callers change MKL's threads between
    calls (threadpoolctl, as sweeps run in-process do). Phase 22 with another count than
    phase 11 gave a Schur complement off by 100% (P1 at 3 856 DOFs) or a segfault (Q2)."""
    from threadpoolctl import threadpool_limits

    from critfric.solve import solve_case

    case = loads_case(square_case(element="P1", size=0.025))
    lib = linsolve.pardiso_library()  # loaded, so that threadpoolctl sees MKL
    with threadpool_limits(limits=2):  # a default count above one, even in a test worker
        if lib.max_threads() != 2:
            pytest.skip(f"MKL takes {lib.max_threads()} thread(s) here, not 2: the counts "
                        "this test compares cannot differ")
        ref = solve_case(case)
        with threadpool_limits(limits=1):
            assert lib.max_threads() == 1
            limited = solve_case(case)
            K = prepare(case).system.stiffness(*lame(1.0, 0.3))
            index = np.arange(0, K.shape[0], 7)
            factor = linsolve.PardisoFactor(K, symmetric=True, schur_index=index)
        np.testing.assert_allclose(limited.positive, ref.positive, rtol=1e-11)
        np.testing.assert_allclose(limited.negative, ref.negative, rtol=1e-11)
        whole = linsolve.PardisoFactor(K, symmetric=True, schur_index=index)
        np.testing.assert_allclose(factor.S, whole.S, rtol=0, atol=1e-12 * np.abs(whole.S).max())
        xc = np.random.default_rng(2).standard_normal((len(index), 3))
        with threadpool_limits(limits=1):  # made with two threads, solved with one
            np.testing.assert_allclose(whole.extend(xc), factor.extend(xc), rtol=0,
                                       atol=1e-11 * np.abs(factor.extend(xc)).max())


def test_substructuring_stops_at_a_failed_piece(monkeypatch):
    """A piece that cannot be factored is a SolverError, and the pieces not yet started are
    not factored (the same holds for Ctrl-C)."""
    system = prepare(loads_case(square_case(element="P1", size=0.05))).system
    K = system.stiffness(*lame(1.0, 0.3)).tolil()
    index = np.concatenate([system.cn, system.ct])
    monkeypatch.setattr(ordering, "ND_MIN_DOFS", 0)
    pieces = ordering.pieces(system)
    first = np.flatnonzero(pieces == 0)
    first = first[~np.isin(first, index)]
    K[first, :] = 0.0  # piece 0 singular
    K[:, first] = 0.0
    calls = []
    original = linsolve.SplitSchur._factor

    def factor(self, h):  # the other pieces take a while: piece 0 fails first
        calls.append(h)
        if h:
            time.sleep(0.3)
        return original(self, h)

    monkeypatch.setattr(linsolve.SplitSchur, "_factor", factor)
    with pytest.raises(SolverError, match="singular"):
        linsolve.SplitSchur(K.tocsr(), index, pieces, workers=2)
    assert sorted(calls)[:2] == [0, 1] and len(calls) <= 3  # at most one piece started after


@pytest.mark.parametrize("transpose", [False, True])
def test_superlu_solves_of_many_columns_shared_among_threads(monkeypatch, transpose):
    """A SuperLU solve of many columns, shared among threads from the main thread, gives what
    one call gives (to rounding); other threads, and too few columns, solve in one call."""
    import threading

    monkeypatch.setattr(linsolve, "SOLVE_SPLIT_ROWS", 0)
    monkeypatch.setattr(linsolve, "usable_cpus", lambda: 3)
    K = prepare(loads_case(square_case(size=0.1))).system.stiffness(*lame(1.0, 0.3))
    order = ordering.minimum_degree(K)
    rng = np.random.default_rng(5)
    B = rng.standard_normal((K.shape[0], 29))
    calls = []

    class Spy:  # SuperLU's solve, its column counts recorded
        def __init__(self, lu):
            self.lu = lu

        def solve(self, b, trans="N"):
            calls.append(b.shape[1])
            return self.lu.solve(b, trans=trans)

    for factor in (linsolve.ScipyFactor(K, symmetric=False, order=order),
                   linsolve.ScipyFactor(K, symmetric=True)):
        lu = factor._lu
        spy = Spy(lu)
        factor._lu = spy
        calls.clear()
        X = factor.solve(B, transpose=transpose)
        assert sorted(calls) == [9, 10, 10]  # three threads, 8 columns at least each
        factor._lu = lu
        with monkeypatch.context() as alone:
            alone.setattr(linsolve, "usable_cpus", lambda: 1)
            np.testing.assert_allclose(X, factor.solve(B, transpose=transpose), rtol=0,
                                       atol=1e-13 * np.abs(X).max())
        assert np.abs((K.T if transpose else K) @ X - B).max() <= 1e-10 * np.abs(B).max()
        calls.clear()
        factor._lu = spy
        other = threading.Thread(target=factor.solve, args=(B,))
        other.start()
        other.join()
        assert calls == [29]
        calls.clear()
        factor.solve(B[:, :15])  # fewer than two parts of 8
        assert calls == [15]


@pytest.mark.parametrize("backend", backends())
def test_a_schur_factorization_solves_the_whole_system(backend):
    """The factorization that gives S also solves K x = b (PARDISO: forward substitution,
    S on the Schur rows, backward substitution), one or several right-hand sides."""
    case = loads_case(square_case(size=0.2))
    system = prepare(case).system
    K = system.stiffness(*lame(1.0, 0.3))
    index = np.concatenate([system.cn, system.ct])
    factor = linsolve.schur(K, index, backend=backend)
    rng = np.random.default_rng(3)
    for b in (rng.standard_normal(K.shape[0]), rng.standard_normal((K.shape[0], 3))):
        x = factor.solve(b)
        assert np.abs(K @ x - b).max() <= 1e-10 * np.abs(b).max()


@pytest.mark.skipif("pardiso" not in AVAILABLE,
                    reason="backend 'pardiso' not installed (pip install critfric[fast])")
def test_pardiso_plan_without_schur_rows_gives_the_plain_factorization():
    """A plan without Schur rows finishes as the plain factorization (factorize(plan=...)),
    to rounding; it is declined where a Schur complement is asked, and the reverse."""
    prep = prepare(loads_case(square_case(element="P1", size=0.1)))
    system = prep.system
    K = system.stiffness(*lame(1.0, 0.3)).tocsr()
    U = upper_triangle(K)
    b = np.random.default_rng(7).standard_normal((K.shape[0], 3))
    whole = linsolve.factorize(K, backend="pardiso").solve(b)
    plan = linsolve.PardisoPlan(U.indptr, U.indices)
    planned = linsolve.factorize(K, backend="pardiso", plan=plan)
    assert planned._index is None and plan.factor(K) is None  # used once
    x = planned.solve(b)
    np.testing.assert_allclose(x, whole, rtol=0, atol=1e-12 * np.abs(whole).max())
    np.testing.assert_allclose(K @ x, b, rtol=0, atol=1e-10 * np.abs(b).max())
    index = np.concatenate([system.cn, system.ct])
    assert linsolve.PardisoPlan(U.indptr, U.indices).schur(K, index) is None
    assert linsolve.PardisoPlan(U.indptr, U.indices, index).factor(K) is None


@pytest.mark.skipif("pardiso" not in AVAILABLE,
                    reason="backend 'pardiso' not installed (pip install critfric[fast])")
@pytest.mark.parametrize("command", ["solve", "stability"])
def test_an_analysis_started_for_a_run_that_fails_is_waited_for(monkeypatch, command):
    """solve_case and stability_case start the static stage's analysis while they assemble;
    a run that fails before using it returns only once that analysis has ended (an analysis
    left running races the caller's next PARDISO or OpenMP call)."""
    from critfric import solve as solve_module
    from critfric.solvers.pardiso import MKL_THREAD
    from critfric.stability import analysis

    started = []
    original = linsolve.PardisoPlan.__init__

    def record(self, *args, **kwargs):
        original(self, *args, **kwargs)
        started.append(self._analysis)

    def fail(*args, **kwargs):
        raise SolverError("made to fail")

    monkeypatch.setattr(linsolve.PardisoPlan, "__init__", record)
    monkeypatch.setattr(solve_module.eigen, "solve", fail)
    run = critfric.solve_case if command == "solve" else analysis.stability_case
    with pytest.raises(SolverError, match="made to fail"):
        run(loads_case(square_case(element="P2", size=0.02)))
    assert len(started) == 1 and started[0].done()
    assert MKL_THREAD.idle
    assert analysis.eigen is solve_module.eigen  # the one patched
