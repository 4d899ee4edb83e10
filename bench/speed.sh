#!/usr/bin/env bash
# Issue 17's speed table, every figure beside its target and, where one exists, a reference
# measured in this run on this machine:
#   - UpdateMask (flow given) on the bench's synthetic step against the numpy/scipy
#     reference (bench/update_mask.sh), and on the first push of simulated packed and loose
#     scenes; how its stages grow with the image size and the number of frames;
#   - the static segmenter and the built-in flow on 1 and 2 threads, FindAction, and the
#     whole push cycle; the built-in flow against OpenCV's DIS presets (bench/flow.sh);
#   - a one-shot `riseg flow` process against the warm estimate on the same pair with the
#     same thread count (1 and 2), timed alternately (speed example `oneshot`), and the
#     process's minor page faults;
#   - bench/flow.sh on the seed the presets were tuned on and on one they were not;
#   - peak memory of `riseg demo` and of `riseg run` on one scene, riseg-core's workspace;
#   - the bare-metal firmware under QEMU (firmware/run.sh), when qemu-system-arm is present.
#
#   bash bench/speed.sh            (RUNS=15 timed runs per figure, SCENES=6 per family)
#
# Needs python3 with numpy and scipy (bench/requirements.txt); bench/flow.sh makes its own
# virtualenv for OpenCV. Honours CARGO_TARGET_DIR. Run it on an idle machine: every time is
# a median, but other load still shifts them.
set -euo pipefail
cd "$(dirname "$0")/.."

RUNS="${RUNS:-15}"
SCENES="${SCENES:-6}"
# Dataset seed of the simulated scenes: not one the parameters were tuned on.
SEED="${SEED:-41}"
work="$(mktemp -d)"
trap 'rm -rf "$work"' EXIT

target_dir="$(cargo metadata --format-version 1 --no-deps |
  python3 -c 'import json, sys; print(json.load(sys.stdin)["target_directory"])')"
echo "==> build"
cargo build --release --quiet -p riseg --bin riseg --example speed
riseg="$target_dir/release/riseg"
speed="$target_dir/release/examples/speed"

echo "==> simulated scenes (seed $SEED, $SCENES per family, one push)"
for layout in packed loose; do
  "$riseg" gen --layout "$layout" --scenes "$SCENES" --pushes 1 --seed "$SEED" \
    --out "$work/$layout" >/dev/null
done

echo "==> push cycle ($RUNS runs per part and scene)"
"$speed" cycle "$work/packed" "$work/loose" --runs "$RUNS" >"$work/rows.tsv"
echo "==> UpdateMask scaling"
"$speed" scaling --runs "$RUNS" >>"$work/rows.tsv"

echo "==> UpdateMask on the synthetic step against numpy (bench/update_mask.sh)"
bash bench/update_mask.sh | tee "$work/update_mask.txt"

echo "==> one-shot riseg flow against the warm estimate (same pair and threads, alternating)"
pair="$work/packed/scene_000"
"$speed" oneshot "$riseg" "$pair/rgb/000000.png" "$pair/rgb/000001.png" --out "$work/f.flo" \
  --runs "$RUNS" >>"$work/rows.tsv"
/usr/bin/time -f '%R' -o "$work/time.txt" \
  "$riseg" flow "$pair/rgb/000000.png" "$pair/rgb/000001.png" -o "$work/f.flo" --threads 1
printf 'oneshot\t1t\tminor_faults\t%s\n' "$(cat "$work/time.txt")" >>"$work/rows.tsv"

echo "==> peak memory"
/usr/bin/time -f '%M' -o "$work/time.txt" "$riseg" demo --out "$work/demo" >/dev/null
printf 'memory\tdemo\tpeak_kb\t%s\n' "$(cat "$work/time.txt")" >>"$work/rows.tsv"
mkdir -p "$work/one/scene_000"
cp -r "$pair"/. "$work/one/scene_000"
/usr/bin/time -f '%M' -o "$work/time.txt" \
  "$riseg" run --dataset "$work/one" --out "$work/run" >/dev/null
printf 'memory\trun_one_packed_scene\tpeak_kb\t%s\n' "$(cat "$work/time.txt")" >>"$work/rows.tsv"

if command -v qemu-system-arm >/dev/null; then
  echo "==> firmware (firmware/run.sh)"
  bash firmware/run.sh | tee "$work/firmware.txt"
