"""Solution multiplicity of the static problem: branches at a critical coefficient (Theorem
3.3) and the enumeration of every solution of small problems."""

from .enumeration import enumerate_solutions
from .problems import static_problem
from .verify import branch

__all__ = ["branch", "enumerate_solutions", "static_problem"]
