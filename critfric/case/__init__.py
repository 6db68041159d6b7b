"""Cases: the TOML schema, its value checks, command-line overrides and the shipped cases."""

from .schema import (
                     BACKENDS,
                     METHODS,
                     OVERRIDES,
                     SHAPES,
                     Case,
                     from_dict,
                     load_case,
                     loads_case,
                     shipped_cases,
)

__all__ = ["BACKENDS", "METHODS", "OVERRIDES", "SHAPES", "Case", "from_dict",
           "load_case", "loads_case", "shipped_cases"]
