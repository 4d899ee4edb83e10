#!/usr/bin/env bash
# Fuzz smoke test: builds every cargo-fuzz target, then runs each for FUZZ_SMOKE_SECONDS
# (default 20) from the committed corpus, one process at a time. A crash, a failed
# property, a leak, an out-of-memory or a timeout fails the script with the target's name;
# the input is left in fuzz/artifacts/<target>/ (reproduce: cargo +nightly fuzz run
# <target> <file>). New inputs go to a scratch folder, so the committed corpus stays as is.
#
# Needs the nightly toolchain and cargo-fuzz on PATH (.ci/run installs it). Set
# CARGO_TARGET_DIR to build outside fuzz/target.
set -euo pipefail
cd "$(dirname "$0")"

seconds="${FUZZ_SMOKE_SECONDS:-20}"
fuzz=(cargo +nightly fuzz)

"${fuzz[@]}" build
scratch="$(mktemp -d)"
trap 'rm -rf "$scratch"' EXIT
for target in $("${fuzz[@]}" list); do
  extra=()
  case "$target" in
    png_read) extra+=(-dict=dict/png.dict) ;;
    scene_json) extra+=(-dict=dict/json.dict) ;;
  esac
  mkdir -p "$scratch/$target" "corpus/$target"
  printf '==> fuzz smoke: %s, %s s\n' "$target" "$seconds"
  if ! nice -n 10 "${fuzz[@]}" run "$target" "$scratch/$target" "corpus/$target" -- \
      -max_total_time="$seconds" -timeout=30 -rss_limit_mb=2048 "${extra[@]}" \
      >"$scratch/$target.log" 2>&1; then
    tail -n 40 "$scratch/$target.log" >&2
    printf 'fuzz smoke: target %s FAILED (input in fuzz/artifacts/%s/)\n' "$target" "$target" >&2
    exit 1
  fi
  grep -E '^Done [0-9]+ runs' "$scratch/$target.log" || true
done
printf 'fuzz smoke: all targets ran %s s without a crash\n' "$seconds"
