#!/usr/bin/env python3
"""The `quadrotor` and `pendulum` families of `gharial bench profile` (stagewise-SQP
paper, Fig. 1b and 1c) rebuilt with crocoddyl and solved by mim_solvers' SQP and
crocoddyl's FDDP.

Question it answers: do mim_solvers' SQP and crocoddyl's FDDP, the paper's own software,
solve gharial's instances as Fig. 1 of Jordana et al. (2023) shows (SQP solving at least
as many instances as FDDP at every iteration budget), or do they behave like gharial's
solvers on the same instances?

The instances (--family, --count, --seed): the initial states of
crates/gharial-problems/src/profiles.rs, regenerated here from gharial's SplitMix64
stream bit for bit (`cargo run -p gharial-problems --example profile_instances --
FAMILY COUNT --x0` prints gharial's; --gharial checks the initial costs, which depend on
them).

quadrotor  the Hector quadrotor of example-robot-data (free-flyer base, m = 1.477 kg,
           I = diag(0.01152, 0.01152, 0.0218)), crocoddyl's `quadrotor_fwddyn.py`
           thrusters (arm 0.1525 m, cm / cf = 1e-6 / 6.6e-5), dt = 0.03, N = 33, the
           example's costs (running dt [1e-6 |x|^2_W / 2 + 1e-6 |u|^2 / 2
           + 1e-2 |log6(M*^-1 M)|^2 / 2] with W = diag(0.1 x3, 1000 x3, 1000 x6), terminal
           3 |log6(M*^-1 M)|^2 / 2, M* = (1, 0, 1), identity attitude); position U(-1, 1)^3,
           attitude uniform on SO(3) (Shoemake), at rest. Two discretisations (--dynamics):
             explicit  gharial's family exactly: x+ = x (+) dt (v, a(x, u)) on SE(3) x R^6,
                       a crocoddyl action model written here (crocoddyl has no explicit
                       Euler on manifolds);
             semi      the paper's own model: crocoddyl's IntegratedActionModelEuler
                       (semi-implicit: q+ = q (+) dt (v + dt a), v+ = v + dt a).
           Two guesses (--guess): `hover` (u = m g / 4, gharial's family) or `quasistatic`
           (crocoddyl's `quasiStatic` controls at x0, the paper's rollout_benchmark.py).
pendulum   the double pendulum of example-robot-data (gharial's copy of the URDF is the
           same file), first joint actuated (crocoddyl's ActuationModelDoublePendulum,
           actLink = 1), crocoddyl's IntegratedActionModelEuler (semi-implicit, as
           gharial's family), dt = 0.01, N = 100, the paper's costs (running
           1e-4 u^2 / 2 + 1e-5 |r(x)|^2_W / 2, terminal 100 |r(x)|^2_W / 2,
           r = (sin q1, sin q2, 1 - cos q1, 1 - cos q2, v1, v2), W = diag(1 x4, 0.1 x2));
           q0 = (U(-pi, pi), 0) at rest, guess x_t = x0 and the quasi-static torque.
           Two cost Hessians (--hessian):
             gn     gharial's family exactly: the Gauss-Newton Hessian r_x^T W r_x;
             exact  the paper's own model: crocoddyl's CostModelDoublePendulum, whose
                    Hessian is the exact one (w cos q_i on the angles: indefinite when
                    |q_i| > pi / 2); SQP then runs without the `reg0` setting (mim_solvers'
                    regularisation cannot grow from 0 when Q_uu is indefinite).

Per instance and solver it prints the iterations to the profile's test
max(|gaps|_inf, |Q_u|_inf) <= tol (`gharial bench profile`'s default criterion, read from
the solvers' fs and Qu at the start of each iteration: crocoddyl's and mim_solvers'
callbacks), and for SQP also to mim_solvers' own KKT test (`KKT` <= tol, the paper's (20)),
as `profile/own`. SQP runs with mim_solvers' defaults (filter size 1, regularisation from
1e-9), with the paper's filter (size = iteration limit), and with gharial's settings (that
filter, regularisation from 0); FDDP with crocoddyl's defaults, its own test switched off.

    ~/.cache/gharial-peers/croc/bin/python bench/peers/fig1.py [--family quadrotor|pendulum] \
        [--dynamics explicit|semi] [--guess hover|quasistatic] [--hessian gn|exact] \
        [--count 20] [--seed 1] [--budget 100] [--tol 1e-4] [--gharial FILE] [--trace I] \
        [--transport-check I]

--gharial FILE: the CSV of gharial's example (`cargo run --release -p gharial-problems
--example profile_instances -- FAMILY COUNT > FILE`, lines
`instance,initial_cost,fddp,sqp,sqp_own`), printed side by side with the relative
difference of the initial costs. --trace I: mim's SQP's first 12 iterations on instance I.
--transport-check I (quadrotor): from mim's first SQP iterate on instance I (gaps open on
SE(3)), the cost after mim's second step and after the full step of a dense KKT solve of
the LQ subproblem with crocoddyl's linearised dynamics and with gharial's (the gap
linearised in all its arguments, which adds the transport Ad(exp fs)). Run time: about
30 s for 20 quadrotor instances, 2 to 3 s (CPU) per pendulum instance.
"""

