"""critfric: critical friction coefficients of Coulomb frictional contact (Hassani, Hild,
Ionescu, Sakki 2003), from a TOML case to an HDF5 result.

The pipeline, one subpackage a stage (imports only run downwards)::

    case -> meshing -> fem -> solvers -> solve -> multiplicity -> files -> sweep -> plots -> cli

The names below, ``__version__`` included, are imported on first use, so that ``import
critfric`` (and the start of the command line, where a Ctrl-C must find critfric's handler)
stays light.
"""

from importlib import import_module

_API = {
    "__version__": "_version",
    "Case": "case", "load_case": "case", "loads_case": "case", "shipped_cases": "case",
    "CaseError": "errors", "CritfricError": "errors", "SolverError": "errors",
    "WriteError": "errors", "read_summary": "files", "write_result": "files",
    "Prepared": "solve", "Result": "solve", "prepare": "solve", "solve_case": "solve",
    "solve_prepared": "solve", "verify": "multiplicity.verify", "coulomb": "solvers.coulomb",
}

__all__ = ["Case", "CaseError", "CritfricError", "Prepared", "Result", "SolverError",
           "WriteError", "__version__", "coulomb", "load_case", "loads_case", "prepare",
           "read_summary", "shipped_cases", "solve_case", "solve_prepared", "verify",
           "write_result"]


def __getattr__(name: str):
    if name not in _API:
        raise AttributeError(f"module 'critfric' has no attribute {name!r}")
    module = import_module(f".{_API[name]}", __name__)
    value = module if module.__name__.endswith("." + name) else getattr(module, name)
    globals()[name] = value
    return value


def __dir__():
    return __all__
