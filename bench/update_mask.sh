#!/usr/bin/env bash
# One UpdateMask step at 640x480, n = 1000, flow given (not computed), per stage: riseg's
# criterion bench against the numpy/scipy reference of the same step on the same inputs,
# both measured in this run on this machine, single-threaded.
#
#   bench/update_mask.sh            (honours CARGO_TARGET_DIR and PYTHON)
set -euo pipefail
cd "$(dirname "$0")/.."

PYTHON="${PYTHON:-python3}"
if ! "$PYTHON" -c 'import numpy, scipy' 2>/dev/null; then
  echo "error: the numpy reference needs numpy and scipy, which $PYTHON cannot import." >&2
  echo "install them with:  $PYTHON -m pip install -r bench/requirements.txt" >&2
  exit 1
fi

work="$(mktemp -d)"
trap 'rm -rf "$work"' EXIT

echo "==> inputs: the bench's synthetic step"
cargo run --release --quiet -p riseg --example dump_synthetic_step -- "$work/step"

echo "==> riseg: cargo bench -p riseg --bench bench_update_mask"
cargo bench -p riseg --bench bench_update_mask

echo "==> numpy/scipy reference"
"$PYTHON" bench/update_mask_reference.py "$work/step" --json "$work/numpy.json"

target_dir="$(cargo metadata --format-version 1 --no-deps |
  "$PYTHON" -c 'import json, sys; print(json.load(sys.stdin)["target_directory"])')"

echo
"$PYTHON" - "$target_dir/criterion/update_mask_640x480_n1000" "$work/numpy.json" <<'PY'
import json
import sys
from pathlib import Path

criterion, reference = Path(sys.argv[1]), json.loads(Path(sys.argv[2]).read_text())
print(f"{'stage':<9} | {'riseg ms':>9} | {'numpy ms':>9} | {'ratio':>7}")
print(f"{'-' * 9} | {'-' * 9} | {'-' * 9} | {'-' * 7}")
for stage, numpy_ms in reference["stages_ms"].items():
    estimates = criterion / stage / "new" / "estimates.json"
    if not estimates.is_file():
        sys.exit(f"error: no criterion result for '{stage}' at {estimates}")
    riseg_ms = json.loads(estimates.read_text())["median"]["point_estimate"] / 1e6
    print(f"{stage:<9} | {riseg_ms:9.3f} | {numpy_ms:9.2f} | {numpy_ms / riseg_ms:6.0f}x")
print(
    f"\nriseg: criterion median; numpy {reference['numpy']}, scipy {reference['scipy']}: "
    f"median of {reference['repeat']} runs; {reference['frames']} frames, "
    f"{reference['groups']} groups in the reference"
)
PY
echo "load average: $(cut -d' ' -f1-3 /proc/loadavg)"
