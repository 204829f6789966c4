"""100 UR5 reaching problems with random targets, solved as Ray tasks.

Start a cluster first (`ray start --head`, or let this script start a local one), and
install the extra: pip install 'gharial[ray]'.
"""
import numpy as np

import gharial


def build(seed):
    """A UR5 reach with a random target in front of the robot."""
    rng = np.random.default_rng(seed)
    return reach(rng.uniform([0.2, -0.4, 0.3], [0.5, 0.6, 0.7]))


def reach(target):
    """A UR5 reach problem like the catalogue's with another tool target."""
    from gharial import robots

    model = robots.load_builtin("ur5")
    space, dt = robots.MultibodyPhaseSpace(model), 0.01
    q0 = np.array([0, -1, 1, -0.5, -0.5, 0.0])
    x0 = np.concatenate([q0, np.zeros(6)])
    step = gharial.dynamics.IntegratorSemiImplEuler(robots.MultibodyFreeFwdDynamics(space), dt)

    def cost(nu, wv, wee, scale):
        c = gharial.CostStack(space, nu)
        c.addCost("state", gharial.QuadraticStateCost(space, nu, x0, [1e-2] * 6 + [wv] * 6), scale)
        if nu:
            c.addCost("control", gharial.QuadraticControlCost(space, np.zeros(nu), [1e-4] * nu), scale)
        ee = robots.FrameTranslationResidual(space, nu, "tool0", target)
        c.addCost("ee", gharial.QuadraticResidualCost(space, ee, [wee] * 3), scale)
        return c

    problem = gharial.TrajOptProblem(x0, [gharial.StageModel(cost(6, 0.1, 10.0, dt), step)] * 100, cost(0, 1.0, 1000.0, 1.0))
    us = [robots.generalized_gravity(model, q0)] * 100
    return problem, problem.rollout(us), us


if __name__ == "__main__":
    import ray

    ray.init(ignore_reinit_error=True, include_dashboard=False)
    results = gharial.solve_batch(build, range(100), solver="proxddp", backend="ray", options={"mu_init": 1e-5, "rollout": "linear"})
    converged = sum(r["converged"] for r in results)
    iters = [r["iterations"] for r in results if r["converged"]]
    print(f"{converged}/100 converged, median {np.median(iters):.0f} iterations")
    ray.shutdown()
