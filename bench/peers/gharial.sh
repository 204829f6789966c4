#!/usr/bin/env bash
# Extra solver for the peer benchmark harness (its README, "To add the Rust solver"):
# run.sh calls this script with REPEATS, TOL, MAX_ITERS, PROBLEMS, TRAJ_DIR and the
# LQR_* knobs in the environment; it prints one JSON line per (problem, solver) and
# writes the final trajectories to $TRAJ_DIR. GHARIAL_ROOT points at the repository.
# Threads as the peers of each solver have them: the ProxDDP family (against aligator)
# and the solvers without a peer on one; the DDP family, SQP and CSQP on
# GHARIAL_THREADS (default 2: crocoddyl's shooting problem, which mim_solvers also
# uses, evaluates its stages on two threads unless told otherwise, and the harness
# leaves it so).
set -euo pipefail
ROOT="${GHARIAL_ROOT:?set GHARIAL_ROOT to the gharial repository}"
. "$ROOT/bench/peers/build_gharial.sh"
run() {
  "$ROOT/target/release/gharial" bench peers \
    --problems "${PROBLEMS:-lqr,lqr_box,lqr_box_term,ur5,ur5_box,pendulum,pendulum_box,pendulum_box_term}" \
    --repeats "${REPEATS:-5}" --tol "${TOL:-1e-6}" --max-iters "${MAX_ITERS:-500}" \
    --traj-dir "${TRAJ_DIR:?}" \
    --lqr-nx "${LQR_NX:-8}" --lqr-nu "${LQR_NU:-4}" --lqr-N "${LQR_N:-100}" \
    --lqr-seed "${LQR_SEED:-42}" --lqr-umax "${LQR_UMAX:-0.05}" "$@"
}
run --solvers ProxDDP,ProxDDP_ls,ProxDDP_as,BCL-DDP,ALTRO,ProxNLP --threads 1
run --solvers DDP,FDDP,BoxDDP,BoxFDDP,SQP,CSQP --threads "${GHARIAL_THREADS:-2}"
