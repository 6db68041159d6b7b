"""Where sweep points run: local worker processes or a Dask distributed cluster.

Both yield ``(point, row)`` pairs as points finish, in whatever order; the caller writes them.

Scheduling keeps the points of one (size, element) group together so that a worker builds
each mesh once: groups are split only while one piece would cost more than a fair share of the
whole (cost ~ (order / size)^2 per point), then handed out largest first.

Local workers are ``spawn``-ed processes started with the BLAS/OpenMP thread variables set to 1
(numpy reads them when it loads), so J workers on J cores do not oversubscribe. A worker
that dies records its point as failed and is replaced. Ctrl-C and SIGTERM are the parent's
alone: a worker is born with both blocked (a signal to the process group during its start-up
is no traceback and no death), then ignores them; the parent, interrupted, kills every worker
at once (SIGKILL, no point is waited for) and reaps it. On a Dask cluster, the nannies set the
same variables by default; tasks are pinned to one worker per group (loosely, so a lost worker
does not stall the sweep).
"""

from __future__ import annotations

import math
import multiprocessing as mp
import os
import signal
from collections import deque
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from multiprocessing.connection import wait

import numpy as np

from ..errors import CaseError, SolverError
from ..fem.elements import get_element
from .grid import empty_row

THREAD_VARS = ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS",
               "BLIS_NUM_THREADS", "VECLIB_MAXIMUM_THREADS", "NUMEXPR_NUM_THREADS")
READY = "ready"  # a worker's first message
CONNECT_TIMEOUT = "10s"  # to reach a Dask scheduler
WORKER_WAIT = 60  # seconds to wait for a first Dask worker


# ------------------------------------------------------------------------------ scheduling
def _cost(point) -> float:
    return 1.0 if point.size is None else (get_element(point.element).order / point.size) ** 2


