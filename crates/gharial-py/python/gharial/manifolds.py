"""State spaces (ALIGATOR's ``aligator.manifolds``): ``x ⊕ v``, ``x1 ⊖ x0`` and products."""

from ._gharial import (  # noqa: F401
    SE2,
    SE3,
    SO2,
    SO3,
    CartesianProduct,
    Manifold,
    TangentBundle,
    VectorSpace,
)

__all__ = ["Manifold", "VectorSpace", "SO2", "SO3", "SE2", "SE3", "CartesianProduct", "TangentBundle"]
