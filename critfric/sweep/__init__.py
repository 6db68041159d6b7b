"""Sweeps over nu, mesh size, element and (3D bodies) slip angle: the grid, the runner, local
and Dask workers, the h -> 0 limits and the minimum over slip directions."""

from .grid import Grid, Point
from .runner import Sweep, make_grid, run_sweep

__all__ = ["Grid", "Point", "Sweep", "make_grid", "run_sweep"]
