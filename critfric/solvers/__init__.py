"""Solvers: sparse factorizations and Schur complements, orderings, the eigen stage (3.2) and
the semi-smooth Newton solver of the static Coulomb problem."""

from .backends import available_backends, factorize, resolve_backend, schur
from .eigen import ContactState, Spectrum
from .from_case import contact_state

__all__ = ["ContactState", "Spectrum", "available_backends", "contact_state", "factorize",
           "resolve_backend", "schur"]
