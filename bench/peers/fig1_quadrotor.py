#!/usr/bin/env python3
"""The quadrotor family of `gharial bench profile` (stagewise-SQP paper, Fig. 1b)
rebuilt with crocoddyl and solved by mim_solvers' SQP and crocoddyl's FDDP.

Question it answers: does mim_solvers' SQP, the paper's own software, solve gharial's
quadrotor instances (crates/gharial-problems/src/profiles.rs, `quadrotor`) in fewer
iterations than crocoddyl's FDDP, as Fig. 1b of Jordana et al. (2023) shows, or does it
behave like gharial's SQP (many more iterations than FDDP)?

The instances: the Hector quadrotor of example-robot-data (free-flyer base, m = 1.477 kg,
I = diag(0.01152, 0.01152, 0.0218)), crocoddyl's `quadrotor_fwddyn.py` thrusters
(arm 0.1525 m, cm / cf = 1e-6 / 6.6e-5), dt = 0.03, N = 33, the example's costs
(running dt [1e-6 |x|^2_W / 2 + 1e-6 |u|^2 / 2 + 1e-2 |log6(M*^-1 M)|^2 / 2] with
W = diag(0.1 x3, 1000 x3, 1000 x6), terminal 3 |log6(M*^-1 M)|^2 / 2, M* = (1, 0, 1),
identity attitude), warm start x_t = x0, u_t = m g / 4; the initial states X0 below are
gharial's (printed by `cargo run --release -p gharial-problems --example profile_instances
-- quadrotor 20 --x0`, seed 1).

Two discretisations (--dynamics):
  explicit  gharial's family exactly: x+ = x (+) dt (v, a(x, u)) on SE(3) x R^6, a crocoddyl
            action model written here (crocoddyl has no explicit Euler on manifolds);
            --gharial checks the initial costs against gharial's.
  semi      the paper's own model: crocoddyl's IntegratedActionModelEuler (semi-implicit:
            q+ = q (+) dt (v + dt a), v+ = v + dt a), as in crocoddyl's example.
Two guesses (--guess): `hover` (u = m g / 4, gharial's family) or `quasistatic`
(crocoddyl's `quasiStatic` controls at x0, the paper's rollout_benchmark.py).

Per instance and solver it prints the iterations to the profile's test
max(|gaps|_inf, |Q_u|_inf) <= tol (`gharial bench profile`'s default criterion, read from
the solvers' fs and Qu at the start of each iteration: crocoddyl's and mim_solvers'
callbacks), and for SQP also to mim_solvers' own KKT test (`KKT` <= tol, the paper's (20)),
as `profile/own`. SQP runs with mim_solvers' defaults (filter size 1, regularisation from
1e-9), with the paper's filter (size = iteration limit), and with gharial's settings (that
filter, regularisation from 0); FDDP with crocoddyl's defaults, its own test switched off.

    ~/.cache/gharial-peers/croc/bin/python bench/peers/fig1_quadrotor.py \
        [--dynamics explicit|semi] [--guess hover|quasistatic] [--count 20] \
        [--budget 100] [--tol 1e-4] [--gharial FILE] [--trace I] [--transport-check I]

--gharial FILE: the CSV of gharial's example (`cargo run --release -p gharial-problems
--example profile_instances > FILE`, lines `instance,initial_cost,fddp,sqp,sqp_own`),
printed side by side. --trace I: mim's SQP's first 12 iterations on instance I.
--transport-check I: from mim's first SQP iterate on instance I (gaps open on SE(3)), the
cost after mim's second step and after the full step of a dense KKT solve of the LQ
subproblem with crocoddyl's linearised dynamics and with gharial's (the gap linearised in
all its arguments, which adds the transport Ad(exp fs)). Run time: about 30 s.
"""

import argparse
import os
import sys

import numpy as np

DT = 0.03
N = 33
TARGET = np.array([1.0, 0.0, 1.0])

