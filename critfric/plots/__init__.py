"""Figures of solve and sweep files (the paper's figures) and of static solutions."""

from .figures import plot_file

__all__ = ["plot_file"]
