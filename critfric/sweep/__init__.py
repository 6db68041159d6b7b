"""Sweeps over nu, mesh size and element: the grid, the runner, local and Dask workers, and the
h -> 0 limits."""

from .grid import Grid, Point
from .runner import Sweep, make_grid, run_sweep

__all__ = ["Grid", "Point", "Sweep", "make_grid", "run_sweep"]
