"""scripts/exponents.py: the singular exponents of a vertex against textbook values."""

import importlib.util
from pathlib import Path

import numpy as np
import pytest

pytestmark = pytest.mark.once  # the same on both installs: run by `make test` only

_spec = importlib.util.spec_from_file_location(
    "exponents", Path(__file__).resolve().parents[1] / "scripts" / "exponents.py")
exponents = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(exponents)


def _positive(omega, first, second, friction=0.0, **kw):
    s = exponents.exponents(omega, first, second, friction, **kw)
    return np.sort(s[(s.real > 1e-4) & (s.real < 1.5) & (np.abs(s.imag) < 1e-8)].real)


def test_williams_exponents_of_free_wedges():
    np.testing.assert_allclose(_positive(2 * np.pi, "free", "free")[:1], [0.5], atol=1e-9)
    np.testing.assert_allclose(_positive(1.5 * np.pi, "free", "free")[:2],
                               [0.544483737, 0.908529189], atol=1e-8)  # the 270 deg notch
    np.testing.assert_allclose(_positive(np.pi, "free", "free")[:1], [1.0], atol=1e-9)


def test_friction_moves_the_exponent_of_a_slipping_edge_through_zero():
    assert _positive(np.pi / 2, "slip", "free", 0.0)[0] == pytest.approx(1.0, abs=1e-9)
    # the crossing of a slipping edge meeting a free one at a right angle (docs/validation.md)
    before, after = (exponents.nearest_real(np.pi / 2, "slip", "free", f, 1.0, 0.3)
                     for f in (1.55, 1.59))
    assert 0 < before < 0.02 and -0.02 < after < 0
    assert exponents.nearest_real(np.pi / 2, "slip", "free", 1.4, 1.0, 0.3) > 0.05
    assert exponents.nearest_real(np.pi / 2, "slip", "free", 1.7, 1.0, 0.3) < -0.05