import argparse
import math
import os
import sys

import numpy as np

MASK64 = (1 << 64) - 1


class SplitMix64:
    """gharial's `lq::random::SplitMix64` (the families' random stream), bit for bit."""

    def __init__(self, seed):
        self.state = seed & MASK64

    def next_u64(self):
        self.state = (self.state + 0x9E3779B97F4A7C15) & MASK64
        z = self.state
        z = ((z ^ (z >> 30)) * 0xBF58476D1CE4E5B9) & MASK64
        z = ((z ^ (z >> 27)) * 0x94D049BB133111EB) & MASK64
        return z ^ (z >> 31)

    def uniform(self, a, b):
        """U(a, b) = a + (b - a) u, u = (next >> 11) 2^-53."""
        return a + (b - a) * ((self.next_u64() >> 11) * (1.0 / (1 << 53)))


def robots_dir():
    robots = os.environ.get("EXAMPLE_ROBOT_DATA_ROBOTS")
    if robots is None:
        import sysconfig
        robots = os.path.join(sysconfig.get_paths()["purelib"], "cmeel.prefix", "share",
                              "example-robot-data", "robots")
    return robots


# --- quadrotor --------------------------------------------------------------------------

QUAD_DT = 0.03
QUAD_N = 33
TARGET = np.array([1.0, 0.0, 1.0])


def quadrotor_x0s(seed, count):
    """`profiles::family("quadrotor", seed, count)`'s initial states: position U(-1, 1)^3,
    a unit quaternion (x, y, z, w) uniform on SO(3) (Shoemake), twist 0."""
    rng, tau = SplitMix64(seed), 2.0 * math.pi
    out = []
    for _ in range(count):
        p = [rng.uniform(-1.0, 1.0) for _ in range(3)]
        u1, u2, u3 = (rng.uniform(0.0, 1.0) for _ in range(3))
        a, b = math.sqrt(1.0 - u1), math.sqrt(u1)
        quat = [a * math.sin(tau * u2), a * math.cos(tau * u2),
                b * math.sin(tau * u3), b * math.cos(tau * u3)]
        out.append(p + quat + [0.0] * 6)
    return out


def hector():
    import pinocchio as pin

    urdf = os.path.join(robots_dir(), "hector_description", "robots", "quadrotor_base.urdf")
    return pin.buildModelFromUrdf(urdf, pin.JointModelFreeFlyer())


def thrusters(state):
    """crocoddyl's quadrotor_fwddyn.py rotors; checks the map against gharial's
    `QuadrotorOde` (f = (0, 0, sum u), tau = (d (u1 - u3), d (u2 - u0), k (-u0 + u1 - u2 + u3)))."""
    import crocoddyl
    import pinocchio as pin

    d, cf, cm = 0.1525, 6.6e-5, 1e-6
    ccw, cw = crocoddyl.ThrusterType.CCW, crocoddyl.ThrusterType.CW
    ps = [crocoddyl.Thruster(pin.SE3(np.eye(3), np.array(p)), cm / cf, kind)
          for p, kind in [([d, 0, 0], ccw), ([0, d, 0], cw), ([-d, 0, 0], ccw), ([0, -d, 0], cw)]]
    act = crocoddyl.ActuationModelFloatingBaseThrusters(state, ps)
    k = cm / cf
    expected = np.array([[0, 0, 0, 0], [0, 0, 0, 0], [1, 1, 1, 1],
                         [0, d, 0, -d], [-d, 0, d, 0], [-k, k, -k, k]])
    data = act.createData()
    x = state.zero()
    for j in range(4):
        u = np.zeros(4)
        u[j] = 1.0
        act.calc(data, x, u)
        assert np.allclose(data.tau, expected[:, j], rtol=0, atol=1e-15), (j, data.tau)
    return act


