"""The command line: thin typer commands over the library's plain functions."""

import sys


def main() -> None:
    """The ``critfric`` command. Ctrl-C at any moment, start-up included, exits 130 with one
    line and no traceback."""
    try:
        from .app import app

        app()
    except KeyboardInterrupt:  # outside a command (start-up, option parsing)
        sys.stderr.write("critfric: interrupted\n")
        sys.exit(130)


def __getattr__(name: str):
    if name == "app":
        from .app import app

        return app
    raise AttributeError(name)