else
  echo "==> firmware: skipped (no qemu-system-arm; .ci/run installs it)" | tee "$work/firmware.txt"
fi

echo "==> built-in flow against OpenCV DIS (bench/flow.sh): tuned seed 1, then untouched seed 101"
bash bench/flow.sh 6 7 1 | tee "$work/flow.txt"
bash bench/flow.sh 6 7 101 | tee -a "$work/flow.txt"

echo
python3 - "$work" "$target_dir" <<'PY'
import json
import re
import sys
from pathlib import Path

work, target_dir = Path(sys.argv[1]), Path(sys.argv[2])
rows = {}
for line in (work / "rows.tsv").read_text().splitlines():
    table, case, column, value = line.split("\t")
    rows.setdefault((table, case, column), []).append(float(value))
get = lambda *k: rows[k][0]

crit = target_dir / "criterion" / "update_mask_640x480_n1000" / "total" / "new" / "estimates.json"
synthetic_ms = json.loads(crit.read_text())["median"]["point_estimate"] / 1e6
numpy_ms = None
for line in (work / "update_mask.txt").read_text().splitlines():
    cells = [c.strip() for c in line.split("|")]
    if len(cells) == 4 and cells[0] == "total":
        numpy_ms = float(cells[2])


def row(what, value, reference, target, met):
    print(f"| {what} | {value} | {reference} | {target} | {'yes' if met else 'no'} |")


print("## Speed (bench/speed.sh)\n")
print("| measure | riseg | reference, same run | target | met |")
print("|---|---|---|---|---|")
ratio = numpy_ms / synthetic_ms if numpy_ms else float("nan")
row("UpdateMask, synthetic step 640x480 n=1000 (criterion median)", f"{synthetic_ms:.2f} ms",
    f"numpy/scipy {numpy_ms:.1f} ms ({ratio:.1f}x)", "<= 5 ms, >= 19x", synthetic_ms <= 5 and ratio >= 19)
for fam in ("packed", "loose"):
    um = get("cycle", fam, "update_mask")
    parts = ", ".join(f"{s} {get('cycle', fam, s):.2f}" for s in ("frames", "twists", "grouping", "mask"))
    row(f"UpdateMask, {fam} scenes' first push, exact flow ({parts})", f"{um:.2f} ms", "-", "<= 5 ms", um <= 5)
for fam in ("packed", "loose"):
    s1, s2 = get("cycle", fam, "segment_1t"), get("cycle", fam, "segment_2t")
    row(f"static segmenter, {fam}, 1 thread (2 threads)", f"{s1:.1f} ms ({s2:.1f} ms, {s1 / s2:.2f}x)",
        "-", "<= 15 ms on 1 thread", s1 <= 15)
for fam in ("packed", "loose"):
    f1, f2 = get("cycle", fam, "flow_1t"), get("cycle", fam, "flow_2t")
    print(f"| built-in flow MEDIUM in the loop, {fam} pairs, 1 thread (2 threads) | {f1:.1f} ms "
          f"({f2:.1f} ms, {f1 / f2:.2f}x) | - | thread scaling reported | yes |")
# bench/flow.sh: one markdown table per pair set, after a line naming it.
pair_set = None
for line in (work / "flow.txt").read_text().splitlines():
    if line.startswith("Dense flow"):
        pair_set, found = line.split(",")[2].strip(), {}
    cells = [c.strip() for c in line.strip().strip("|").split("|")]
    if pair_set and len(cells) == 4 and cells[0] in ("riseg-medium", "opencv-dis-medium"):
        found[cells[0]] = (float(cells[1]), float(cells[3]))
        if len(found) == 2:
            (epe, ms), (dis_epe, dis_ms) = found["riseg-medium"], found["opencv-dis-medium"]
            row(f"built-in flow MEDIUM vs DIS-medium, {pair_set} (EPE on objects px; bench/flow.sh)",
                f"EPE {epe:.3f}, {ms:.1f} ms", f"DIS-medium EPE {dis_epe:.3f}, {dis_ms:.1f} ms ({ms / dis_ms:.2f}x)",
                "EPE <= DIS's at <= 0.5x its time", epe <= dis_epe and ms <= 0.5 * dis_ms)
            pair_set = None