def quadrotor_costs(state, nu, model, terminal):
    import crocoddyl
    import pinocchio as pin

    pose = crocoddyl.CostModelResidual(state, crocoddyl.ResidualModelFramePlacement(
        state, model.getFrameId("base_link"), pin.SE3(np.eye(3), TARGET), nu))
    c = crocoddyl.CostModelSum(state, nu)
    if terminal:
        c.addCost("goalPose", pose, 3.0)
        return c
    w = np.array([0.1] * 3 + [1000.0] * 3 + [1000.0] * model.nv)
    xreg = crocoddyl.CostModelResidual(state, crocoddyl.ActivationModelWeightedQuad(w),
                                       crocoddyl.ResidualModelState(state, state.zero(), nu))
    ureg = crocoddyl.CostModelResidual(state, crocoddyl.ResidualModelControl(state, nu))
    c.addCost("xReg", xreg, 1e-6)
    c.addCost("uReg", ureg, 1e-6)
    c.addCost("trackPose", pose, 1e-2)
    return c


def explicit_euler_classes():
    import crocoddyl

    class ExplicitEulerData(crocoddyl.ActionDataAbstract):
        def __init__(self, model):
            crocoddyl.ActionDataAbstract.__init__(self, model)
            self.ddata = model.dam.createData()
            self.w = np.zeros(model.state.ndx)

    class ExplicitEuler(crocoddyl.ActionModelAbstract):
        """x+ = x (+) dt (v, a(x, u)); cost dt l(x, u) (terminal: l(x)). Every calcDiff
        re-evaluates its point first (as gharial's derivatives do)."""

        def __init__(self, dam, dt):
            crocoddyl.ActionModelAbstract.__init__(self, dam.state, dam.nu, dam.nr)
            self.dam, self.dt = dam, dt

        def createData(self):
            return ExplicitEulerData(self)

        def calc(self, data, x, u=None):
            if u is None:
                self.dam.calc(data.ddata, x)
                data.cost = data.ddata.cost
                data.xnext[:] = x
                return
            self.dam.calc(data.ddata, x, u)
            nv = self.state.nv
            data.w[:] = self.dt * np.concatenate([x[-nv:], data.ddata.xout])
            data.xnext[:] = self.state.integrate(x, data.w)
            data.cost = self.dt * data.ddata.cost

        def calcDiff(self, data, x, u=None):
            self.calc(data, x, u)
            dd = data.ddata
            if u is None:
                self.dam.calcDiff(dd, x)
                data.Lx[:] = dd.Lx
                data.Lxx[:, :] = dd.Lxx
                return
            self.dam.calcDiff(dd, x, u)
            nv, ndx = self.state.nv, self.state.ndx
            jx, jw = self.state.Jintegrate(x, data.w)
            dw_dx = np.zeros((ndx, ndx))
            dw_dx[:nv, nv:] = np.eye(nv)
            dw_dx[nv:, :] = dd.Fx
            dw_du = np.zeros((ndx, self.nu))
            dw_du[nv:, :] = dd.Fu
            data.Fx[:, :] = jx + self.dt * jw @ dw_dx
            data.Fu[:, :] = self.dt * jw @ dw_du
            data.Lx[:] = self.dt * dd.Lx
            data.Lu[:] = self.dt * dd.Lu
            data.Lxx[:, :] = self.dt * dd.Lxx
            data.Lxu[:, :] = self.dt * dd.Lxu
            data.Luu[:, :] = self.dt * dd.Luu

    return ExplicitEuler


