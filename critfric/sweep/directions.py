"""The body's critical coefficient over slip directions (3D bodies): the minimum, over the
slip angle theta, of the lowest positive eigenvalue alpha+(theta).

Reversing every slip direction flips the sign of every eigenvalue, alpha(theta + 180) =
-alpha(theta), so the lowest positive eigenvalue at theta + 180 is minus the negative one of
least modulus at theta: each sample theta of a sweep gives the curve alpha+ at two angles.
The minimum is bracketed on these samples (the lowest one and its two neighbours on the
circle), then located by Brent's bounded minimization over the angle (golden section and
parabolic steps), each evaluation one solve of the prepared mesh at that angle, to
``ANGLE_TOL`` degrees. The angle and value reported are those of one evaluation (or of the
lowest sample, solved again, when no evaluation goes below it).

A direction with no positive real eigenvalue has alpha+ = +inf (no friction coefficient
makes it critical). Such samples take part in the bracket as higher than every finite one
(the function minimized is clipped to a ceiling above every finite sample, so the search
never steps on an infinite value); when every sample is infinite, nothing is located: the
status is ``no-positive-alpha`` and the value +inf (null in JSON). Failed samples are left
out of the bracket, and the status says how many.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from scipy.optimize import minimize_scalar

ANGLE_TOL = 1e-6  # degrees: the tolerance of the located angle
MAX_EVALUATIONS = 200  # solves of one bracket at most
CEILING = 10.0  # an infinite value counts as CEILING x (1 + the largest finite sample)
TIE = 1e-9  # samples this close (relative) to the lowest are tied with it
#: the columns of a minimum (a row of the sweep file's /minima)
MINIMUM_KEYS = ("nu", "size", "element", "slip_angle", "positive", "r_positive", "bracket_lo",
                "bracket_hi", "evaluations", "seconds", "status")


@dataclass(frozen=True)
class MinimumTask:
    """The minimum over directions at one (nu, size, element), as a worker receives it: the
    samples of alpha+ on the circle (angles in [0, 360) ascending; +inf where none)."""

    nu: float
    size: float | None
    element: str
    angles: tuple[float, ...]
    values: tuple[float, ...]
    failed: int = 0  # samples left out (failed points)
    slip_angle = None  # not a grid point: no angle of its own (read by grid.empty_row)

    @property
    def group(self) -> tuple:
        return (self.size, self.element)

    @property
    def key(self) -> tuple:
        return minimum_key(self.__dict__)


def minimum_key(m: dict) -> tuple:
    """(element, size or -1, nu): what identifies a minimum over directions."""
    return (m["element"], -1.0 if m["size"] is None else m["size"], m["nu"])


def circle_samples(rows: list[dict]) -> tuple[np.ndarray, np.ndarray, int]:
    """(angles in [0, 360) ascending, alpha+ there, failed rows) from the sweep rows of one
    (nu, size, element): alpha+ at each row's angle and minus its negative eigenvalue of least
    modulus at angle + 180; an angle met twice keeps the lower value."""
    ok = [r for r in rows if r.get("slip_angle") is not None
          and not r["status"].startswith("failed")]
    theta = np.array([float(r["slip_angle"]) for r in ok])
    pos = np.array([r["positive"][0] if r["positive"] else math.inf for r in ok])
    neg = np.array([-r["negative"][0] if r["negative"] else math.inf for r in ok])
    angles = np.round(np.mod(np.concatenate([theta, theta + 180.0]), 360.0), 9) % 360.0
    values = np.concatenate([pos, neg])
    order = np.lexsort((values, angles))
    angles, values = angles[order], values[order]
    first = np.r_[True, np.diff(angles) > 0]
    return angles[first], values[first], len(rows) - len(ok)


def bracket(angles: np.ndarray, values: np.ndarray) -> tuple[float, float, float]:
    """(lo, best, hi): the lowest sample and its neighbours on the circle, lo < best < hi
    (unwrapped around best: lo may be negative, hi above 360). Samples within TIE of the
    lowest (equal by a symmetry of the body, apart from rounding) count as equal: the first
    angle of them is taken, so that every install brackets the same one."""
    low = float(np.min(values))
    k, n = int(np.flatnonzero(values <= low + TIE * abs(low))[0]), len(angles)
    lo = angles[k - 1] if k > 0 else angles[-1] - 360.0
    hi = angles[k + 1] if k < n - 1 else angles[0] + 360.0
    return float(lo), float(angles[k]), float(hi)


def locate(alpha_at: Callable[[float], tuple[float, float]], angles, values, *,
           tol: float = ANGLE_TOL) -> dict:
    """The minimum of alpha+ over the angle, bracketed by the circle samples ``angles``,
    ``values`` (:func:`circle_samples`); ``alpha_at(angle)`` solves at an angle in [0, 360)
    and returns (alpha+, its r), (+inf, NaN) without a positive eigenvalue.

    Returns slip_angle (degrees in [0, 360)), positive (the minimum), r_positive,
    bracket_lo, bracket_hi, evaluations (solves) and status.
    """
    angles, values = np.asarray(angles, dtype=float), np.asarray(values, dtype=float)
    lo, best, hi = bracket(angles, values)
    out = {"bracket_lo": lo, "bracket_hi": hi, "evaluations": 0}
    if not np.isfinite(values).any():
        return {**out, "slip_angle": math.nan, "positive": math.inf, "r_positive": math.nan,
                "status": "no-positive-alpha"}
    ceiling = CEILING * (1.0 + float(np.abs(values[np.isfinite(values)]).max()))
    seen: dict[float, tuple[float, float]] = {}

    def solve(angle: float) -> float:
        if angle not in seen:
            seen[angle] = alpha_at(angle)
        return seen[angle][0]

    # the offset from the best sample is the variable: Brent's tolerance has a part relative
    # to |x| (sqrt(eps) |x|), which would be 4e-6 degrees at x = 300
    found = minimize_scalar(lambda u: min(solve(float((best + u) % 360.0)), ceiling),
                            bounds=(lo - best, hi - best), method="bounded",
                            options={"xatol": tol, "maxiter": MAX_EVALUATIONS})
    sample = float(values[int(np.argmin(values))])
    angle = min(seen, key=lambda a: seen[a][0])
    if not seen[angle][0] < sample:  # no evaluation went below the sample: solve it again
        angle = float(best % 360.0)
        solve(angle)
    value, r = seen[angle]
    status = "ok" if found.success else f"ok, but {found.message.lower()}"
    return {**out, "slip_angle": angle, "positive": value, "r_positive": r,
            "evaluations": len(seen), "status": status}


def minimum_tasks(rows: list[dict], done: set[tuple]) -> list[MinimumTask]:
    """The minima to locate: one per (nu, size, element) of the rows of an angle sweep, except
    those in ``done``; grouped by (size, element) so that a worker meshes each once."""
    groups: dict[tuple, list[dict]] = {}
    for r in rows:
        if r.get("slip_angle") is not None:
            groups.setdefault(minimum_key(r), []).append(r)
    tasks = []
    for key, group in groups.items():
        if key in done:
            continue
        angles, values, failed = circle_samples(group)
        r = group[0]
        tasks.append(MinimumTask(r["nu"], r["size"], r["element"], tuple(angles.tolist()),
                                 tuple(values.tolist()), failed))
    return sorted(tasks, key=lambda t: (t.element, -1.0 if t.size is None else -t.size, t.nu))


def task_minimum(task: MinimumTask, alpha_at: Callable[[float], tuple[float, float]]) -> dict:
    """The minimum row of ``task`` (:data:`MINIMUM_KEYS` but seconds), solving with
    ``alpha_at``; two circle samples or fewer (one direction) locate nothing."""
    row = {"nu": task.nu, "size": task.size, "element": task.element}
    if len(task.angles) < 3:
        return {**row, "slip_angle": math.nan, "positive": math.nan, "r_positive": math.nan,
                "bracket_lo": math.nan, "bracket_hi": math.nan, "evaluations": 0,
                "status": "not located: fewer than two slip directions were solved"}
    found = locate(alpha_at, task.angles, task.values)
    if task.failed:
        found["status"] += f" ({task.failed} failed sample(s) left out of the bracket)"
    return {**row, **found}


def failed_minimum(task: MinimumTask, status: str, seconds: float = 0.0) -> dict:
    """The minimum row of a task whose solve failed."""
    return {"nu": task.nu, "size": task.size, "element": task.element,
            "slip_angle": math.nan, "positive": math.nan, "r_positive": math.nan,
            "bracket_lo": math.nan, "bracket_hi": math.nan, "evaluations": 0,
            "seconds": seconds, "status": status}
