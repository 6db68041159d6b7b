"""The sweep grid: points (nu, size, element[, slip angle]), parsing of --nu/--size/--element/
--slip-angle, empty rows."""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from ..case.numbers import FINITE_NUMBER, plain_integer, plain_number
from ..errors import CaseError
from ..fem.elements import NAMES

NU_POINTS = 11  # points of a range A:B given without N


#: what a sweep point computes into its positive/negative columns: the static critical
#: coefficients (``solve``) or the flutter thresholds of steady sliding (``stability``)
QUANTITIES = ("critical", "flutter")
MAX_POINTS = 10_000  # a sweep has at most this many points (nu x size x element)
NU_GAP = 1e-3  # a range reaching nu = 1/2 stops at 1/2 - min(NU_GAP, step / 2)
ANGLE_POINTS = 13  # points of a slip-angle range A:B given without N (every 30 degrees of 0:360)
ANGLE_RANGE = (-720.0, 720.0)  # the slip angles [solve] slip_angle accepts, degrees


@dataclass(frozen=True)
class Point:
    """One sweep point; ``size`` is None for a case with an inline mesh, ``slip_angle`` None
    when the sweep does not turn the slip direction (the case's own is used)."""

    nu: float
    size: float | None
    element: str
    slip_angle: float | None = None

    @property
    def key(self) -> tuple:
        key = (self.element, -1.0 if self.size is None else self.size, self.nu)
        return key if self.slip_angle is None else key + (self.slip_angle,)

    @property
    def group(self) -> tuple:
        return (self.size, self.element)


@dataclass
class Grid:
    """The values swept: every combination of ``nu`` x ``size`` x ``element`` (x
    ``slip_angle``, degrees, 3D bodies; None: the case's own slip direction)."""

    nu: list[float]
    size: list[float | None]
    element: list[str]
    notes: list[str] = field(default_factory=list)
    quantity: str = "critical"  # what a point computes: one of QUANTITIES
    slip_angle: list[float] | None = None

    def points(self) -> list[Point]:
        """All points, grouped by (size, element), then by slip angle, nu ascending within."""
        angles = [None] if self.slip_angle is None else self.slip_angle
        return [Point(nu, size, el, a) for el in self.element for size in self.size
                for a in angles for nu in self.nu]

    @property
    def directions(self) -> int:
        """Distinct slip directions up to reversal (angles modulo 180 degrees); 0 when the
        sweep does not turn the slip direction."""
        if self.slip_angle is None:
            return 0
        return len({round(a % 180.0, 9) % 180.0 for a in self.slip_angle})

    def to_json(self) -> dict:
        out = {"nu": list(self.nu), "size": list(self.size), "element": list(self.element)}
        if self.slip_angle is not None:
            out["slip_angle"] = list(self.slip_angle)
        return out if self.quantity == "critical" else {**out, "quantity": self.quantity}


def _float(text: str, what: str, within: str | None = None) -> float:
    """A plain finite number (:func:`critfric.case.numbers.plain_number`), part of the option
    value ``within``; -0 is 0."""
    return plain_number(text, what, allowed=FINITE_NUMBER, within=within) + 0.0


def _items(text: str, what: str) -> list[str]:
    """The comma-separated items of an option's value, none of them empty."""
    items = [v.strip() for v in text.split(",")]
    if not all(items):
        raise CaseError(f"got {text!r}: an empty item; allowed: values separated by single "
                        "commas", key=what)
    return items


def _range(text: str, key: str, allowed: str, default: int) -> tuple[float, float, int]:
    """``A:B[:N]`` -> (A, B, N), N ``default`` if not given; :class:`CaseError` naming
    ``key`` otherwise."""
    parts = text.split(":")
    if len(parts) not in (2, 3):
        raise CaseError(f"got {text!r}; allowed: {allowed}", key=key)
    lo, hi = _float(parts[0], key, text), _float(parts[1], key, text)
    if len(parts) == 2:
        return lo, hi, default
    allowed = f"N, an integer >= 2 and <= {MAX_POINTS} in ASCII digits"
    n = plain_integer(parts[2], key, allowed=allowed, within=text)
    if not 2 <= n <= MAX_POINTS:
        raise CaseError(f"got N = {parts[2][:20]!r}; allowed: {allowed}", key=key)
    return lo, hi, n