def quadrotor_build(x0, args):
    """(problem, xs0, us0) of one instance; `args.dynamics`: see the module's doc;
    `args.guess`: hover thrusts (gharial's family) or crocoddyl's `quasiStatic` controls
    at x0 (the paper's script)."""
    import crocoddyl

    model = hector()
    state = crocoddyl.StateMultibody(model)
    act = thrusters(state)
    nu = act.nu

    def dam(terminal):
        return crocoddyl.DifferentialActionModelFreeFwdDynamics(
            state, act, quadrotor_costs(state, nu, model, terminal))

    if args.dynamics == "explicit":
        euler = explicit_euler_classes()
        run, ter = euler(dam(False), QUAD_DT), euler(dam(True), QUAD_DT)
    else:
        run = crocoddyl.IntegratedActionModelEuler(dam(False), QUAD_DT)
        ter = crocoddyl.IntegratedActionModelEuler(dam(True), QUAD_DT)
    x0 = np.array(x0)
    problem = crocoddyl.ShootingProblem(x0, [run] * QUAD_N, ter)
    hover = model.inertias[1].mass * 9.81 / 4.0
    xs0 = [x0.copy() for _ in range(QUAD_N + 1)]
    if args.guess == "hover":
        us0 = [np.full(nu, hover) for _ in range(QUAD_N)]
    else:
        us0 = [np.array(u) for u in problem.quasiStatic(xs0[:QUAD_N])]
    return problem, xs0, us0


# --- pendulum ---------------------------------------------------------------------------

PENDULUM_DT = 0.01
PENDULUM_N = 100


def pendulum_x0s(seed, count):
    """`profiles::family("pendulum", seed, count)`'s initial states: q0 = (U(-pi, pi), 0),
    at rest."""
    rng = SplitMix64(seed)
    return [[rng.uniform(-math.pi, math.pi), 0.0, 0.0, 0.0] for _ in range(count)]


def pendulum_goal(state, nu, hessian):
    """crocoddyl's CostModelDoublePendulum, 1/2 |r(x)|^2_W; `hessian == "gn"`: its exact
    Hessian replaced by the Gauss-Newton one r_x^T W r_x (gharial's
    QuadraticResidualCost)."""
    import crocoddyl
    from crocoddyl.utils.pendulum import CostModelDoublePendulum

    class GaussNewton(CostModelDoublePendulum):
        def calcDiff(self, data, x, u=None):
            CostModelDoublePendulum.calcDiff(self, data, x, u)
            rx = data.residual.Rx
            data.Lxx[:, :] = rx.T @ data.activation.Arr @ rx

    kind = GaussNewton if hessian == "gn" else CostModelDoublePendulum
    w = np.array([1.0] * 4 + [0.1] * 2)
    return kind(state, crocoddyl.ActivationModelWeightedQuad(w), nu)


def pendulum_build(x0, args):
    """(problem, xs0, us0) of one instance, as the paper's rollout_benchmark.py builds it
    (crocoddyl's double-pendulum example), with the cost Hessian `args.hessian`."""
    import crocoddyl
    import pinocchio as pin
    from crocoddyl.utils.pendulum import ActuationModelDoublePendulum

    urdf = os.path.join(robots_dir(), "double_pendulum_description", "urdf",
                        "double_pendulum.urdf")
    state = crocoddyl.StateMultibody(pin.buildModelFromUrdf(urdf))
    act = ActuationModelDoublePendulum(state, actLink=1)
    nu, dt = act.nu, PENDULUM_DT
    goal = pendulum_goal(state, nu, args.hessian)
    ureg = crocoddyl.CostModelResidual(state, crocoddyl.ResidualModelControl(state, nu))

    def euler(terms):
        c = crocoddyl.CostModelSum(state, nu)
        for name, cost, weight in terms:
            c.addCost(name, cost, weight)
        dam = crocoddyl.DifferentialActionModelFreeFwdDynamics(state, act, c)
        return crocoddyl.IntegratedActionModelEuler(dam, dt)

    # The running weights are divided by dt: crocoddyl's Euler multiplies the cost by dt.
    run = euler([("uReg", ureg, 1e-4 / dt), ("xGoal", goal, 1e-5 / dt)])
    ter = euler([("xGoal", goal, 100.0)])
    x0 = np.array(x0)
    problem = crocoddyl.ShootingProblem(x0, [run] * PENDULUM_N, ter)
    xs0 = [x0.copy() for _ in range(PENDULUM_N + 1)]
    us0 = [np.array(u) for u in problem.quasiStatic(xs0[:PENDULUM_N])]
    return problem, xs0, us0


