"""Constraint sets (ALIGATOR's ``aligator.constraints``) for ``h(x, u) ∈ C``."""

from ._gharial import (  # noqa: F401
    BoxConstraint,
    ConstraintSet,
    EqualityConstraintSet,
    NegativeOrthantSet,
    SecondOrderCone,
)

__all__ = ["ConstraintSet", "EqualityConstraintSet", "NegativeOrthantSet", "BoxConstraint", "SecondOrderCone"]