# gharial's `profiles::family("quadrotor", 1, 20)` initial states (p, quaternion xyzw, twist).
X0 = [
    [0.1331231503445618, 0.49156351452540226, 0.9420055071735924, 0.2557372263266478, -0.7001708748691142, -0.6644161850629069, 0.053947660581578086, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0],
    [0.754697373528346, 0.04613435970196278, -0.4289826312060667, 0.25713575111288706, -0.3740114969319871, -0.5479976919875361, -0.7026344250309966, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0],
    [-0.09012418505942077, 0.060157995003177867, -0.12806920035054992, -0.7223246819741863, -0.5578638406191421, -0.3747270768154572, 0.16313983891708825, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0],
    [0.3634099467611771, 0.7686491270795797, -0.8680796137088471, 0.02480809615655807, -0.95810745971505, 0.1993490198830807, 0.20414363148312004, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0],
    [-0.42617729035252183, -0.9041976343115175, 0.031039792822940893, 0.14521612665627237, 0.5149189001344635, -0.011954567653435588, 0.8447649916725263, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0],
    [0.19570434609117493, 0.17319028442039675, -0.20566148667052775, 0.7488497994815745, -0.015402861827094, -0.12315925786271718, -0.651013461355943, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0],
    [0.08734157884882077, 0.49647065764330955, 0.6360669967669679, -0.43933718463718013, 0.37203410138163373, -0.7895969602853107, -0.2123913979247607, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0],
    [-0.5272789302524608, 0.31247105846438195, 0.7378178842478063, 0.35779235416332517, -0.18070228081205683, 0.7709896918975078, 0.4948799975745356, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0],
    [0.7878780598425066, 0.8253803273581597, -0.39628744895212265, 0.8284932526454438, -0.42663097474189526, -0.13316721491942815, 0.33741878220151866, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0],
    [-0.21267568550618932, -0.8245383318729729, 0.21409946941058045, -0.23785614068393643, 0.8876637624517694, -0.2777367456556032, 0.27989248164526864, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0],
    [0.05291195975748608, -0.8632600037081652, 0.5047028667633311, -0.6708276444917979, -0.12618946178444262, 0.7179094108366234, -0.1366476086594674, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0],
    [-0.9251320712311051, -0.9559667663383808, 0.1369148851606381, 0.7974168758926158, 0.4940746508320087, -0.31030289393655125, 0.15404116158186637, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0],
    [0.9453760807576317, 0.3821727402666808, 0.13124735673194854, -0.5112090933837942, -0.5177609325932446, -0.5281415704230561, 0.43778460584282886, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0],
    [0.6115001750896452, -0.7819031117569648, 0.29916975003429136, 0.41190983719081686, -0.7807414702398084, -0.30590020953719754, 0.35664843260319473, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0],
    [0.37013944164453516, 0.881678599482939, 0.5011442006654203, 0.8378139104067281, 0.41390544130160756, -0.3550231970783563, -0.02662079499509819, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0],
    [0.5608319257710925, -0.22378403020240412, -0.8063952482950181, -0.12417640380066308, -0.1780155748437257, 0.5431173268936577, 0.8111191312502007, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0],
    [0.711918955088992, 0.68760895715068, -0.9997716352251791, -0.8282985167197044, -0.07236853795189592, -0.2943268361968251, -0.47122826253208744, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0],
    [0.3300139008750069, -0.03307551030563061, -0.0761271846535061, -0.07599504795379176, -0.06263930966304772, 0.18227592456776623, 0.9783028962925561, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0],
    [0.6956104141174644, 0.8195193011668729, -0.22768883562769937, -0.6968701080447779, -0.6042782001304672, -0.22203639845306825, -0.31610084960773677, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0],
    [-0.630084237644762, -0.7996895832394115, 0.9769629914649898, 0.12588639365102505, -0.760731869343384, -0.24399439143071752, -0.5881380584600977, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0],
]


def hector():
    import pinocchio as pin

    robots = os.environ.get("EXAMPLE_ROBOT_DATA_ROBOTS")
    if robots is None:
        import sysconfig
        robots = os.path.join(sysconfig.get_paths()["purelib"], "cmeel.prefix", "share",
                              "example-robot-data", "robots")
    urdf = os.path.join(robots, "hector_description", "robots", "quadrotor_base.urdf")
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
    x = np.concatenate([X0[0][:7], np.zeros(6)])
    for j in range(4):
        u = np.zeros(4)
        u[j] = 1.0
        act.calc(data, x, u)
        assert np.allclose(data.tau, expected[:, j], rtol=0, atol=1e-15), (j, data.tau)
    return act


def costs(state, nu, model, terminal):
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


