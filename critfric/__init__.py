"""critfric: critical friction coefficients of Coulomb frictional contact (Hassani, Hild,
Ionescu, Sakki 2003), from a TOML case to an HDF5 result.

The pipeline, one subpackage a stage (imports only run downwards)::

    case -> meshing -> fem -> solvers -> solve -> multiplicity -> files -> sweep -> plots -> cli
"""

from ._version import __version__
from .case import Case, load_case, loads_case, shipped_cases
from .errors import CaseError, CritfricError, SolverError
from .files import read_summary, write_result
from .multiplicity import verify
from .solve import Prepared, Result, prepare, solve_case, solve_prepared
from .solvers import coulomb

__all__ = [
    "Case", "CaseError", "CritfricError", "Prepared", "Result", "SolverError", "__version__",
    "coulomb", "load_case", "loads_case", "prepare", "read_summary", "shipped_cases",
    "solve_case", "solve_prepared", "verify", "write_result",
]
