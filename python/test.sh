#!/usr/bin/env bash
# Builds the riseg wheel with maturin, installs it into a fresh virtualenv and runs the
# pytest suite there against the `riseg` CLI built from this repository.
#
# maturin lives in a cached tools virtualenv; the test virtualenv is new on every run, so
# the wheel must install as a user's would. Every Python package is pinned. Nothing is
# skipped: a missing tool, package or binary fails the script.
#
# Environment: RISEG_CI_CACHE (default ~/.cache/riseg-ci) for the tools and, unless
# CARGO_TARGET_DIR is set, the cargo target; PYTHON (default python3). RISEG_RERUN=1 also
# builds the CLI with `--features rerun` (the rerun SDK: a long cold build), installs the
# `rerun-sdk` wheel of the same version and runs tests/test_rerun.py; without it that
# file is not run, and the script says so. RISEG_BIN: test against this riseg binary
# instead of building one (CI passes the every-feature CLI its feature tests built; with
# RISEG_RERUN=1 it must have the `rerun` feature).
set -euo pipefail
cd "$(dirname "$0")"

MATURIN_VERSION=1.16.0
NUMPY_VERSION=2.4.6
PYTEST_VERSION=8.4.2
# The same version as the `re_sdk` and `re_sdk_types` crates in Cargo.toml.
RERUN_SDK_VERSION=0.36.3

CACHE="${RISEG_CI_CACHE:-$HOME/.cache/riseg-ci}"
export CARGO_TARGET_DIR="${CARGO_TARGET_DIR:-$CACHE/target}"
PYTHON="${PYTHON:-python3}"
TOOLS="$CACHE/py-tools"
WORK="$(mktemp -d)"
trap 'rm -rf "$WORK"' EXIT

if [ "$("$TOOLS/bin/maturin" --version 2>/dev/null)" != "maturin $MATURIN_VERSION" ]; then
  rm -rf "$TOOLS"
  "$PYTHON" -m venv "$TOOLS"
  "$TOOLS/bin/pip" install --quiet --disable-pip-version-check "maturin==$MATURIN_VERSION"
fi

echo "python/test.sh: wheel (maturin $MATURIN_VERSION)"
"$TOOLS/bin/maturin" build --release --quiet --out "$WORK/wheels"

PACKAGES=("numpy==$NUMPY_VERSION" "pytest==$PYTEST_VERSION")
TESTS=(test_riseg.py)
FEATURES=()
if [ "${RISEG_RERUN:-0}" = 1 ]; then
  PACKAGES+=("rerun-sdk==$RERUN_SDK_VERSION")
  TESTS+=(test_rerun.py)
  FEATURES=(--features rerun)
else
  echo "python/test.sh: not running test_rerun.py (RISEG_RERUN=1 runs it)"
fi

if [ -n "${RISEG_BIN:-}" ]; then
  echo "python/test.sh: the riseg CLI the tests compare with: $RISEG_BIN"
  [ -x "$RISEG_BIN" ] || { echo "python/test.sh: RISEG_BIN=$RISEG_BIN is not an executable" >&2; exit 1; }
else
  echo "python/test.sh: the riseg CLI the tests compare with (cargo build)"
  (cd .. && cargo build --release --quiet -p riseg --bin riseg "${FEATURES[@]}")
  RISEG_BIN="$CARGO_TARGET_DIR/release/riseg"
fi

echo "python/test.sh: fresh virtualenv"
"$PYTHON" -m venv "$WORK/venv"
"$WORK/venv/bin/pip" install --quiet --disable-pip-version-check "${PACKAGES[@]}"
"$WORK/venv/bin/pip" install --quiet --disable-pip-version-check --no-index \
  "$WORK"/wheels/riseg-*.whl

# Run from the tests folder: `import riseg` must find the installed wheel, not the source.
cd tests
RISEG_BIN="$RISEG_BIN" "$WORK/venv/bin/python" -m pytest -p no:cacheprovider \
  "${TESTS[@]}" "$@"
