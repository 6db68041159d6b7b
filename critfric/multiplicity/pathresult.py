"""What ``critfric path`` finds: solution curves of the static problem (2.8) along a parameter,
the pieces they are made of (one contact state each) and the events on them.

A *curve* is a chain of *pieces*; on a piece every contact node keeps one status (free, stuck,
slip+, slip-), so the piece is a segment (load path) or a rational curve (friction path) of
the condensed unknowns. A *point* is one exact solution on a curve. *Events* are where pieces
meet: a kink (a node changes status and the curve goes on), a fold (the curve turns back in
the parameter) or a branch point (a piece whose linear system is singular: the friction is a
critical coefficient of its contact state, and a continuum of solutions joins curves there).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

PARAMETERS = ("friction", "load")
EVENT_KINDS = ("kink", "fold", "branch")


@dataclass
class PathPoint:
    """One solution on a curve: the parameter value, the status word of each contact node
    (free, stuck, slip+, slip-, cone) and the contact values along Gamma_C (sorted along t).
    ``piece``: index of the curve's piece it lies on."""

    value: float
    status: list[str]
    Un: np.ndarray
    Ut: np.ndarray
    X: np.ndarray
    Y: np.ndarray
    piece: int = 0

    def to_json(self) -> dict:
        return {"value": float(self.value), "status": list(self.status),
                "Un": self.Un.tolist(), "Ut": self.Ut.tolist(), "X": self.X.tolist(),
                "Y": self.Y.tolist()}


@dataclass
class Piece:
    """A stretch of a curve in one contact state (``state``: free, stuck, slip+ or slip- per
    node), from parameter ``start`` to ``end`` (equal on a continuum at a branch point).
    ``critical``: the lowest positive and the negative of lowest modulus critical coefficient
    of the state (eigenproblem (3.2); None: none real, or no slipping node); ``margin``: the
    positive one over the largest friction on the piece (None without one)."""

    state: list[str]
    start: float
    end: float
    critical: tuple[float | None, float | None] = (None, None)
    margin: float | None = None

    def to_json(self) -> dict:
        return {"state": list(self.state), "start": float(self.start), "end": float(self.end),
                "critical": {"positive": self.critical[0], "negative": self.critical[1]},
                "margin": self.margin}


@dataclass
class Curve:
    """Points and pieces of one solution curve. ``seed``: "start" (the solution at the start
    of the range), {"value": t} (a solution that the enumeration at t found on no curve yet) or
    {"value": t, "event": k} (a curve leaving branch point k)."""

    seed: Any
    points: list[PathPoint] = field(default_factory=list)
    pieces: list[Piece] = field(default_factory=list)

    def to_json(self) -> dict:
        return {"seed": self.seed, "points": [p.to_json() for p in self.points],
                "pieces": [p.to_json() for p in self.pieces]}


@dataclass
class Event:
    """A kink, fold or branch point at parameter ``value``: the contact nodes whose status
    changes there, the critical coefficient of the singular state (branch points; None
    otherwise) and the curves that meet there. ``unbounded``: a branch point that a curve
    reaches only at infinity (the solution grows without bound as the friction tends to the
    critical coefficient)."""

    kind: str
    value: float
    nodes: list[int]
    critical: float | None
    curves: list[int]
    states: list[list[str]] = field(default_factory=list)
    unbounded: bool = False

    def to_json(self) -> dict:
        return {"kind": self.kind, "value": float(self.value), "nodes": list(self.nodes),
                "critical": self.critical, "curves": list(self.curves),
                "states": [list(s) for s in self.states], "unbounded": self.unbounded}


@dataclass
class PathResult:
    """Every curve found along ``parameter`` over ``range``, with its events.

    Attributes
    ----------
    friction
        The fixed friction of a load path (None for a friction path).
    samples
        The parameter values at which each curve holds a point (and, on small problems,
        where every solution was enumerated).
    isolated
        Solutions the enumeration found at a sample value on no curve that could be
        followed (said, never dropped), as (value, PathPoint).
    s
        (p,) arc length of each contact node along Gamma_C.
    node
        The contact node whose tangential displacement the diagram shows.
    """

    parameter: str
    range: tuple[float, float]
    curves: list[Curve]
    events: list[Event]
    n_dofs: int
    n_contact: int
    seconds: float
    friction: float | None = None
    samples: np.ndarray = field(default_factory=lambda: np.zeros(0))
    isolated: list[tuple[float, PathPoint]] = field(default_factory=list)
    s: np.ndarray = field(default_factory=lambda: np.zeros(0))
    node: int = 0
    notes: list[str] = field(default_factory=list)
    case: Any = field(default=None, repr=False)
    mesh: Any = field(default=None, repr=False)
    contact_nodes: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=int))

    def to_json(self) -> dict:
        """The JSON of ``critfric path --json``."""
        return {"parameter": self.parameter, "range": [float(v) for v in self.range],
                "friction": self.friction,
                "curves": [c.to_json() for c in self.curves],
                "events": [e.to_json() for e in self.events],
                "isolated": [{"value": float(t), **p.to_json()} for t, p in self.isolated],
                "node": int(self.node), "n_dofs": int(self.n_dofs),
                "n_contact": int(self.n_contact), "seconds": float(self.seconds),
                "notes": list(self.notes)}

    def counts(self) -> dict[str, int]:
        """Pieces, kinks, folds and branch points: the numbers a table shows."""
        kinds = [e.kind for e in self.events]
        return {"curves": len(self.curves), "pieces": sum(len(c.pieces) for c in self.curves),
                **{f"{k}s" if k != "branch" else "branches": kinds.count(k) for k in EVENT_KINDS}}
