"""
The unit square over the Poisson ratio
======================================

The unit square of section 5.1 of the paper: clamped on top, in frictional contact on its
bottom edge :math:`\\Gamma_C`, free sides, every contact node slipping along :math:`+x`. Its
lowest positive eigenvalue is the critical friction coefficient: below it the discrete static
problem has one solution, at it a continuum. The paper studies it at :math:`\\nu = 0.3`, where
it converges to about 1.945 as :math:`h \\to 0` (Fig. 5). Here it is over the whole range of
Poisson ratios, on three meshes, with the lowest negative eigenvalue (slip along :math:`-x`),
which the symmetric body mirrors.
"""

import matplotlib.pyplot as plt
import numpy as np

import critfric

# %%
# Three meshes, one assembly each
# -------------------------------
# The case is the shipped ``unit-square``; ``overrides`` set the element and the mesh size.
# Every Poisson ratio reuses the mesh and the assembly of its (element, size).

nus = np.round(np.linspace(0.05, 0.475, 18), 4)  # step 0.025, 0.3 among them
meshes = [("P1", 0.1), ("P1", 0.05), ("Q2", 0.1)]
curves = {}
for element, size in meshes:
    case = critfric.load_case("unit-square",
                              overrides={"mesh.element": element, "mesh.size": size})
    prepared = critfric.prepare(case)
    results = [critfric.solve_prepared(prepared, case.with_overrides({"material.nu": nu}))
               for nu in nus]
    curves[element, size] = (np.array([r.critical for r in results]),
                             np.array([r.negative[0] for r in results]))
    print(f"{element}, h = {size}: {results[0].n_dofs} DOFs, "
          f"{results[0].n_contact} contact nodes")

at_03 = {key: pos[np.flatnonzero(nus == 0.3)[0]] for key, (pos, _) in curves.items()}
for (element, size), value in at_03.items():
    print(f"{element}, h = {size}: critical coefficient at nu = 0.3: {value:.6f}")

# %%
# The figure
# ----------
# Left: the coefficient against nu. Right: the relative difference between the positive and
# the negative family, which the body's left-right symmetry makes small but not zero: the
# gmsh meshes are not symmetric.

fig, (left, right) = plt.subplots(1, 2, figsize=(10, 4))
for (element, size), (pos, neg) in curves.items():
    label = f"{element}, h = {size}"
    left.plot(nus, pos, marker="o", ms=3, label=label)
    right.semilogy(nus, np.abs(pos + neg) / pos, marker="o", ms=3, label=label)
left.axhline(1.94471145, color="0.5", ls="--", lw=1)
left.annotate(r"$h \to 0$ limit at $\nu = 0.3$: 1.94471", (0.3, 1.94471145),
              xytext=(0.25, 3.2), arrowprops={"arrowstyle": "->", "color": "0.4"})
left.set_ylabel(r"critical friction coefficient $\mu_{cr}$")
right.set_ylabel(r"$|\alpha_+ + \alpha_-| / \alpha_+$")
right.set_title("positive vs negative family")
left.set_title("Unit square: lowest positive eigenvalue")
for ax in (left, right):
    ax.set_xlabel(r"Poisson ratio $\nu$")
    ax.grid(True, alpha=0.3)
    ax.legend()
fig.tight_layout()

# %%
# The check: at nu = 0.3 every mesh is within 0.6% of the h -> 0 value (P1 at h = 0.1 is
# 1.9553), the quadratic element within 1e-4 of it on the coarsest mesh; the coefficient
# falls monotonically with nu.

for (element, size), value in at_03.items():
    assert abs(value / 1.94471145 - 1) < 6e-3, (element, size, value)
assert abs(at_03["Q2", 0.1] - 1.94471145) < 1e-4
assert all(np.all(np.diff(pos) < 0) for pos, _ in curves.values())
