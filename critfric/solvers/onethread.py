"""One kept thread that runs the functions given to it one at a time, in order
(:class:`OneThread`): every MKL call of the process runs in one such thread
(:data:`critfric.solvers.pardiso.MKL_THREAD`)."""

from __future__ import annotations

import os
import queue
import threading
import weakref
from collections.abc import Callable
from concurrent.futures import Future


class OneThread:
    """One daemon thread, started on first use and kept, that runs the functions given to it
    one at a time, in order; a call from within it (one those functions make, a finalizer
    the garbage collector runs there) runs at once. A forked child starts its own. Not a
    ThreadPoolExecutor: its thread refuses work once the interpreter shuts down, when the
    finalizers release the factors left, and a call from within it would wait on itself."""

    def __init__(self, name: str):
        self._name = name
        self._start = threading.Lock()
        self._thread: threading.Thread | None = None
        self._queue: queue.SimpleQueue = queue.SimpleQueue()
        self._waiting = 0  # calls that a caller may wait on, queued or running
        if hasattr(os, "register_at_fork"):  # POSIX
            os.register_at_fork(after_in_child=self._forget)

    def submit(self, fn: Callable, *args) -> Future:
        """fn(*args) queued; its future."""
        future: Future = Future()
        self._queued(future, fn, args)
        return future

    def post(self, fn: Callable, *args) -> None:
        """fn(*args) queued for nobody to wait on (a release: the caller goes on meanwhile,
        and a later call runs after it); its error is dropped, and :attr:`idle` does not
        count it."""
        self._queued(None, fn, args)

    def _queued(self, future: Future | None, fn: Callable, args: tuple) -> None:
        if threading.current_thread() is self._thread:
            outcome = _run(fn, args)
            if future is not None:
                _settle(future, *outcome)
            return
        with self._start:
            if self._thread is None:
                self._thread = threading.Thread(target=self._serve, name=self._name,
                                                daemon=True)
                self._thread.start()
                # at exit, after the finalizers made later (the factors' releases): the
                # posted calls end before the process does
                weakref.finalize(self, self._drain)
            self._waiting += future is not None
        self._queue.put((future, fn, args))

    @property
    def idle(self) -> bool:
        """No call that a caller may wait on is queued or running (posted ones aside)."""
        return self._waiting == 0

    def call(self, fn: Callable, *args):
        """fn(*args) run in the thread; its value (or its exception, raised here)."""
        return self.submit(fn, *args).result()

    def _serve(self) -> None:
        while True:
            future, fn, args = self._queue.get()
            outcome = _run(fn, args)
            if future is not None:
                with self._start:  # counted done before the waiting caller wakes
                    self._waiting -= 1
                _settle(future, *outcome)
            del future, fn, args, outcome  # the arrays of a call live no longer than it

    def _drain(self) -> None:
        """Wait for every call queued so far (posted ones included)."""
        if self._thread is not None and threading.current_thread() is not self._thread:
            self.call(int)

    def _forget(self) -> None:
        self._start, self._thread, self._waiting = threading.Lock(), None, 0
        self._queue = queue.SimpleQueue()


def _run(fn: Callable, args: tuple) -> tuple:
    try:
        return fn(*args), None
    except BaseException as exc:  # noqa: BLE001 - raised in the waiting thread
        return None, exc


def _settle(future: Future, value, error: BaseException | None) -> None:
    if error is None:
        future.set_result(value)
    else:
        future.set_exception(error)