FAMILIES = {"quadrotor": (quadrotor_x0s, quadrotor_build),
            "pendulum": (pendulum_x0s, pendulum_build)}


# --- solvers ----------------------------------------------------------------------------


def residual(solver):
    """max(|gaps|_inf, |Q_u|_inf) of the point at which the solver's last backward pass ran."""
    gaps = max(np.max(np.abs(f)) for f in solver.fs)
    qu = max(np.max(np.abs(q)) for q in solver.Qu)
    return max(gaps, qu)


def sqp_rows(problem, xs0, us0, filter_size, reg_min, iters):
    """mim_solvers' SQP with its own test off: per iteration (cost, gap 1-norm, KKT,
    max(|gaps|, |Q_u|)) at the iteration's start, from its callback (called after the
    iteration's backward pass and KKT evaluation, before the step)."""
    import mim_solvers

    class Rows(mim_solvers.CallbackAbstract):
        def __init__(self):
            mim_solvers.CallbackAbstract.__init__(self)
            self.rows = []

        def __call__(self, solver, kind=None):
            self.rows.append((solver.cost, solver.merit - solver.cost, solver.KKT,
                              residual(solver)))

    s = mim_solvers.SolverSQP(problem)
    s.termination_tolerance = 0.0
    s.filter_size = filter_size
    s.mu_dynamic = 1.0
    if reg_min is not None:
        s.reg_min = reg_min
    rows = Rows()
    s.setCallbacks([rows])
    s.solve(xs0, us0, iters, False)
    return rows.rows


def sqp(problem, xs0, us0, filter_size, reg_min, tol, budget):
    """mim_solvers' SQP: (iterations to its own KKT test, iterations to the profile's test)."""
    rows = sqp_rows(problem, xs0, us0, filter_size, reg_min, budget + 1)
    first = lambda col: next((k for k, r in enumerate(rows) if r[col] <= tol), None)  # noqa: E731
    return first(2), first(3)


def fddp(problem, xs0, us0, tol, budget):
    """crocoddyl's FDDP: iterations to the profile's test (its own test off)."""
    import crocoddyl

    class FirstKkt(crocoddyl.CallbackAbstract):
        def __init__(self):
            crocoddyl.CallbackAbstract.__init__(self)
            self.k = 0
            self.first = None

        def __call__(self, solver):
            if self.first is None and residual(solver) <= tol:
                self.first = self.k
            self.k += 1

    s = crocoddyl.SolverFDDP(problem)
    s.th_stop = 1e-300
    cb = FirstKkt()
    s.setCallbacks([cb])
    s.solve(xs0, us0, budget + 1, False)
    return cb.first


