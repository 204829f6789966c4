"""The UR5 reaches a point with its tool in 1 s (the peer benchmark's problem), from its URDF."""
import numpy as np, gharial
from gharial import robots

model = robots.load_builtin("ur5")  # or robots.load_urdf("ur5_robot.urdf")
space, dt, q0 = robots.MultibodyPhaseSpace(model), 0.01, np.array([0, -1, 1, -0.5, -0.5, 0.0])
x0, step = np.concatenate([q0, np.zeros(6)]), gharial.dynamics.IntegratorSemiImplEuler(robots.MultibodyFreeFwdDynamics(space), dt)
def cost(nu, wq, wv, wu, wee, scale):
    c = gharial.CostStack(space, nu)
    c.addCost("state", gharial.QuadraticStateCost(space, nu, x0, [wq] * 6 + [wv] * 6), scale)
    if nu: c.addCost("control", gharial.QuadraticControlCost(space, np.zeros(nu), [wu] * nu), scale)
    c.addCost("ee", gharial.QuadraticResidualCost(space, robots.FrameTranslationResidual(space, nu, "tool0", [0.3, 0.5, 0.5]), [wee] * 3), scale)
    return c
problem = gharial.TrajOptProblem(x0, [gharial.StageModel(cost(6, 1e-2, 1e-1, 1e-4, 10.0, dt), step)] * 100, cost(0, 1e-2, 1.0, 0, 1000.0, 1.0))
us = [robots.generalized_gravity(model, q0)] * 100
solver = gharial.SolverProxDDP(tol=1e-6, mu_init=1e-5, rollout="linear", verbose=True)
solver.run(problem, problem.rollout(us), us)
print(solver.results, "\ntool at", robots.frame_placement(model, solver.results.xs[-1][:6], "tool0")[1])
