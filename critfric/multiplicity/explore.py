"""Following every solution curve of (2.8) along a parameter, piece by piece.

The solution set is a union of pieces (:mod:`.arcs`), each in one contact state, meeting at
*vertices*, where a node's values reach the boundary between two statuses. At a vertex, the
states of which the point is a solution (every combination of the statuses each node is
consistent with) give the pieces that leave it, both ways in the parameter; a state whose
system is singular there (the friction is a critical coefficient of it) gives the continuum
z + c n both ways along its null vectors. Pieces are told apart by their midpoints: a piece
already walked (from either end) is not walked again, so the exploration ends.

Events: two pieces at a vertex with the same direction in the parameter make a kink (the
status of a node changes), with opposite directions a fold (the curve turns back); a vertex
with a singular state or more than two pieces is a branch point. A piece may also end where
the solution grows without bound (a pole of a friction piece that is not removable): a branch
point at infinity.

Where more than MAX_STATES states meet at a vertex (nodes at the vertex of their Coulomb law,
as at the origin of a load that starts from zero), the pieces leaving it are those of the
Newton solution a step PROBE (relative to the range) away, each way.
"""

from __future__ import annotations

import itertools
from collections import OrderedDict
from dataclasses import dataclass, field

import numpy as np

from ..errors import SolverError
from ..solvers import coulomb
from .arcs import MIN_STEP, State, Track
from .loadstate import LoadState, Singular
from .pathresult import Curve, Event, PathPoint, Piece
from .states import FREE, LABELS, SLIP_MINUS, SLIP_PLUS, STUCK

MAX_STATES = 64
STATE_BYTES = 1 << 30  # factored states kept for reuse
SAME_TOL = 1e-7
PROBE = 1e-6
CODES = {"free": FREE, "stuck": STUCK, "slip+": SLIP_PLUS, "slip-": SLIP_MINUS, "cone": STUCK}


class Points:
    """Points (scaled keys, the parameter first) with a value each, found again within
    SAME_TOL; bucketed by the parameter, so a look-up costs the few points near it."""

    WIDTH = 1e-6  # bucket width in the scaled parameter (> SAME_TOL)

    def __init__(self):
        self.buckets: dict[int, list[tuple[np.ndarray, object]]] = {}

    def find(self, key: np.ndarray):
        """(value,) of a point within SAME_TOL of key, or None."""
        b = int(np.floor(key[0] / self.WIDTH))
        for near in (b - 1, b, b + 1):  # the point's bucket and its neighbours
            for k, value in self.buckets.get(near, ()):
                if np.abs(k - key).max() <= SAME_TOL:
                    return (value,)
        return None

    def add(self, key: np.ndarray, value=None) -> None:
        self.buckets.setdefault(int(np.floor(key[0] / self.WIDTH)), []).append((key, value))


@dataclass
class Way:
    """How a curve reaches a vertex: in ``state``, along d (+1/-1, 0 on a continuum)."""

    state: State
    d: int


@dataclass
class Arc:
    """A piece leaving a vertex: in ``state``, along the parameter (d = +1/-1) or along the
    null vector n at fixed t (d = 0); its end (t1, z1), z1 None where it is unbounded."""

    state: State
    t0: float
    z0: np.ndarray
    d: int
    t1: float
    z1: np.ndarray | None
    why: str
    n: np.ndarray | None = None
    c1: float = 0.0
    key: np.ndarray = field(default=None, repr=False)

    def at(self, frac: float) -> tuple[float, np.ndarray]:
        """The point a fraction of the way along (the middle of an unbounded null arc: c=1)."""
        if self.d == 0:
            c = frac * self.c1 if np.isfinite(self.c1) else 1.0
            return self.t0, self.z0 + c * self.n
        t = self.t0 + frac * (self.t1 - self.t0)
        return t, self.state.solve(t)


