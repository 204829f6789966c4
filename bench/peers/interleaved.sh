#!/usr/bin/env bash
# Wall-clock ratios gharial / peer measured the way a shared, noisy machine allows:
# rounds that alternate gharial's solves (`gharial bench peers`, one thread and two) and
# the peer solver's (crocoddyl / mim_solvers through the harness's own problem code,
# with one thread and with two, crocoddyl's default that the harness keeps), each round
# REPEATS solves of each; one line per round with the medians, minima and the ratios of
# both at equal thread counts. The
# minima are the least disturbed figures: on this shared machine a side's median moves
# by up to 1.8x between rounds (two modes), its minimum by a few per cent; the
# two-thread peer spins when the other core is busy (tens of milliseconds on `lqr`).
#   PAIRS      problem:solver pairs (default: FDDP and SQP on lqr, ur5, pendulum; CSQP
#              on the box problems)
#   ROUNDS     rounds per pair (default 3); REPEATS solves per side and round (default 20)
#   CROC_VENV, PEERS_DIR  as in instructions.sh
set -euo pipefail
HERE="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"
ROOT="$(cd "$HERE/../.." && pwd)"
PEERS_DIR="${PEERS_DIR:-$ROOT/../shared/peers}"
CROC_VENV="${CROC_VENV:-$HOME/.cache/gharial-peers/croc}"
PAIRS="${PAIRS:-lqr:FDDP ur5:FDDP pendulum:FDDP lqr:SQP ur5:SQP pendulum:SQP \
lqr_box:CSQP lqr_box_term:CSQP ur5_box:CSQP pendulum_box:CSQP}"
ROUNDS="${ROUNDS:-3}"
REPEATS="${REPEATS:-20}"
[ -x "$CROC_VENV/bin/python" ] || { echo "interleaved.sh: no venv at $CROC_VENV (run the harness's setup.sh)" >&2; exit 2; }
. "$ROOT/bench/peers/build_gharial.sh"
GHARIAL="$ROOT/target/release/gharial"

echo "| problem | solver | round | gharial 1 thread median / min (ms) | gharial 2 threads | peer 1 thread | peer 2 threads | ratio of medians (1 / 2 threads) | ratio of minima (1 / 2) |"
echo "|---|---|---:|---|---|---|---|---|---|"
for pair in $PAIRS; do
  problem="${pair%%:*}"
  solver="${pair#*:}"
  for round in $(seq "$ROUNDS"); do
    g() {
      "$GHARIAL" bench peers --problems "$problem" --solvers "$solver" --repeats "$REPEATS" --threads "$1" \
        | python3 -c 'import json,sys; d=json.loads(sys.stdin.readline()); print(d["time_ms"], d["time_ms_min"])'
    }
    g1=$(g 1)
    g2=$(g 2)
    p1=$("$CROC_VENV/bin/python" "$HERE/peer_once.py" "$PEERS_DIR" "$problem" "$solver" "$REPEATS" 1 | cut -d' ' -f2-)
    p2=$("$CROC_VENV/bin/python" "$HERE/peer_once.py" "$PEERS_DIR" "$problem" "$solver" "$REPEATS" 2 | cut -d' ' -f2-)
    python3 - "$problem" "$solver" "$round" $g1 $g2 $p1 $p2 <<'PY'
import sys
problem, solver, rnd = sys.argv[1:4]
gm, gn, hm, hn, am, an, bm, bn = map(float, sys.argv[4:12])
print(f"| `{problem}` | {solver} | {rnd} | {gm:.3f} / {gn:.3f} | {hm:.3f} / {hn:.3f} | {am:.3f} / {an:.3f} "
      f"| {bm:.3f} / {bn:.3f} | {gm / am:.2f} / {hm / bm:.2f} | {gn / an:.2f} / {hn / bn:.2f} |")
PY
  done
done
