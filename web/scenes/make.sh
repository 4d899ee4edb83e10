#!/usr/bin/env bash
# Regenerates the bundled scenes and index.json: one packed and one loose scene made by
# `riseg gen` (seed 1, two pushes, 640x480), without the ground-truth flow/ (the page
# computes its own flow; leaving it out halves the download).
#   usage: web/scenes/make.sh [path/to/riseg]   (default: cargo run --release)
set -euo pipefail
cd "$(dirname "$0")"
riseg=("${1:-}")
[ -n "${riseg[0]}" ] || riseg=(cargo run --quiet --release --)
tmp="$(mktemp -d)"
trap 'rm -rf "$tmp"' EXIT
for layout in packed loose; do
  "${riseg[@]}" gen --layout "$layout" --scenes 1 --pushes 2 --seed 1 --out "$tmp/$layout" >/dev/null
  rm -rf "$layout"
  mv "$tmp/$layout/scene_000" "$layout"
  rm -rf "$layout/flow"
done
# index.json: what the page fetches for each bundled scene (a static server lists no folders).
{
  printf '{"scenes": [\n'
  sep=""
  for layout in packed loose; do
    files="$(cd "$layout" && find . -type f | sed 's|^\./||' | sort | sed 's/.*/"&"/' | paste -sd, -)"
    printf '%s  {"name": "%s", "title": "%s (riseg gen --layout %s --seed 1 --pushes 2)", "files": [%s]}' \
      "$sep" "$layout" "$layout" "$layout" "$files"
    sep=$',\n'
  done
  printf '\n]}\n'
} > index.json
du -sh packed loose
