"""The command line: thin typer commands over the library's plain functions."""

from .app import app, main

__all__ = ["app", "main"]