class Explorer:
    """Curves, events and pieces of one path (``samples``: values every curve holds)."""

    def __init__(self, track: Track, samples: np.ndarray, max_pieces: int):
        self.track, self.cz, self.samples = track, track.cz, samples
        self.max_pieces = max_pieces
        self.states: OrderedDict[bytes, State] = OrderedDict()
        self.pending: list[tuple[Piece, State]] = []  # pieces whose margins are to come
        self.walked = Points()  # midpoints of the pieces walked
        self.vertices = Points()  # vertices reached, with their event (or None)
        self.curves: list[Curve] = []
        self.events: list[Event] = []
        self.hits: dict[int, list[np.ndarray]] = {}  # sample index -> points on curves
        self.notes: list[str] = []
        self.continua: list[tuple[np.ndarray, int]] = []  # null piece key -> branch event
        self.pieces = 0

    # ------------------------------------------------------------------ geometry
    def key(self, t: float, z: np.ndarray) -> np.ndarray:
        return np.concatenate([[t / self.track.length], self.cz.norm(z, self.track.u0(t))])

    def state(self, code) -> State:
        """The state of ``code``, factored once while it is among the recently used ones
        (at most what STATE_BYTES holds: a path meets the same state only near where it met
        it before)."""
        code = np.asarray(code, dtype=np.int8)
        k = code.tobytes()
        if k in self.states:
            self.states.move_to_end(k)
            return self.states[k]
        self.states[k] = self._make(code)
        if len(self.states) > max(8, STATE_BYTES // (16 * (2 * self.cz.p) ** 2)):
            self.states.popitem(last=False)
        return self.states[k]

    def _make(self, code: np.ndarray) -> State:
        """A load path's state on its displacement unknowns (n_u = p0 + 2 p_free, cheaper),
        on its contact forces where the fixed friction is a critical value of it."""
        if self.track.parameter == "load":
            try:
                return LoadState(self.track, code)
            except Singular:
                pass
        return State(self.track, code)

    def point(self, t: float, z: np.ndarray, piece: int) -> PathPoint:
        Un, Ut, X, Y = self.cz.contact(z, self.track.u0(t))
        f = self.track.friction(t)
        return PathPoint(float(t), self.cz.labels(z, f, self.track.u0(t)), Un, Ut, X, Y, piece)

    # ------------------------------------------------------------------ arcs at a vertex
    def arcs(self, t: float, z: np.ndarray, known: tuple | None = None
             ) -> tuple[list[Arc], list[State]]:
        """Every piece leaving the vertex (t, z), one per geometric piece, and the singular
        states there. ``known``: (code, d) of a piece known to leave it (the one a curve
        arrived by, walked back), not searched again."""
        f, u0 = self.track.friction(t), self.track.u0(t)
        ok = self.cz.consistent(z, f, u0)
        if not ok.any(axis=1).all():
            self.notes.append(f"a curve ends at {t:.10g}: its end is no solution to "
                              "CONSISTENT_TOL at every node (round-off); the path may be "
                              "incomplete there")
            return [], []
        counts = ok.sum(axis=1)
        if np.prod(counts, dtype=float) > MAX_STATES:
            return self._probed(t, z), []
        _, cols = np.nonzero(ok)  # the statuses of each node, in node order
        options = np.split(cols, np.cumsum(counts)[:-1])
        found, singular = [], []
        for code in itertools.product(*options):  # the few states that meet at a vertex
            st = self.state(code)
            crit = st.singular_at(f)
            if crit is not None:
                nulls = self._null_arcs(st, t, z)
                if nulls:  # a continuum leaves the vertex: a branch point (else no solution
                    singular.append(st)  # but the vertex lies along the null direction)
                found += nulls
                if self.track.parameter == "load":
                    continue
                lim = st.limit(f)
                if lim is None or np.abs(self.cz.norm(lim - z, 0 * u0)).max() > SAME_TOL:
                    continue
            for d in (1, -1):
                if known is not None and d == known[1] and np.array_equal(st.code, known[0]):
                    continue
                end = st.exit(t, z, d)
                if end is not None:
                    found.append(Arc(st, t, z, d, *end))
        return self._distinct(found), singular

    def _null_arcs(self, st: State, t, z) -> list[Arc]:
        out = []
        N = st.null(self.track.friction(t))
        for j in range(N.shape[1]):  # the null vectors (one, but for degenerate states)
            for n in (N[:, j], -N[:, j]):
                end = st.null_exit(t, z, n)
                if end is not None:
                    out.append(Arc(st, t, z, 0, t, end[1], "row" if end[1] is not None
                                   else "unbounded", n=n, c1=end[0]))
        return out

    def _probed(self, t, z) -> list[Arc]:
        """The pieces of the Newton solutions a step PROBE away, each way."""
        out = []
        for d in (1, -1):
            s = t + d * PROBE * self.track.length
            if not self.track.span[0] <= s <= self.track.span[1]:
                continue
            code = [CODES[w] for w in self.cz.labels(self._newton(s, z), self.track.friction(s),
                                                      self.track.u0(s))]
            st = self.state(code)
            if st.singular_at(self.track.friction(t)) is None:
                end = st.exit(t, z, d)
                if end is not None:
                    out.append(Arc(st, t, z, d, *end))
        if out:
            self.notes.append(f"at {t:.10g} more than {MAX_STATES} contact states meet: the "
                              "pieces leaving it are those of the Newton solution")
        return self._distinct(out)

    def _newton(self, t: float, z: np.ndarray) -> np.ndarray:
        """The contact forces of the Newton solution at t, from z."""
        cz, u0 = self.cz, self.track.u0(t)
        found = coulomb.solve(cz.problem, self.track.friction(t), condensed=(cz.cond, u0),
                              start=u0 + cz.C @ z, tol=1e-12)
        return np.concatenate([found.X, found.Y])

    def _distinct(self, arcs: list[Arc]) -> list[Arc]:
        """One arc per geometric piece: of arcs that coincide, the shortest (ties: the most
        slipping nodes); each with the key of its midpoint."""
        arcs = sorted(arcs, key=lambda a: (abs(a.t1 - a.t0) if a.d else a.c1, -len(a.state.slip)))
        kept: list[Arc] = []
        for a in arcs:  # a handful of candidates
            a.key = self.key(*a.at(0.5))
            if not any(b.d == a.d and self._same(a, b) for b in kept):
                kept.append(a)
        return kept

    def _same(self, a: Arc, b: Arc) -> bool:
        """Whether two arcs leaving one vertex the same way coincide (on the shorter)."""
        if a.d == 0:
            return np.abs(self.cz.norm(a.n - b.n, 0 * self.cz.u0)).max() <= SAME_TOL
        t, z = a.at(0.5)
        return np.abs(self.key(t, z) - self.key(t, b.state.solve(t))).max() <= SAME_TOL

    def _retraces(self, a: Arc, arrival: Arc) -> bool:
        """Whether ``a`` leaves the vertex back along the piece the curve ``arrival`` came by:
        another state with the same solutions there (a slipping and a free node where X = Y
        = 0), not another piece."""
        if not arrival.d or a.d != -arrival.d:
            return False
        span = min(abs(a.t1 - arrival.t1), abs(arrival.t1 - arrival.t0))
        t = arrival.t1 + a.d * 0.5 * span
        return span > 0 and np.abs(self.key(t, a.state.solve(t))
                                   - self.key(t, arrival.state.solve(t))).max() <= SAME_TOL

    def _walked(self, arc: Arc) -> bool:
        return self.walked.find(arc.key) is not None

    def _vertex(self, t, z) -> tuple | None:
        """(event or None,) of a known vertex at (t, z), or None if it is new."""
        return self.vertices.find(self.key(t, z))

    # ------------------------------------------------------------------ walking
    def seed(self, t: float, z: np.ndarray, seed) -> None:
        """Follow every curve through the solution (t, z) not yet on one."""
        if self._vertex(t, z) is not None:
            return
        arcs, singular = self.arcs(t, z)
        inside = (not singular and len(arcs) == 2 and arcs[0].d == -arcs[1].d
                  and np.array_equal(arcs[0].state.code, arcs[1].state.code))
        back = min(arcs, key=lambda a: a.d) if inside else None
        if back is not None and back.z1 is not None:  # inside a piece: start at its end
            t, z = back.t1, back.z1
            arcs, singular = self.arcs(t, z)
        ci = self._curve(seed, t, z)
        fresh = [a for a in arcs if not self._walked(a)]
        if not singular and len(arcs) == 2 and len(fresh) == 2:  # one curve through it
            first, then = fresh
            event = self._event(Way(first.state, -first.d), [then], [], t, ci, z)
            self.vertices.add(self.key(t, z), event)
            self._run([(ci, first)])
            self._turn(self.curves[ci])
            self._run([(ci, then)])
            return
        event = self._event(None, arcs, singular, t, ci, z)
        self.vertices.add(self.key(t, z), event)
        self._run(self._spread(ci, fresh, t, z, event))

    def finish(self) -> None:
        """Drop the curves spawned at a branch point whose piece another curve walked first,
        and renumber the events' curves."""
        self._margins()
        keep = [i for i, c in enumerate(self.curves)
                if c.pieces or not (isinstance(c.seed, dict) and "event" in c.seed)]
        new = {old: i for i, old in enumerate(keep)}
        self.curves = [self.curves[i] for i in keep]
        for e in self.events:
            e.curves = sorted({new[c] for c in e.curves if c in new})

    def _curve(self, seed, t, z) -> int:
        self.curves.append(Curve(seed))
        self._add(len(self.curves) - 1, t, z, 0)
        return len(self.curves) - 1

    def _spread(self, ci, fresh, t, z, event) -> list[tuple[int, Arc]]:
        """The current curve goes on along the first fresh arc, each other starts a curve."""
        todo = [(ci, fresh[0])] if fresh else []
        for arc in fresh[1:]:
            cj = self._curve({"value": float(t), "event": event}, t, z)
            if event is not None:
                self.events[event].curves.append(cj)
            todo.append((cj, arc))
        return todo

    def _run(self, todo: list[tuple[int, Arc]]) -> None:
        while todo:  # spawned curves wait here until the current one ends
            ci, arc = todo.pop(0)
            todo += self._walk(ci, arc)

    def _walk(self, ci: int, arc: Arc) -> list[tuple[int, Arc]]:
        """Walk from arc to arc along curve ci; return the curves spawned on the way."""
        curve, spawned, same = self.curves[ci], [], False
        while arc is not None:
            if self._walked(arc):
                return spawned
            self.pieces += 1
            if self.pieces > self.max_pieces:
                raise SolverError(f"the path needs more than {self.max_pieces} pieces; "
                                  "shorten [path] range, or raise [path] max_pieces")
            self.walked.add(arc.key)
            st = arc.state
            if same:  # the state goes on through a vertex where a row only touched 0
                curve.pieces[-1] = self._piece(arc, start=curve.pieces[-1].start)
            else:
                curve.pieces.append(self._piece(arc))
            k = len(curve.pieces) - 1
            if arc.d:
                lo, hi = sorted((arc.t0, arc.t1))
                inside = self.samples[(self.samples > lo + MIN_STEP * self.track.length)
                                      & (self.samples < hi - MIN_STEP * self.track.length)]
                for t in inside[::arc.d]:
                    self._add(ci, t, st.solve(t), k)
            if arc.z1 is None:
                self._unbounded(ci, arc)
                return spawned
            t, z = arc.t1, arc.z1
            self._add(ci, t, z, k)
            known = self._vertex(t, z)
            if known is not None and known[0] is not None:
                self.events[known[0]].curves.append(ci)
            arcs, singular = self.arcs(t, z, (arc.state.code, -arc.d) if arc.d else None)
            others = [a for a in arcs if np.abs(a.key - arc.key).max() > SAME_TOL
                      and not self._retraces(a, arc)]
            fresh = [a for a in others if not self._walked(a)]
            event = None if known is not None else self._event(arc, others, singular, t, ci,
                                                               z)
            if known is None:
                self.vertices.add(self.key(t, z), event)
            todo = self._spread(ci, fresh, t, z, event)
            spawned += todo[1:]
            nxt = todo[0][1] if todo else None
            same = (nxt is not None and event is None and len(others) == 1 and nxt.d == arc.d
                    and np.array_equal(nxt.state.code, arc.state.code))
            arc = nxt
        return spawned

    def _piece(self, arc: Arc, start: float | None = None) -> Piece:
        """The piece of an arc (``start``: where the piece it extends began); its critical
        values and margin are filled in by :meth:`finish`."""
        t0 = arc.t0 if start is None else start
        piece = Piece([LABELS[c] for c in arc.state.code], float(t0), float(arc.t1))
        self.pending.append((piece, arc.state))
        return piece

    def _margins(self) -> None:
        for piece, st in self.pending:  # every piece: its state's critical values
            pos, neg = st.margins()
            f = max(abs(self.track.friction(piece.start)), abs(self.track.friction(piece.end)))
            piece.critical = (pos, neg)
            piece.margin = pos / f if pos is not None and f > 0 else None
        self.pending = []

    def _add(self, ci: int, t: float, z: np.ndarray, piece: int) -> None:
        self.curves[ci].points.append(self.point(t, z, piece))
        at = np.flatnonzero(np.abs(self.samples - t) <= MIN_STEP * self.track.length)
        for k in at:
            self.hits.setdefault(int(k), []).append(self.key(t, z))

    def _event(self, arc, others, singular, t, ci, z) -> int | None:
        """Record the event at a vertex (t, z) reached by ``arc`` (None: a seed) with the
        arcs ``others`` leaving it; return its index (None: no event). Only an admissible
        continuum makes a singular state a branch point; on the zero solution (no load, no
        reference displacement) every status holds at once, so a change of status there is
        no kink or fold."""
        states = ([arc.state] if arc else []) + [a.state for a in others]
        if singular:  # a continuum: one branch event for it, whichever end comes first
            nulls = [a.key for a in ([arc] if isinstance(arc, Arc) else []) + others
                     if a.d == 0]
            for k, e in self.continua:
                if any(np.abs(k - n).max() <= SAME_TOL for n in nulls):
                    self.events[e].curves.append(ci)
                    return e
            f = self.track.friction(t)
            crit = singular[0].critical
            event = Event("branch", float(t), singular[0].slip.tolist(),
                          float(crit[np.argmin(np.abs(crit - f))]), [ci],
                          [[LABELS[c] for c in s.code] for s in states])
            self.events.append(event)
            self.continua += [(n, len(self.events) - 1) for n in nulls]
            return len(self.events) - 1
        if not np.any(z) and not np.any(self.track.u0(t)):
            return None
        if len(others) >= 2 + (arc is None):
            kind = "branch"
        elif len(others) == 1 and arc is not None:
            o = others[0]
            if np.array_equal(o.state.code, arc.state.code) and o.d == arc.d:
                return None
            kind = "fold" if arc.d and o.d and o.d != arc.d else "kink"
        else:
            return None
        codes = np.array([s.code for s in states])
        nodes = np.flatnonzero((codes != codes[0]).any(axis=0)).tolist()
        self.events.append(Event(kind, float(t), nodes, None, [ci],
                                 [[LABELS[c] for c in s.code] for s in states]))
        return len(self.events) - 1

    def _unbounded(self, ci: int, arc: Arc) -> None:
        if arc.why == "pole":
            self.events.append(Event("branch", float(arc.t1), [], float(arc.t1), [ci],
                                     [[LABELS[c] for c in arc.state.code]], unbounded=True))
        else:
            self.notes.append(f"a continuum at {arc.t0:.10g} is unbounded: the solutions "
                              "grow without bound along it")

    def _turn(self, curve: Curve) -> None:
        """Reverse a curve walked backwards from its seed."""
        n = len(curve.pieces)
        curve.points.reverse()
        for pt in curve.points:
            pt.piece = n - 1 - pt.piece if n else 0
        curve.pieces.reverse()
        for pc in curve.pieces:
            pc.start, pc.end = pc.end, pc.start
