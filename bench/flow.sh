#!/usr/bin/env bash
# riseg's DIS flow against OpenCV's DIS presets on the same 640x480 pairs with exact ground
# truth, both on one thread, in one run. Prints three tables: textured rigid objects moved
# on a textured background, and the simulator's pushes (the frames `riseg gen` writes) in
# its loose and its packed layouts.
#
#   bash bench/flow.sh [PAIRS] [RUNS] [SEED]
#
# Defaults: 6 pairs, 7 timed runs per pair, seed 1 (pair i uses seed SEED + i; the presets
# were tuned on the default seeds, other seeds check that the figures hold).
#
# Needs python3 with opencv-python-headless and numpy; if they are missing, a virtualenv
# is made under ${RISEG_BENCH_VENV:-$HOME/.cache/riseg-bench-venv} and they are installed
# from PyPI. RISEG_FLOW_PRESETS picks riseg's rows (default ultrafast,fast,medium,fine; a
# `+anchor` or `+noanchor` suffix toggles the coarse anchor, see the flow_pairs example).
# The pairs are written to ${RISEG_FLOW_PAIRS:-/tmp/riseg-flow-pairs}/{textured,sim,packed}.
set -euo pipefail
cd "$(dirname "$0")/.."

PAIRS="${1:-6}"
RUNS="${2:-7}"
SEED="${3:-1}"
PRESETS="${RISEG_FLOW_PRESETS:-ultrafast,fast,medium,fine}"
DIR="${RISEG_FLOW_PAIRS:-/tmp/riseg-flow-pairs}"
PY=python3
if ! "$PY" -c 'import cv2, numpy' 2>/dev/null; then
  VENV="${RISEG_BENCH_VENV:-$HOME/.cache/riseg-bench-venv}"
  if ! [ -x "$VENV/bin/python" ] || ! "$VENV/bin/python" -c 'import cv2, numpy' 2>/dev/null; then
    python3 -m venv "$VENV"
    "$VENV/bin/pip" install --quiet opencv-python-headless numpy
  fi
  PY="$VENV/bin/python"
fi

cargo build --quiet --release -p riseg --example flow_pairs
EXAMPLE="${CARGO_TARGET_DIR:-target}/release/examples/flow_pairs"

ROWS="$(mktemp)"
trap 'rm -f "$ROWS"' EXIT
for KIND in textured sim packed; do
  : >"$ROWS"
  rm -f "$DIR/$KIND"/pair_*
  "$EXAMPLE" "$DIR/$KIND" --kind "$KIND" --pairs "$PAIRS" --runs "$RUNS" --seed "$SEED" --presets "$PRESETS" >>"$ROWS"
  "$PY" bench/flow_vs_opencv.py "$DIR/$KIND" --runs "$RUNS" >>"$ROWS"
  echo "Dense flow, 640x480, $PAIRS $KIND pairs from seed $SEED (exact ground truth), one thread,"
  echo "median of $RUNS runs per pair, averaged over pairs; $(nproc) cores, load $(cut -d' ' -f1-3 /proc/loadavg)."
  echo
  printf '| %-22s | %15s | %15s | %9s |\n' method "EPE objects px" "EPE all px" "time ms"
  printf '|%s|%s|%s|%s|\n' "------------------------" "-----------------" "-----------------" "-----------"
  sort -k4 -n -t$'\t' "$ROWS" | while IFS=$'\t' read -r name obj all ms; do
    printf '| %-22s | %15s | %15s | %9s |\n' "$name" "$obj" "$all" "$ms"
  done
  echo
done
