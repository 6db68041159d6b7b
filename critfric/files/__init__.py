"""Files: solve results and sweep files in HDF5, ParaView export, atomic writes and locks."""

from .results import read_summary, write_result

__all__ = ["read_summary", "write_result"]