def lq_step_cost(problem, xs, us, transport):
    """Cost after the full Gauss-Newton step of the LQ subproblem at (xs, us), solved
    densely (no regularisation). `transport=False`: crocoddyl's and mim_solvers' linearised
    dynamics dx+ = Fx dx + Fu du + fs; `True`: the linearisation of the gap
    fs = log(x+^-1 f(x, u)) in all its arguments, as gharial builds it, which is
    dx+ = fs + Ad(exp(fs)) (Fx dx + Fu du) (on SE(3); identity on the velocities)."""
    import pinocchio as pin

    problem.calc(xs, us)
    problem.calcDiff(xs, us)
    ds, ms = list(problem.runningDatas), list(problem.runningModels)
    state = ms[0].state
    nx, nu, N = state.ndx, ms[0].nu, problem.T
    nz = (N + 1) * nx + N * nu
    xi = lambda t: slice(t * nx, (t + 1) * nx)  # noqa: E731
    ui = lambda t: slice((N + 1) * nx + t * nu, (N + 1) * nx + (t + 1) * nu)  # noqa: E731
    h, g = np.zeros((nz, nz)), np.zeros(nz)
    c, d = np.zeros(((N + 1) * nx, nz)), np.zeros((N + 1) * nx)
    c[xi(0), xi(0)] = np.eye(nx)
    for t, dt_ in enumerate(ds):
        h[xi(t), xi(t)] += dt_.Lxx
        h[xi(t), ui(t)] += dt_.Lxu
        h[ui(t), xi(t)] += dt_.Lxu.T
        h[ui(t), ui(t)] += dt_.Luu
        g[xi(t)] += dt_.Lx
        g[ui(t)] += dt_.Lu
        fs = state.diff(xs[t + 1], dt_.xnext)
        ad = np.eye(nx)
        if transport:
            ad[:6, :6] = pin.exp6(fs[:6]).action
        row = xi(t + 1)
        c[row, xi(t + 1)] = np.eye(nx)
        c[row, xi(t)] = -ad @ dt_.Fx
        c[row, ui(t)] = -ad @ dt_.Fu
        d[row] = fs
    h[xi(N), xi(N)] += problem.terminalData.Lxx
    g[xi(N)] += problem.terminalData.Lx
    kkt = np.block([[h, c.T], [c, np.zeros((c.shape[0], c.shape[0]))]])
    z = np.linalg.solve(kkt, np.concatenate([-g, d]))[:nz]
    xs1 = [state.integrate(xs[t], z[xi(t)]) for t in range(N + 1)]
    us1 = [us[t] + z[ui(t)] for t in range(N)]
    return problem.calc(xs1, us1)


def transport_check(problem, xs0, us0):
    """mim_solvers' second step (regularisation 0) against the dense LQ steps of both
    linearisations from the same point (after mim's first step, where gaps are open)."""
    import mim_solvers

    s = mim_solvers.SolverSQP(problem)
    s.termination_tolerance = 0.0
    s.reg_min = 0.0
    s.solve(xs0, us0, 1, False)
    xs, us = [np.array(x) for x in s.xs], [np.array(u) for u in s.us]
    rows = sqp_rows(problem, xs0, us0, 1, 0.0, 3)
    print("after mim's first step: cost %.15e; mim's second step (alpha = 1) reaches %.15e" % (
        rows[1][0], rows[2][0]))
    print("  dense LQ step, dx+ = Fx dx + Fu du + fs (crocoddyl):      %.15e" % lq_step_cost(
        problem, xs, us, False))
    print("  dense LQ step, dx+ = fs + Ad(exp fs)(Fx dx + Fu du):       %.15e" % lq_step_cost(
        problem, xs, us, True))


def read_gharial(path):
    out = {}
    with open(path) as f:
        for line in f:
            parts = line.strip().split(",")
            if len(parts) == 5 and parts[0].isdigit():
                out[int(parts[0])] = (float(parts[1]), *parts[2:])
    return out


def parse():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--family", choices=sorted(FAMILIES), default="quadrotor")
    ap.add_argument("--dynamics", choices=["explicit", "semi"], default="explicit",
                    help="quadrotor: gharial's explicit Euler or crocoddyl's semi-implicit one")
    ap.add_argument("--guess", choices=["hover", "quasistatic"], default="hover",
                    help="quadrotor: hover thrusts or crocoddyl's quasiStatic controls")
    ap.add_argument("--hessian", choices=["gn", "exact"], default="gn",
                    help="pendulum: the goal cost's Gauss-Newton Hessian (gharial's) or "
                         "crocoddyl's exact one (the paper's)")
    ap.add_argument("--count", type=int, default=20)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--budget", type=int, default=100)
    ap.add_argument("--tol", type=float, default=1e-4)
    ap.add_argument("--gharial", default=None)
    ap.add_argument("--trace", type=int, default=None,
                    help="print mim SQP's first 12 iterations on this instance (reg_min 0 and 1e-9)")
    ap.add_argument("--transport-check", type=int, default=None,
                    help="quadrotor, on this instance: mim's second step against the dense LQ "
                         "steps of both gap linearisations, then exit")
    args = ap.parse_args()
    if args.transport_check is not None and args.family != "quadrotor":
        ap.error("--transport-check is for the quadrotor family")
    return args


