"""Files written safely: output checks, atomic HDF5 writes, write locks, Ctrl-C that is never lost."""

from __future__ import annotations

import errno
import os
import secrets
import shutil
import signal
import sys
import tempfile
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

import h5py

from ..errors import CaseError, WriteError


class Terminated(KeyboardInterrupt):
    """SIGTERM (a batch scheduler's stop) under an :class:`interrupt_guard`: handled as a
    Ctrl-C is (every write finished or undone, workers stopped), with exit code 143."""


_GUARDS: list = []  # the interrupt guards entered, innermost last


class interrupt_guard:
    """Ctrl-C that is never lost. SIGINT raises KeyboardInterrupt as usual (SIGTERM:
    :class:`Terminated`) and also sets a flag; :meth:`check` raises it again at a safe point.
    CPython drops (and prints) an exception raised inside a garbage-collection callback or
    ``__del__``: there the interrupt is kept silently for :meth:`check`. A no-op outside the
    main thread; a signal that is ignored stays ignored."""

    SIGNALS = ("SIGINT", "SIGTERM")

    def __enter__(self) -> interrupt_guard:
        self.hit = None  # the exception type to raise, once a signal came
        self._defer = 0
        self._saved = {}
        try:
            for name in self.SIGNALS:
                number = getattr(signal, name, None)
                if number is not None and signal.getsignal(number) is not signal.SIG_IGN:
                    self._saved[number] = signal.signal(number, self._handler)
        except ValueError:  # not the main thread
            return self
        self._hook = sys.unraisablehook
        sys.unraisablehook = self._unraisable
        _GUARDS.append(self)
        return self

    def _handler(self, signum, frame):
        self.hit = self.hit or (Terminated if signum == getattr(signal, "SIGTERM", None)
                                else KeyboardInterrupt)
        if not self._defer:
            raise self.hit

    @contextmanager
    def deferred(self) -> Iterator[None]:
        """Hold a Ctrl-C back until the block is done, then raise it: for a write and the
        record that it happened, so that what an interruption says matches what is on disk.
        Blocks nest: the outermost one raises."""
        self._defer += 1
        try:
            yield
        finally:
            self._defer -= 1
        if not self._defer:
            self.check()

    def _unraisable(self, info) -> None:
        if not (self.hit and issubclass(info.exc_type, KeyboardInterrupt)):
            self._hook(info)

    def check(self) -> None:
        """Raise KeyboardInterrupt (SIGTERM: :class:`Terminated`) if a signal came, even if
        it was swallowed."""
        if self.hit:
            raise self.hit

    def __exit__(self, *exc) -> None:
        if self in _GUARDS:
            _GUARDS.remove(self)
            sys.unraisablehook = self._hook
        for number, saved in self._saved.items():
            signal.signal(number, saved)


@contextmanager
def held() -> Iterator[None]:
    """A write that an interrupt never cuts in two: under an :class:`interrupt_guard`, a
    Ctrl-C or SIGTERM during the block is raised when it ends; outside one, nothing is held
    (the write must then undo itself)."""
    if _GUARDS:
        with _GUARDS[-1].deferred():
            yield
    else:
        yield


def _lock(fd: int) -> None:
    """An exclusive, non-blocking lock on an open file (OSError if another process has it)."""
    try:
        import fcntl
    except ImportError:  # Windows
        import msvcrt

        msvcrt.locking(fd, msvcrt.LK_NBLCK, 1)
        return
    fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)


@contextmanager
def output_lock(path: Path | str):
    """Hold an exclusive lock for writing ``path``; refuse at once if another process has it.

    The lock is ``flock`` on ``.<name>.lock`` in the same directory (so a killed writer never
    blocks a later run; a symbolic link there is refused, never followed); the file is removed
    when the lock is released.
    """
    path = Path(path)
    lock = path.with_name(f".{path.name}.lock")
    while True:
        try:
            fd = os.open(lock, os.O_RDWR | os.O_CREAT | getattr(os, "O_NOFOLLOW", 0), 0o644)
        except OSError as exc:  # a symbolic link planted as the lock: refused, not followed
            raise CaseError(f"cannot write in directory {str(path.parent)!r} ({exc.strerror}); "
                            "allowed: a file in a writable directory", file=str(path),
                            key="output.file") from None
        try:
            _lock(fd)
        except OSError:
            holder = os.read(fd, 64).decode(errors="replace").strip() or "unknown"
            os.close(fd)
            raise CaseError(f"is being written by another critfric process (pid {holder}); "
                            "wait for it to finish or choose another output file",
                            file=str(path), key="output.file") from None
        try:  # the lock file may have been removed by its previous holder: start again
            same = os.stat(lock).st_ino == os.fstat(fd).st_ino
        except FileNotFoundError:
            same = False
        if same:
            break
        os.close(fd)
    try:
        os.ftruncate(fd, 0)
        os.write(fd, str(os.getpid()).encode())
        yield path
    finally:
        try:
            os.unlink(lock)
        except FileNotFoundError:
            pass
        os.close(fd)