def build(x0, dynamics, guess="hover"):
    """(problem, xs0, us0) of one instance; `guess`: hover thrusts (gharial's family) or
    crocoddyl's `quasiStatic` controls at x0 (the paper's script)."""
    import crocoddyl

    model = hector()
    state = crocoddyl.StateMultibody(model)
    act = thrusters(state)
    nu = act.nu

    def dam(terminal):
        return crocoddyl.DifferentialActionModelFreeFwdDynamics(
            state, act, costs(state, nu, model, terminal))

    if dynamics == "explicit":
        euler = explicit_euler_classes()
        run, ter = euler(dam(False), DT), euler(dam(True), DT)
    else:
        run = crocoddyl.IntegratedActionModelEuler(dam(False), DT)
        ter = crocoddyl.IntegratedActionModelEuler(dam(True), DT)
    x0 = np.array(x0)
    problem = crocoddyl.ShootingProblem(x0, [run] * N, ter)
    hover = model.inertias[1].mass * 9.81 / 4.0
    xs0 = [x0.copy() for _ in range(N + 1)]
    if guess == "hover":
        us0 = [np.full(nu, hover) for _ in range(N)]
    else:
        us0 = [np.array(u) for u in problem.quasiStatic(xs0[:N])]
    return problem, xs0, us0


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
    nx, nu = state.ndx, ms[0].nu
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


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--dynamics", choices=["explicit", "semi"], default="explicit")
    ap.add_argument("--guess", choices=["hover", "quasistatic"], default="hover")
    ap.add_argument("--count", type=int, default=len(X0))
    ap.add_argument("--budget", type=int, default=100)
    ap.add_argument("--tol", type=float, default=1e-4)
    ap.add_argument("--gharial", default=None)
    ap.add_argument("--trace", type=int, default=None,
                    help="print mim SQP's first 12 iterations on this instance (reg_min 0 and 1e-9)")
    ap.add_argument("--transport-check", type=int, default=None,
                    help="on this instance: mim's second step against the dense LQ steps of "
                         "both gap linearisations, then exit")
    args = ap.parse_args()
    if args.transport_check is not None:
        transport_check(*build(X0[args.transport_check], args.dynamics, args.guess))
        return 0
    ours = read_gharial(args.gharial) if args.gharial else {}
    big = args.budget + 1
    # SQP settings: mim_solvers' defaults (filter 1, reg_min 1e-9), the paper's filter
    # (size = iteration limit), and gharial's profile settings (that filter, and the
    # regularisation starting at 0 as gharial's does).
    settings = [("mim", 1, None), ("paper", big, None), ("reg0", big, 0.0)]
    show = lambda v: "-" if v is None else str(v)  # noqa: E731
    print("dynamics=%s guess=%s N=%d dt=%g tol=%g budget=%d; SQP columns: profile test / own KKT test"
          % (args.dynamics, args.guess, N, DT, args.tol, args.budget))
    print("  mim: mim_solvers' defaults (filter 1, reg_min 1e-9); paper: filter %d; "
          "reg0: filter %d, reg_min 0 (gharial's settings)" % (big, big))
    header = "inst  init_cost              fddp    sqp:mim  sqp:paper   sqp:reg0"
    if ours:
        header += "  | gharial: fddp  sqp  sqp_own  init_cost_rel_diff"
    print(header)
    names = ["fddp"] + [n for n, _, _ in settings]
    budgets = {b: dict.fromkeys(names, 0) for b in (10, 20, 50, args.budget)}
    for i, x0 in enumerate(X0[:args.count]):
        problem, xs0, us0 = build(x0, args.dynamics, args.guess)
        c0 = problem.calc(xs0, us0)
        got = {"fddp": (fddp(problem, xs0, us0, args.tol, args.budget), None)}
        for name, size, reg in settings:
            own, first = sqp(problem, xs0, us0, size, reg, args.tol, args.budget)
            got[name] = (first, own)
        cells = ["%4s" % show(got["fddp"][0])] + [
            "%4s/%-4s" % (show(got[n][0]), show(got[n][1])) for n, _, _ in settings]
        line = "%4d  %.15e  %s" % (i, c0, "  ".join(cells))
        if i in ours:
            g = ours[i]
            line += "  |          %4s %4s %8s  %.1e" % (g[1], g[2], g[3], abs(g[0] - c0) / abs(c0))
        print(line, flush=True)
        for b, row in budgets.items():
            for n in names:
                row[n] += got[n][0] is not None and got[n][0] <= b
    n = min(args.count, len(X0))
    for b, row in sorted(budgets.items()):
        print("solved within %3d: " % b + "  ".join("%s %.2f" % (k, v / n) for k, v in row.items()))
    if args.trace is not None:
        problem, xs0, us0 = build(X0[args.trace], args.dynamics, args.guess)
        for reg in (0.0, None):
            print("mim SQP on instance %d, reg_min %s: iter cost gap_l1 KKT max(gaps,|Qu|)" % (
                args.trace, "1e-9" if reg is None else reg))
            for k, r in enumerate(sqp_rows(problem, xs0, us0, 1, reg, 12)):
                print("  %3d %.9e %.4e %.4e %.4e" % (k, *r))
    return 0


if __name__ == "__main__":
    sys.exit(main())
