#!/usr/bin/env bash
# Runs the peer benchmark harness (aligator, crocoddyl, mim_solvers from PyPI) with
# gharial added as an extra solver, and prints the merged table.
#   PEERS_DIR  the harness (default: ../shared/peers beside the repository); it is copied
#              to WORK_DIR because the harness writes its build and results in place
#   WORK_DIR   writable copy (default: $HOME/.cache/gharial-peers/harness)
# Every other knob of the harness's run.sh (REPEATS, TOL, PROBLEMS, ...) passes through.
set -euo pipefail
HERE="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"
ROOT="$(cd "$HERE/../.." && pwd)"
PEERS_DIR="${PEERS_DIR:-$ROOT/../shared/peers}"
WORK_DIR="${WORK_DIR:-$HOME/.cache/gharial-peers/harness}"
mkdir -p "$WORK_DIR"
# Keep the files' times (-p): the harness rebuilds its C++ program only when a source is
# newer than the binary, and a fresh copy time would force a rebuild on every run.
cp -R -p "$PEERS_DIR"/. "$WORK_DIR"/
chmod -R u+w "$WORK_DIR"
mkdir -p "$WORK_DIR/extra"
cp "$HERE/gharial.sh" "$WORK_DIR/extra/gharial.sh"
chmod +x "$WORK_DIR/extra/gharial.sh"
cd "$WORK_DIR"
GHARIAL_ROOT="$ROOT" ./run.sh
