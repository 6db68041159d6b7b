"""critfric: critical friction coefficients of Coulomb frictional contact (Hassani, Hild,
Ionescu, Sakki 2003), from a TOML case to an HDF5 result."""

__version__ = "0.1.0"

from .case import Case, load_case, loads_case, shipped_cases  # noqa: E402
from .errors import CaseError, CritfricError, SolverError  # noqa: E402
from .solve import Result, prepare, solve_case, solve_prepared  # noqa: E402
from .results import read_summary, write_result  # noqa: E402
from . import coulomb, verify  # noqa: F401  (critfric.verify.branch, critfric.coulomb)

__all__ = [
    "Case", "CaseError", "CritfricError", "Result", "SolverError", "__version__", "load_case",
    "loads_case", "prepare", "read_summary", "shipped_cases", "solve_case", "solve_prepared",
    "write_result",
]