def make_chunks(points: list, jobs: int) -> list[list]:
    """Points grouped by (size, element); a group costing more than 1/jobs of the total is
    cut into that many nearly equal pieces. Largest first."""
    groups: dict[tuple, list] = {}
    for p in points:
        groups.setdefault(p.group, []).append(p)
    share = sum(_cost(p) for p in points) / max(jobs, 1)
    chunks = []
    for group in groups.values():
        k = min(len(group), max(1, math.ceil(sum(_cost(p) for p in group) / share - 1e-9)))
        cuts = np.cumsum([0] + [len(group) // k + (i < len(group) % k) for i in range(k)])
        chunks += [group[a:b] for a, b in zip(cuts[:-1], cuts[1:])]
    return sorted(chunks, key=lambda c: sum(_cost(p) for p in c), reverse=True)


# ------------------------------------------------------------------------------ local pool
@contextmanager
def pinned_threads():
    """The thread variables set to 1 (for processes started inside), restored after."""
    saved = {k: os.environ.get(k) for k in THREAD_VARS}
    os.environ.update({k: "1" for k in THREAD_VARS})
    try:
        yield
    finally:
        for k, v in saved.items():
            if v is None:
                os.environ.pop(k, None)
            else:
                os.environ[k] = v


STOP_SIGNALS = tuple(getattr(signal, name) for name in ("SIGINT", "SIGTERM")
                     if hasattr(signal, name))
WAIT_SECONDS = 0.5  # the parent wakes at least this often to honour a signal


@contextmanager
def signals_held() -> Iterator[None]:
    """Ctrl-C and SIGTERM blocked in this thread for the block, then delivered: a process
    started inside inherits them blocked, and one that comes meanwhile is raised once the
    worker is in the pool (so it is stopped with the others)."""
    if not hasattr(signal, "pthread_sigmask"):  # Windows
        yield
        return
    try:  # multiprocessing's resource tracker unblocks both after starting: start it first
        from multiprocessing import resource_tracker

        resource_tracker.ensure_running()
    except (ImportError, AttributeError, OSError):
        pass
    old = signal.pthread_sigmask(signal.SIG_BLOCK, STOP_SIGNALS)
    try:
        yield
    finally:
        signal.pthread_sigmask(signal.SIG_SETMASK, old)


def _ignore(signum, frame) -> None:
    """A worker's SIGTERM: the parent decides (a handler, not SIG_IGN, so that programs the
    worker starts get the default action back)."""


def _worker_main(conn, fn: Callable, spec: dict) -> None:
    """A worker process: run each chunk received, send one row per point; None stops."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # the parent decides what Ctrl-C does
    if hasattr(signal, "pthread_sigmask"):  # born with both blocked: now ignored instead
        signal.signal(signal.SIGTERM, _ignore)
        signal.pthread_sigmask(signal.SIG_UNBLOCK, STOP_SIGNALS)
    try:
        conn.send(READY)
        while (chunk := conn.recv()) is not None:
            for point in chunk:
                conn.send(fn(spec, point))
    except (EOFError, BrokenPipeError, OSError):
        pass


class _Worker:
    def __init__(self, ctx, fn, spec, pool: list, at: int | None = None):
        """Start a worker and put it in ``pool`` (at index ``at``, else at the end) before
        any Ctrl-C or SIGTERM that came meanwhile is raised."""
        self.conn, child = ctx.Pipe()
        self.pending: deque = deque()
        self.ready = False
        with signals_held():
            with pinned_threads():
                self.process = ctx.Process(target=_worker_main, args=(child, fn, spec),
                                           daemon=True)
                try:
                    self.process.start()
                finally:
                    child.close()
            if at is None:
                pool.append(self)
            else:
                pool[at] = self

    def stop(self, *, kill: bool) -> None:
        if self.process.is_alive() and not kill:
            try:
                self.conn.send(None)
            except OSError:
                pass
            self.process.join(5)
        if self.process.is_alive():
            self.process.kill()
            self.process.join(5)
        self.conn.close()


def run_local(jobs: int, fn: Callable, spec: dict, points: list) -> Iterator[tuple]:
    """Run ``fn(spec, point)`` over ``jobs`` spawned processes; yield (point, row)."""


    ctx = mp.get_context("spawn")
    queue = deque(make_chunks(points, jobs))
    pool: list[_Worker] = []
    clean = False
    try:
        for _ in range(min(jobs, len(queue))):
            _Worker(ctx, fn, spec, pool)
        for w in pool:
            _assign(w, queue)
        while any(w.pending for w in pool):
            busy = [w for w in pool if w.pending]
            wait([w.conn for w in busy] + [w.process.sentinel for w in busy], WAIT_SECONDS)
            for i, w in enumerate(pool):
                if not w.pending:
                    continue
                try:
                    row = w.conn.recv() if w.conn.poll() else None
                except (EOFError, OSError):
                    row = None
                if row == READY:
                    w.ready = True
                elif row is not None:
                    yield w.pending.popleft(), row
                    if not w.pending:
                        _assign(w, queue)
                elif not w.process.is_alive():
                    if not w.ready:
                        raise SolverError(
                            f"a sweep worker process failed to start (exit code "
                            f"{w.process.exitcode}); run with --jobs 1 to see why. From a "
                            "script, start the sweep under `if __name__ == '__main__':`")
                    point = w.pending.popleft()
                    code = w.process.exitcode
                    yield point, empty_row(point, f"failed: the worker process died "
                                                  f"(exit code {code})")
                    if w.pending:
                        queue.appendleft(list(w.pending))
                    w.stop(kill=True)
                    _Worker(ctx, fn, spec, pool, at=i)
                    _assign(pool[i], queue)  # noqa: PLR1736 -- pool[i] is the new worker
        clean = True
    finally:
        for w in pool:
            w.stop(kill=not clean)


def _assign(w: _Worker, queue: deque) -> None:
    if queue:
        chunk = queue.popleft()
        w.pending.extend(chunk)
        w.conn.send(chunk)


# ------------------------------------------------------------------------------ Dask
def connect_dask(address: str):
    """A ``distributed.Client`` of the scheduler at ``address`` (bad address: CaseError)."""
    try:
        from distributed import Client
    except ImportError:
        raise CaseError("needs dask.distributed: pip install 'critfric[dask]'",
                        key="--scheduler") from None
    try:
        return Client(address, timeout=CONNECT_TIMEOUT)
    except (OSError, TimeoutError, ValueError) as exc:
        raise CaseError(f"cannot connect to the Dask scheduler at {address!r}: {exc}",
                        key="--scheduler") from None


def run_dask(client, fn: Callable, spec: dict, points: list) -> Iterator[tuple]:
    """Run ``fn(spec, point)`` on the cluster of ``client``; yield (point, row)."""
    from distributed import as_completed



    futures = {}
    try:
        try:
            client.wait_for_workers(1, timeout=WORKER_WAIT)
        except TimeoutError:
            raise CaseError(f"the Dask scheduler has no worker after {WORKER_WAIT} s; start "
                            "some (dask worker ADDRESS)", key="--scheduler") from None
        slots = sorted(client.nthreads())
        load = {w: 0.0 for w in slots}
        for chunk in make_chunks(points, len(slots)):
            target = min(slots, key=load.__getitem__)
            load[target] += sum(_cost(p) for p in chunk)
            for p in chunk:
                fut = client.submit(fn, spec, p, workers=[target], allow_other_workers=True,
                                    pure=False)
                futures[fut] = p
        for fut in as_completed(list(futures)):
            point = futures.pop(fut)
            try:
                row = fut.result()
            except Exception as exc:
                row = empty_row(point, f"failed: {type(exc).__name__}: {exc}")
            yield point, row
    finally:
        if futures:
            client.cancel(list(futures))