def check_output(path: Path, *, force: bool = False, inputs=(),
                 key: str | None = "output.file") -> Path:
    """Refuse an output path that cannot be written, that is one of the ``inputs`` (even
    under another name or through a link) or that is a symbolic link (never written through,
    never replaced), before any work is done; ``key`` is what the error names."""
    path = Path(path)
    for given in inputs:
        try:
            same = given is not None and os.path.samefile(path, given)
        except (OSError, ValueError):
            same = False
        if same:
            raise CaseError(f"is an input of this command ({given}); allowed: an output that "
                            "is not one of its inputs", file=str(path), key=key)
    try:
        link = os.path.islink(path)
    except ValueError:  # a NUL in the name: refused below
        link = False
    if link:
        raise CaseError("is a symbolic link; allowed: a path that is not a link (critfric "
                        "never writes through one)", file=str(path), key=key)
    try:
        os.stat(path)
    except FileNotFoundError:
        pass
    except (OSError, ValueError) as exc:  # name too long, a file used as a directory, NUL
        why = exc.strerror if isinstance(exc, OSError) and exc.strerror else str(exc)
        raise CaseError(f"cannot write this path ({why}); allowed: a file path in an existing "
                        "writable directory", file=str(path), key=key) from None
    if path.is_dir():
        raise CaseError("is a directory; allowed: a file path",
                        file=str(path), key=key)
    if path.exists() and not path.is_file():  # replacing it would remove a device or pipe
        raise CaseError("is not a regular file (a device, pipe or socket); allowed: a path to "
                        "a regular file or to none", file=str(path), key=key)
    if path.exists() and not force:
        raise CaseError("exists already; pass --force to overwrite it", file=str(path),
                        key=key)
    parent = path.parent if str(path.parent) else Path(".")
    if not parent.is_dir():
        raise CaseError(f"cannot write here: directory {str(parent)!r} does not exist; "
                        "allowed: a file in an existing writable directory", file=str(path),
                        key=key)
    if not os.access(parent, os.W_OK):
        raise CaseError(f"cannot write here: directory {str(parent)!r} is not writable; "
                        "allowed: a file in an existing writable directory", file=str(path),
                        key=key)
    return path


def _mode() -> int:
    """The permissions a new file gets here: 0o666 less the process umask."""
    mask = os.umask(0o022)
    os.umask(mask)
    return 0o666 & ~mask


#: the errors of a write that found no room: a full disk, a quota, the file-size limit
NO_ROOM = {errno.ENOSPC, errno.EFBIG} | ({errno.EDQUOT} if hasattr(errno, "EDQUOT") else set())


def write_whole(path: Path, data, *, keep_mode: bool = False) -> None:
    """Write the bytes ``data`` to ``path`` whole or not at all: to a temporary file beside
    it (the old file's permissions with ``keep_mode``, else the umask's), flushed to disk,
    then renamed over it. Any failure (an OSError, an interrupt) removes the temporary file,
    leaves ``path`` as it was and is raised as it came, for the caller to word."""
    path = Path(path)
    tmp = path.with_name(f".{path.name}.{secrets.token_hex(6)}.tmp")  # named before made:
    try:  # whatever stops this block finds it to remove
        mode = None
        if keep_mode:
            try:
                mode = os.stat(path).st_mode & 0o7777
            except FileNotFoundError:
                pass
        fd = os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL
                     | getattr(os, "O_NOFOLLOW", 0), 0o666)
        with open(fd, "wb") as out:
            if mode is not None:
                os.fchmod(out.fileno(), mode)
            out.write(data)
            out.flush()
            os.fsync(out.fileno())
        os.replace(tmp, path)
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise


def atomic_h5(path: Path, fill) -> Path:
    """Write an HDF5 file whole or not at all: built in memory, then :func:`write_whole`. A
    full disk or an I/O error leaves the old file unchanged and no temporary file behind, and
    is a :class:`WriteError` (exit 1)."""
    import io

    path = Path(path)
    buffer = io.BytesIO()
    with h5py.File(buffer, "w") as f:
        fill(f)
    try:
        write_whole(path, buffer.getbuffer())
    except OSError as exc:
        raise WriteError(f"cannot write {path} ({exc.strerror or exc}); nothing was "
                         "changed: free some space or choose another directory") from None
    return path


@contextmanager
def staged(paths: list[Path], *, key: str | None = "output.file"):
    """Yield temporary paths (same names, in a private directory beside the first target)
    to write; on success rename each over its target, else remove them all. A directory
    that cannot be written is a :class:`CaseError` naming ``key``."""
    paths = [Path(p) for p in paths]
    parent = paths[0].parent if str(paths[0].parent) else Path(".")
    try:
        tmp = Path(tempfile.mkdtemp(prefix=".critfric-", dir=parent))
    except OSError as exc:
        raise CaseError(f"cannot write in directory {str(parent)!r} ({exc.strerror}); "
                        "allowed: a file in an existing writable directory",
                        file=str(paths[0]), key=key) from None
    try:
        yield [tmp / p.name for p in paths]
        for p in paths:
            (tmp / p.name).chmod(_mode())
            os.replace(tmp / p.name, p)
    except OSError as exc:  # disk full, quota, file system gone: nothing partial is left
        raise WriteError(f"cannot write {paths[0]} ({exc.strerror or exc}); nothing was "
                         "changed: free some space or choose another directory") from None
    finally:
        shutil.rmtree(tmp, ignore_errors=True)