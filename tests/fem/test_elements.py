"""Reference elements: node order, shape functions, quadrature and lookup."""

from math import factorial

import numpy as np
import pytest

from critfric.errors import CaseError
from critfric.fem.elements import (
    ELEMENTS,
    P1,
    P2,
    Q1,
    Q2,
    facet_quadrature,
    facet_shape,
    get_element,
)

NAMES = ["P1", "P2", "Q1", "Q2"]
RNG = np.random.default_rng(0)


def random_points(element, n=7):
    """Random points inside the reference cell."""
    if element.reference == "triangle":
        p = RNG.random((n, 2))
        flip = p.sum(axis=1) > 1
        p[flip] = 1 - p[flip]
        return p
    return RNG.uniform(-1, 1, (n, 2))


def polynomial_basis(element):
    """Monomial exponents (i, j) spanning the element's polynomial space."""
    p = element.order
    if element.reference == "triangle":
        return [(i, j) for i in range(p + 1) for j in range(p + 1 - i)]
    return [(i, j) for i in range(p + 1) for j in range(p + 1)]


def test_attributes():
    expected = {
        "P1": (3, 1, "triangle"),
        "P2": (6, 2, "triangle"),
        "Q1": (4, 1, "quad"),
        "Q2": (9, 2, "quad"),
    }
    assert list(ELEMENTS) == NAMES
    for name, (n_local, order, reference) in expected.items():
        e = ELEMENTS[name]
        assert (e.name, e.n_local, e.order, e.reference) == (name, n_local, order, reference)
        assert e.doflocs.shape == (n_local, 2)
    assert isinstance(ELEMENTS["P1"], P1) and isinstance(ELEMENTS["Q2"], Q2)
    assert isinstance(ELEMENTS["P2"], P2) and isinstance(ELEMENTS["Q1"], Q1)


def test_gmsh_node_order():
    np.testing.assert_array_equal(
        P2.doflocs, [[0, 0], [1, 0], [0, 1], [0.5, 0], [0.5, 0.5], [0, 0.5]]
    )
    np.testing.assert_array_equal(Q1.doflocs, [[-1, -1], [1, -1], [1, 1], [-1, 1]])
    np.testing.assert_array_equal(
        Q2.doflocs,
        [[-1, -1], [1, -1], [1, 1], [-1, 1], [0, -1], [1, 0], [0, 1], [-1, 0], [0, 0]],
    )


@pytest.mark.parametrize("name", NAMES)
def test_kronecker_delta_at_nodes(name):
    e = get_element(name)
    values, _ = e.shape(e.doflocs)
    np.testing.assert_allclose(values, np.eye(e.n_local), atol=1e-14)


@pytest.mark.parametrize("name", NAMES)
def test_partition_of_unity(name):
    e = get_element(name)
    values, grads = e.shape(random_points(e))
    assert values.shape == (e.n_local, 7) and grads.shape == (e.n_local, 7, 2)
    np.testing.assert_allclose(values.sum(axis=0), 1.0, atol=1e-14)
    np.testing.assert_allclose(grads.sum(axis=0), 0.0, atol=1e-13)


@pytest.mark.parametrize("name", NAMES)
def test_reproduces_polynomial_space(name):
    e = get_element(name)
    xi = random_points(e)
    values, grads = e.shape(xi)
    for i, j in polynomial_basis(e):
        nodal = e.doflocs[:, 0] ** i * e.doflocs[:, 1] ** j
        x, y = xi.T
        np.testing.assert_allclose(nodal @ values, x**i * y**j, atol=1e-13)
        dx = i * x ** max(i - 1, 0) * y**j
        dy = j * x**i * y ** max(j - 1, 0)
        np.testing.assert_allclose(nodal @ grads[:, :, 0], dx, atol=1e-13)
        np.testing.assert_allclose(nodal @ grads[:, :, 1], dy, atol=1e-13)


@pytest.mark.parametrize("name", NAMES)
def test_gradients_match_finite_differences(name):
    e = get_element(name)
    xi = random_points(e, 5) * 0.9 + (0.03 if e.reference == "triangle" else 0.0)
    _, grads = e.shape(xi)
    h = 1e-6
    for k in range(2):
        step = np.zeros(2)
        step[k] = h
        fd = (e.shape(xi + step)[0] - e.shape(xi - step)[0]) / (2 * h)
        np.testing.assert_allclose(grads[:, :, k], fd, atol=1e-8)


def exact_reference_integral(reference, i, j):
    if reference == "triangle":
        return factorial(i) * factorial(j) / factorial(i + j + 2)
    one_d = lambda k: 0.0 if k % 2 else 2.0 / (k + 1)
    return one_d(i) * one_d(j)


@pytest.mark.parametrize("name,degree", [("P1", 1), ("P2", 2), ("Q1", 3), ("Q2", 5)])
def test_quadrature_exactness(name, degree):
    """Triangles: total degree; quads: degree per variable (tensor Gauss)."""
    e = get_element(name)
    points, weights = e.quadrature()
    assert points.shape == (len(weights), 2)
    assert weights.sum() == pytest.approx(0.5 if e.reference == "triangle" else 4.0, abs=1e-15)
    for i in range(degree + 1):
        for j in range(degree + 1 - i if e.reference == "triangle" else degree + 1):
            approx = weights @ (points[:, 0] ** i * points[:, 1] ** j)
            assert approx == pytest.approx(exact_reference_integral(e.reference, i, j), abs=1e-14)


def test_quadrature_is_not_overly_exact():
    """The P2 rule must be degree 2 exactly: a test that can fail if the rule is swapped."""
    points, weights = get_element("P2").quadrature()
    cubic = weights @ points[:, 0] ** 3
    assert abs(cubic - exact_reference_integral("triangle", 3, 0)) > 1e-6


@pytest.mark.parametrize("order", [1, 2])
def test_facet_shape_and_quadrature(order):
    nodes = np.array([-1.0, 1.0, 0.0][: order + 1])
    values, derivs = facet_shape(nodes, order)
    np.testing.assert_allclose(values, np.eye(order + 1), atol=1e-15)
    s, w = facet_quadrature(order)
    values, derivs = facet_shape(s, order)
    np.testing.assert_allclose(values.sum(axis=0), 1.0, atol=1e-15)
    np.testing.assert_allclose(derivs.sum(axis=0), 0.0, atol=1e-14)
    np.testing.assert_allclose(derivs.T @ nodes, 1.0, atol=1e-14)  # d s / d s
    # integrals of N_a over [-1, 1]: (1, 1) for order 1, (1/3, 1/3, 4/3) for order 2
    expected = [1.0, 1.0] if order == 1 else [1 / 3, 1 / 3, 4 / 3]
    np.testing.assert_allclose(values @ w, expected, atol=1e-15)
    for k in range(2 * order + 2):  # exact up to degree 2 * (order + 1) - 1
        assert w @ s**k == pytest.approx(0.0 if k % 2 else 2.0 / (k + 1), abs=1e-15)


@pytest.mark.parametrize("bad", ["P3", "p1", "", None])
def test_unknown_element(bad):
    with pytest.raises(CaseError) as info:
        get_element(bad)
    for name in NAMES:
        assert name in str(info.value)
