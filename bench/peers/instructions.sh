#!/usr/bin/env bash
# Instructions executed by one solve (valgrind's callgrind, collection switched on inside
# the solver's solve call only) of gharial and of the peer solver of the same name, on the
# peer harness's problems: a measure of the work per solve that a shared, noisy machine
# cannot blur, beside run.sh's wall-clock times (which it does not replace: the
# instructions per cycle of the two code bases differ).
#   PAIRS      problem:solver pairs (default: every DDP-family, SQP and CSQP pair the
#              harness runs on crocoddyl and mim_solvers)
#   CROC_VENV  the harness's crocoddyl + mim_solvers venv (default: the one its
#              setup.sh creates, $HOME/.cache/gharial-peers/croc)
#   PEERS_DIR  the harness (default: ../shared/peers beside the repository)
# Prints a Markdown table: iterations and instructions of each side and their ratio.
set -euo pipefail
HERE="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"
ROOT="$(cd "$HERE/../.." && pwd)"
PEERS_DIR="${PEERS_DIR:-$ROOT/../shared/peers}"
CROC_VENV="${CROC_VENV:-$HOME/.cache/gharial-peers/croc}"
PAIRS="${PAIRS:-lqr:DDP lqr:FDDP lqr:SQP ur5:DDP ur5:FDDP ur5:SQP pendulum:DDP pendulum:FDDP pendulum:SQP \
lqr_box:BoxDDP lqr_box:BoxFDDP lqr_box:CSQP lqr_box_term:CSQP ur5_box:BoxDDP ur5_box:BoxFDDP ur5_box:CSQP \
pendulum_box:BoxDDP pendulum_box:CSQP pendulum_box_term:CSQP}"
command -v valgrind >/dev/null || { echo "instructions.sh: valgrind is needed" >&2; exit 2; }
[ -x "$CROC_VENV/bin/python" ] || { echo "instructions.sh: no venv at $CROC_VENV (run the harness's setup.sh)" >&2; exit 2; }
. "$ROOT/bench/peers/build_gharial.sh"
GHARIAL="$ROOT/target/release/gharial"
TMP="$(mktemp -d)"
trap 'rm -rf "$TMP"' EXIT
export OMP_NUM_THREADS=1

# Instructions collected by callgrind while the functions matching $1 run, without those
# of the OpenMP runtime (crocoddyl's parallel loops call it even on one thread, and its
# waiting loops execute a load-dependent number of instructions); the command follows.
# Its standard output goes to $TMP/out.
collected() {
  local pattern="$1"
  shift
  valgrind --tool=callgrind --callgrind-out-file="$TMP/cg.out" --collect-atstart=no \
    --toggle-collect="$pattern" "$@" >"$TMP/out" 2>"$TMP/err" || { cat "$TMP/err" >&2; return 1; }
  local total openmp
  total=$(sed -n 's/^==[0-9]*== Collected : //p' "$TMP/err")
  openmp=$(callgrind_annotate --threshold=100 "$TMP/cg.out" 2>/dev/null \
    | awk '/libgomp/ { gsub(",", "", $1); s += $1 } END { printf "%.0f\n", s }')
  echo $((total - openmp))
}

# The solve function of each peer solver (BoxFDDP and BoxDDP inherit FDDP's and DDP's).
peer_symbol() {
  case "$1" in
    DDP | BoxDDP) echo 'crocoddyl::SolverDDP::solve(*' ;;
    FDDP | BoxFDDP) echo 'crocoddyl::SolverFDDP::solve(*' ;;
    SQP) echo 'mim_solvers::SolverSQP::solve(*' ;;
    CSQP) echo 'mim_solvers::SolverCSQP::solve(*' ;;
    *) echo "instructions.sh: no peer solver $1" >&2; return 1 ;;
  esac
}

echo "| problem | solver | gharial iterations | peer iterations | gharial instructions | peer instructions | ratio |"
echo "|---|---|---:|---:|---:|---:|---:|"
for pair in $PAIRS; do
  problem="${pair%%:*}"
  solver="${pair#*:}"
  g=$(collected '*as gharial::solvers::Solver>::solve_with' \
    "$GHARIAL" bench peers --problems "$problem" --solvers "$solver" --repeats 1)
  g_iters=$(sed -n 's/.*"iters":\([0-9]*\).*/\1/p' "$TMP/out")
  p=$(collected "$(peer_symbol "$solver")" \
    "$CROC_VENV/bin/python" "$HERE/peer_once.py" "$PEERS_DIR" "$problem" "$solver")
  p_iters=$(cut -d' ' -f1 "$TMP/out")
  ratio=$(python3 -c "print(f'{$g / $p:.2f}')")
  printf '| `%s` | %s | %s | %s | %.1f M | %.1f M | %s |\n' "$problem" "$solver" "$g_iters" "$p_iters" \
    "$(python3 -c "print($g / 1e6)")" "$(python3 -c "print($p / 1e6)")" "$ratio"
done
