"""Figures of solve and sweep files (the paper's figures) and of static solutions."""

from .figures import figures, plot_file, solve_figures, sweep_figures

__all__ = ["figures", "plot_file", "solve_figures", "sweep_figures"]
