"""
Closed forms: the one triangle and the four triangles
=====================================================

Section 4 of the paper solves two tiny meshes by hand. One P1 triangle with one contact node
(Fig. 1) has the critical friction coefficient

.. math:: \\mu_{cr} = 3 - 4\\nu,

and the unit square cut into four P1 triangles meeting at its centre (Fig. 3) has

.. math:: \\mu_{cr} = \\pm\\sqrt{\\frac{(1 - \\nu)(5 - 8\\nu)}{\\nu (3 - 4\\nu)}},

which tends to infinity as :math:`\\nu \\to 0` and to 1 as :math:`\\nu \\to 1/2` (Fig. 4).
critfric ships both meshes as cases (``one-triangle``, ``four-triangles``). Meshing and
assembling once (``prepare``) and solving for each Poisson ratio (``solve_prepared``), we
compare the computed eigenvalues with these formulas.
"""

import matplotlib.pyplot as plt
import numpy as np

import critfric

# %%
# One mesh, many Poisson ratios
# -----------------------------
# ``prepare`` does everything that does not depend on nu (mesh, stiffness parts, contact
# basis); ``with_overrides`` changes one key of a case, here ``material.nu``.


def critical_over_nu(name, nus):
    case = critfric.load_case(name)
    prepared = critfric.prepare(case)
    return np.array([critfric.solve_prepared(prepared,
                                             case.with_overrides({"material.nu": nu})).critical
                     for nu in nus])


nu_one = np.linspace(0.0, 0.49, 15)
one = critical_over_nu("one-triangle", nu_one)
nu_four = np.linspace(0.02, 0.49, 40)
four = critical_over_nu("four-triangles", nu_four)

one_exact = 3 - 4 * nu_one
four_exact = np.sqrt((1 - nu_four) * (5 - 8 * nu_four) / (nu_four * (3 - 4 * nu_four)))
print(f"one triangle:   largest |computed - 3 + 4 nu| = {np.abs(one - one_exact).max():.1e}")
print(f"four triangles: largest relative difference   = "
      f"{np.abs(four / four_exact - 1).max():.1e}")

# %%
# The figure
# ----------
# Dots: critfric; lines: the closed forms.

fig, (left, right) = plt.subplots(1, 2, figsize=(10, 4))
left.plot(nu_one, one_exact, color="0.6", label=r"$3 - 4\nu$")
left.plot(nu_one, one, "o", ms=4, label="critfric, one-triangle")
left.set_title("One triangle (Fig. 1)")
right.plot(nu_four, four_exact, color="0.6", label="closed form")
right.plot(nu_four, four, "o", ms=3, label="critfric, four-triangles")
right.set_yscale("log")
right.set_title("Four triangles (Fig. 4)")
for ax in (left, right):
    ax.set_xlabel(r"Poisson ratio $\nu$")
    ax.set_ylabel(r"critical friction coefficient $\mu_{cr}$")
    ax.grid(True, alpha=0.3)
    ax.legend()
fig.tight_layout()

# %%
# The check: both agree with the paper to rounding.

assert np.abs(one - one_exact).max() < 1e-12
assert np.abs(four / four_exact - 1).max() < 1e-12