def solve_instance(problem, xs0, us0, settings, args):
    """{solver: (iterations to the profile's test, SQP: to its own test)}, None if not
    within the budget."""
    got = {"fddp": (fddp(problem, xs0, us0, args.tol, args.budget), None)}
    for name, size, reg in settings:
        own, first = sqp(problem, xs0, us0, size, reg, args.tol, args.budget)
        got[name] = (first, own)
    return got


def main():
    args = parse()
    x0s, build = FAMILIES[args.family]
    instances = x0s(args.seed, max(args.count, (args.trace or 0) + 1,
                                   (args.transport_check or 0) + 1))
    if args.transport_check is not None:
        transport_check(*build(instances[args.transport_check], args))
        return 0
    ours = read_gharial(args.gharial) if args.gharial else {}
    big = args.budget + 1
    # SQP settings: mim_solvers' defaults (filter 1, reg_min 1e-9), the paper's filter
    # (size = iteration limit), and gharial's profile settings (that filter, and the
    # regularisation starting at 0 as gharial's does).
    settings = [("mim", 1, None), ("paper", big, None), ("reg0", big, 0.0)]
    if args.family == "pendulum" and args.hessian == "exact":
        # mim_solvers multiplies its regularisation on a failed backward pass: from 0 it
        # never grows, and an indefinite Q_uu (the exact Hessian's) retries forever.
        settings.pop()
    show = lambda v: "-" if v is None else str(v)  # noqa: E731
    model = ("dynamics=%s guess=%s" % (args.dynamics, args.guess) if args.family == "quadrotor"
             else "hessian=%s" % args.hessian)
    print("family=%s %s seed=%d tol=%g budget=%d; SQP columns: profile test / own KKT test"
          % (args.family, model, args.seed, args.tol, args.budget))
    print("  mim: mim_solvers' defaults (filter 1, reg_min 1e-9); paper: filter %d; "
          "reg0: filter %d, reg_min 0 (gharial's settings)" % (big, big))
    header = "inst  init_cost              fddp " + "".join("%11s" % ("sqp:" + n) for n, _, _ in settings)
    if ours:
        header += "  | gharial: fddp  sqp  sqp_own  init_cost_rel_diff"
    print(header)
    names = ["fddp"] + [n for n, _, _ in settings]
    names_ours = ["gharial_fddp", "gharial_sqp"] if ours else []
    budgets = {b: dict.fromkeys(names + names_ours, 0) for b in (10, 20, 50, args.budget)}
    for i, x0 in enumerate(instances[:args.count]):
        problem, xs0, us0 = build(x0, args)
        c0 = problem.calc(xs0, us0)
        got = solve_instance(problem, xs0, us0, settings, args)
        cells = ["%4s" % show(got["fddp"][0])] + [
            "%4s/%-4s" % (show(got[n][0]), show(got[n][1])) for n, _, _ in settings]
        line = "%4d  %.15e  %s" % (i, c0, "  ".join(cells))
        if i in ours:
            g = ours[i]
            line += "  |          %4s %4s %8s  %.1e" % (g[1], g[2], g[3], abs(g[0] - c0) / abs(c0))
            for k, v in zip(names_ours, g[1:3]):
                got[k] = (None if v == "-" else int(v), None)
        print(line, flush=True)
        for b, row in budgets.items():
            for n in row:
                row[n] += got[n][0] is not None and got[n][0] <= b
    for b, row in sorted(budgets.items()) if args.count else []:
        print("solved within %3d: " % b + "  ".join(
            "%s %.2f" % (k, v / args.count) for k, v in row.items()))
    if args.trace is not None:
        problem, xs0, us0 = build(instances[args.trace], args)
        for reg in (0.0, None):
            print("mim SQP on instance %d, reg_min %s: iter cost gap_l1 KKT max(gaps,|Qu|)" % (
                args.trace, "1e-9" if reg is None else reg))
            for k, r in enumerate(sqp_rows(problem, xs0, us0, 1, reg, 12)):
                print("  %3d %.15e %.4e %.4e %.4e" % (k, *r))
    return 0


if __name__ == "__main__":
    sys.exit(main())
