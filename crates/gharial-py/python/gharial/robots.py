"""Robots (ALIGATOR's multibody classes and Pinocchio's algorithms): multibody models
from URDF, their dynamics and kinematics on numpy arrays, and the spaces, ODEs and
residuals that make robot trajectory-optimization problems.

Conventions are Pinocchio's: free-flyer quaternions are ``(x, y, z, w)``, spatial
vectors ``[linear, angular]``, q-derivatives are taken along ``integrate(q, dq)``::

    import numpy as np
    from gharial import robots
    from gharial.dynamics import IntegratorSemiImplEuler

    model = robots.load_builtin("ur5")            # or robots.load_urdf("arm.urdf")
    q = model.neutral()
    v = np.zeros(model.nv)
    tau = robots.rnea(model, q, v, v)             # gravity torques
    R, p = robots.frame_placement(model, q, "tool0")

    space = robots.MultibodyPhaseSpace(model)
    ode = robots.MultibodyFreeFwdDynamics(space)  # B = I (fixed base)
    step = IntegratorSemiImplEuler(ode, 0.01)
    reach = robots.FrameTranslationResidual(space, ode.nu, "tool0", [0.4, 0.2, 0.5])

Algorithms (module functions taking the model first): ``rnea``, ``aba``, ``crba``,
``generalized_gravity``, ``nonlinear_effects``, ``compute_rnea_derivatives``,
``compute_aba_derivatives``, ``frame_placement``, ``frame_jacobian``,
``center_of_mass``, ``jacobian_center_of_mass``, ``integrate``, ``difference``.
Wrong sizes or non-real arrays raise ``ValueError``; errors of the Rust core (unknown
frame, malformed URDF, a quaternion off the unit sphere) raise
:class:`gharial.GharialError` (a ``ValueError``).
"""

from ._gharial import (  # noqa: F401
    CenterOfMassTranslationResidual,
    ContactForceResidual,
    FlyHighResidual,
    FramePlacementResidual,
    FrameTranslationResidual,
    FrameVelocityResidual,
    FrictionConeResidual,
    MultibodyConfiguration,
    MultibodyConstraintFwdDynamics,
    MultibodyFreeFwdDynamics,
    MultibodyPhaseSpace,
    RobotModel,
    aba,
    builtin_robots,
    center_of_mass,
    compute_aba_derivatives,
    compute_rnea_derivatives,
    crba,
    difference,
    frame_jacobian,
    frame_placement,
    generalized_gravity,
    integrate,
    jacobian_center_of_mass,
    load_builtin,
    load_urdf,
    load_urdf_string,
    nonlinear_effects,
    rnea,
)

__all__ = [
    "RobotModel",
    "load_urdf",
    "load_urdf_string",
    "load_builtin",
    "builtin_robots",
    "rnea",
    "aba",
    "crba",
    "generalized_gravity",
    "nonlinear_effects",
    "compute_rnea_derivatives",
    "compute_aba_derivatives",
    "frame_placement",
    "frame_jacobian",
    "center_of_mass",
    "jacobian_center_of_mass",
    "integrate",
    "difference",
    "MultibodyConfiguration",
    "MultibodyPhaseSpace",
    "MultibodyFreeFwdDynamics",
    "MultibodyConstraintFwdDynamics",
    "FrameTranslationResidual",
    "FramePlacementResidual",
    "CenterOfMassTranslationResidual",
    "FrameVelocityResidual",
    "FlyHighResidual",
    "ContactForceResidual",
    "FrictionConeResidual",
]