def parse_nu(text: str) -> tuple[list[float], list[str]]:
    """``A:B[:N]`` (N points from A to B, default 11) or ``v1,v2,...``; values, notes.

    Every value must lie in [0, 0.5); only a range may end at 0.5, and then its last point is
    moved to 0.5 - min(1e-3, step/2), never at the singular (incompressible) value itself.
    """
    notes: list[str] = []
    text = text.strip()
    allowed = "Poisson ratios in [0, 0.5): A:B[:N] (B may be 0.5) or v1,v2,..."
    if ":" in text:
        lo, hi, n = _range(text, "--nu", allowed, NU_POINTS)
        if not (0.0 <= lo < hi <= 0.5):
            raise CaseError(f"got {text!r}; allowed: 0 <= A < B <= 0.5", key="--nu")
        values = np.linspace(lo, hi, n)
        if hi == 0.5:
            values[-1] = 0.5 - min(NU_GAP, 0.5 * (values[-1] - values[-2]))
            notes.append(f"nu = 0.5 is singular (incompressible): the range is sampled up to "
                         f"nu = {values[-1]:.6g}, never at 0.5")
        return [float(f"{v:.12g}") for v in values], notes  # 0.15, not 0.15000000000000002
    if text.count(",") >= MAX_POINTS:
        raise CaseError(f"got {text.count(',') + 1} values; allowed: at most {MAX_POINTS}",
                        key="--nu")
    values = [_float(v, "--nu", text) for v in _items(text, "--nu")]
    bad = [v for v in values if not 0.0 <= v < 0.5]
    if not values or bad:
        raise CaseError(f"got {text!r}; allowed: {allowed}", key="--nu")
    return sorted(set(values)), notes


def parse_slip_angles(text: str) -> tuple[list[float], list[str]]:
    """``A:B[:N]`` (N points from A to B, ends included, default 13) or ``v1,v2,...``: slip
    angles in degrees within what ``[solve] slip_angle`` accepts; values, notes."""
    text = text.strip()
    lo_ok, hi_ok = ANGLE_RANGE
    allowed = (f"slip angles in degrees in [{lo_ok:g}, {hi_ok:g}]: A:B[:N] (N points, ends "
               "included) or v1,v2,...")
    if ":" in text:
        lo, hi, n = _range(text, "--slip-angle", allowed, ANGLE_POINTS)
        if not lo_ok <= lo < hi <= hi_ok:
            raise CaseError(f"got {text!r}; allowed: {lo_ok:g} <= A < B <= {hi_ok:g}",
                            key="--slip-angle")
        values = [float(f"{v:.12g}") for v in np.linspace(lo, hi, n)]
    else:
        if text.count(",") >= MAX_POINTS:
            raise CaseError(f"got {text.count(',') + 1} values; allowed: at most {MAX_POINTS}",
                            key="--slip-angle")
        values = sorted({_float(v, "--slip-angle", text) for v in _items(text, "--slip-angle")})
        if not values or not all(lo_ok <= v <= hi_ok for v in values):
            raise CaseError(f"got {text!r}; allowed: {allowed}", key="--slip-angle")
    turns = {round(v % 180.0, 9) % 180.0 for v in values}
    notes = []
    if len(turns) < len(values):
        notes.append(f"{len(values) - len(turns)} of the {len(values)} slip angles repeat "
                     "another's direction or its reverse: each angle also gives the curve at "
                     "angle + 180 (alpha(angle + 180) = -alpha(angle)), so angles in "
                     "[A, A + 180) cover every direction")
    return values, notes


def parse_sizes(text: str) -> list[float]:
    """``h1,h2,...``: distinct positive mesh sizes, coarsest first."""
    if text.count(",") >= MAX_POINTS:
        raise CaseError(f"got {text.count(',') + 1} sizes; allowed: at most {MAX_POINTS}",
                        key="--size")
    values = [_float(v, "--size", text) for v in _items(text, "--size")]
    if not values or any(v <= 0 for v in values):
        raise CaseError(f"got {text!r}; allowed: positive mesh sizes h1,h2,...", key="--size")
    return sorted(set(values), reverse=True)


def parse_elements(text: str) -> list[str]:
    """``P1,P2,...``: distinct element names."""
    values = _items(text, "--element")
    bad = [v for v in values if v not in NAMES]
    if not values or bad:
        raise CaseError(f"got {text!r}; allowed: a comma list of " + ", ".join(NAMES),
                        key="--element")
    return list(dict.fromkeys(values))


def empty_row(point: Point, status: str, seconds: float = 0.0) -> dict:
    """A row of a point without values (a failed point)."""
    return {"nu": point.nu, "size": point.size, "element": point.element,
            "slip_angle": getattr(point, "slip_angle", None), "h": math.nan,
            "n_dofs": -1, "n_contact": -1, "positive": [], "negative": [], "r_positive": [],
            "complex_count": -1, "seconds": seconds, "status": status}
