"""The command line: thin typer commands over the library's plain functions."""

import os
import sys


def main() -> None:
    """The ``critfric`` command. Ctrl-C at any moment, start-up included, exits 130 with one
    line and no traceback."""
    # numpy asks the kernel for huge pages on large arrays (madvise); where the kernel then
    # compacts memory on the first touch (THP defrag "madvise", the common default) that
    # doubled the assembly of a 1.2 M-DOF matrix (3.6 s against 1.7 s, measured). Set before
    # numpy is imported; sweep workers inherit it; a user's own setting wins.
    os.environ.setdefault("NUMPY_MADVISE_HUGEPAGE", "0")
    # a Ctrl-C that lands in a callback Python runs for itself (an import lock's weakref
    # callback during start-up) is printed as "Exception ignored ... Traceback" and dropped:
    # kept instead, and honoured once the imports are done
    swallowed, previous = [], sys.unraisablehook

    def unraisable(info) -> None:
        if issubclass(info.exc_type, KeyboardInterrupt):
            swallowed.append(info.exc_type)
        else:
            previous(info)

    sys.unraisablehook = unraisable
    try:  # from the first import on (a Ctrl-C landed in ``import signal`` before the try)
        import signal

        # a Ctrl-C during an import that C code turns into another error (numpy's import of
        # datetime: "PyCapsule_Import could not import module") is still an interrupt
        signal.signal(signal.SIGINT, _recording)
        from ..guards import keep_freed_memory
        from .app import app

        if swallowed:
            raise KeyboardInterrupt
        # the command's own process (not a test's CliRunner): its malloc settings
        if next((a for a in sys.argv[1:] if not a.startswith("-")), None) == "stability":
            keep_freed_memory()
        app()
    except KeyboardInterrupt:  # outside a command (start-up, option parsing)
        _interrupted("critfric: interrupted")
    except Exception as exc:
        if _from_interrupt(exc) or _SIGINTS:  # e.g. Python 3.11 wraps one raised in a class's
            _interrupted("critfric: interrupted")  # __set_name__ (import platform) in a RuntimeError
        raise
    except SystemExit as exc:
        from .failures import said_interrupted

        if exc.code == 130:  # typer's own silent Ctrl-C exit, or a command's
            _interrupted(None if said_interrupted() else "critfric: interrupted")
        if exc.code == 143 and said_interrupted():  # a command stopped by SIGTERM
            _interrupted(None, 143)
        _quiet()
        raise
    finally:
        sys.unraisablehook = previous
    _quiet()


_SIGINTS: list[int] = []  # the Ctrl-Cs received since start-up


def _recording(signum, frame) -> None:
    """Python's own SIGINT handler (a KeyboardInterrupt), which also keeps a note of it."""
    _SIGINTS.append(signum)
    raise KeyboardInterrupt


def _quiet() -> None:
    """Ctrl-C and SIGTERM ignored from here on: the work is done."""
    import signal

    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.signal(signal.SIGTERM, signal.SIG_IGN)


def _from_interrupt(exc: BaseException) -> bool:
    """Whether a KeyboardInterrupt is in the cause or context chain of ``exc``."""
    seen = set()
    while exc is not None and id(exc) not in seen:
        if isinstance(exc, KeyboardInterrupt):
            return True
        seen.add(id(exc))
        exc = exc.__cause__ or exc.__context__
    return False


def _interrupted(line: str | None, code: int = 130) -> None:
    """Say it (unless a command did), then leave at once: a second Ctrl-C (or SIGTERM)
    during the interpreter's shutdown must not turn into a traceback or a death by signal."""
    import signal

    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.signal(signal.SIGTERM, signal.SIG_IGN)
    if line:
        sys.stderr.write(line + "\n")
    sys.stderr.flush()
    sys.stdout.flush()
    os._exit(code)


def __getattr__(name: str):
    if name == "app":
        from .app import app

        return app
    raise AttributeError(name)