for fam in ("packed", "loose"):
    c1, c2 = get("cycle", fam, "cycle_1t"), get("cycle", fam, "cycle_2t")
    fa = get("cycle", fam, "find_action")
    row(f"push cycle, {fam} (segment + flow + UpdateMask + FindAction {fa:.2f} ms), 1 thread (2)",
        f"{c1:.1f} ms ({c2:.1f} ms)", "-", "<= 50 ms on 1 thread", c1 <= 50)
for t in (1, 2):
    cli, warm = get("oneshot", f"{t}t", "process"), get("oneshot", f"{t}t", "warm")
    new = get("oneshot", f"{t}t", "process_new")
    # Judged on the process writing a new file: replacing an existing one adds the file
    # system's cost of deleting the old file (on an ext4 mounted with `discard`, a
    # synchronous TRIM of its blocks inside the rename, ~2.3 ms for 2.4 MB), which any
    # tool pays for the same replacement (as an `rm` of the old file would).
    row(f"one-shot `riseg flow --threads {t}` on a packed pair, writing a new .flo (over the last run's)"
        " (wall, spawn to exit, median)", f"{new:.1f} ms ({cli:.1f} ms)",
        f"warm estimate {warm:.1f} ms, same pair and threads, timed alternately ({new / warm:.2f}x; {cli / warm:.2f}x)",
        "<= 1.5x warm", new <= 1.5 * warm)
decode, start = get("oneshot", "decode", "pair"), get("oneshot", "start", "process")
row("PNG decode of the pair in the one-shot, one after the other (part of the one-shot's time)",
    f"{decode:.1f} ms", "-", "reported", True)
row("a `riseg --version` process, spawn to exit (part of every one-shot's time)", f"{start:.1f} ms", "-",
    "reported", True)
for t in (1, 2):
    warm = get("oneshot", f"{t}t", "warm")
    # What a one-shot cannot avoid even with every buffer's pages already in place: starting
    # and ending a process, and decoding the two PNGs (the warm estimate starts from pixels).
    # On two threads the two images decode side by side: at best half the serial time.
    floor = start + decode / t + warm
    row(f"one-shot floor, {t} thread(s): process start + warm decode of the pair (serial time / {t}) + warm"
        " estimate", f"{floor:.1f} ms", f"warm estimate {warm:.1f} ms ({floor / warm:.2f}x)", "reported", True)
row("one-shot `riseg flow --threads 1`, minor page faults", f"{get('oneshot', '1t', 'minor_faults'):.0f}", "-",
    "reported", True)
row("peak RSS, `riseg demo`", f"{get('memory', 'demo', 'peak_kb') / 1024:.0f} MiB", "-", "reported", True)
row("peak RSS, `riseg run` on one packed scene", f"{get('memory', 'run_one_packed_scene', 'peak_kb') / 1024:.0f} MiB",
    "-", "reported", True)
ws = get("scaling", "640x480 n=1000", "workspace_bytes")
row("riseg-core workspace, 640x480 n=1000 (WorkspaceLen::bytes)", f"{ws:,.0f} B", "-", "reported", True)
fw = (work / "firmware.txt").read_text()
m = re.search(r"^instructions: update_mask (\d+)", fw, re.M)
flash = re.search(r"flash (\d+) bytes; RAM (\d+) bytes", fw)
if m and flash:
    row("firmware, update_mask at 160x120 under QEMU Cortex-M4F", f"{int(m.group(1)) / 1e6:.1f} M instructions",
        "-", "runs, counted", True)
    row("firmware flash / RAM", f"{int(flash.group(1)):,} B / {int(flash.group(2)):,} B", "-", "reported", True)
else:
    print("| firmware | not run | - | runs, counted | no |")

print("\n## UpdateMask scaling (synthetic step, one thread, median ms)\n")
print("| image, frames | frames | twists | grouping | mask | total | workspace bytes |")
print("|---|---|---|---|---|---|---|")
for size in ("320x240", "640x480", "1280x720"):
    for n in (250, 1000, 4000):
        case = f"{size} n={n}"
        cells = [f"{get('scaling', case, s):.2f}" for s in ("frames", "twists", "grouping", "mask", "total")]
        print(f"| {case} | " + " | ".join(cells) + f" | {get('scaling', case, 'workspace_bytes'):,.0f} |")
PY
echo
echo "load average: $(cut -d' ' -f1-3 /proc/loadavg); $(nproc) cores"
