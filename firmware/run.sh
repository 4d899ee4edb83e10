#!/usr/bin/env bash
# Bare-metal riseg-core (issue 17): builds the firmware for thumbv7em-none-eabihf with
# Debian's rustc-web and build-std=core (no alloc: no heap can be linked), runs it under
# qemu-system-arm -M mps2-an386 (Cortex-M4F) with -icount shift=0 and semihosting, prints
# its output and the flash and RAM the ELF needs, then runs the same step natively
# (../determinism, riseg's testkit scene and heap workspace) and fails unless both print
# the same input and output digests.
# Set CARGO_TARGET_DIR to build elsewhere, NATIVE_TARGET_DIR for determinism/'s build
# (default: $CARGO_TARGET_DIR/native); QEMU_TIMEOUT (seconds) bounds the run.
set -euo pipefail
cd "$(dirname "$0")"
target="$(realpath -m "${CARGO_TARGET_DIR:-target}")"
elf="$target/thumbv7em-none-eabihf/release/riseg-firmware"

RUSTC=/usr/bin/rustc RUSTC_BOOTSTRAP=1 CARGO_TARGET_DIR="$target" /usr/bin/cargo build \
  --release --quiet --target thumbv7em-none-eabihf -Z build-std=core

log="$(mktemp)"
trap 'rm -f "$log"' EXIT
status=0
timeout "${QEMU_TIMEOUT:-120}" qemu-system-arm -M mps2-an386 -cpu cortex-m4 -nographic \
  -monitor none -serial none -semihosting-config enable=on,target=native \
  -icount shift=0 -kernel "$elf" >"$log" 2>&1 || status=$?
cat "$log"
if [ "$status" -ne 0 ]; then
  echo "firmware: qemu-system-arm exited with $status (124 = timeout)" >&2
  exit 1
fi

# Flash: what is loaded at 0 (vector table, code, constants, .data's initial values).
# RAM: .data + .bss + .uninit from the ELF, plus the stack's deepest use the firmware read.
stack="$(sed -n 's/^stack: \([0-9]*\) bytes.*/\1/p' "$log")"
size -A "$elf" | awk -v stack="${stack:-0}" -v map="$elf.map" '
  $1 == ".vector_table" || $1 == ".text" || $1 == ".rodata" { flash += $2 }
  $1 == ".data" { flash += $2; ram += $2 }
  $1 == ".bss" || $1 == ".uninit" { ram += $2 }
  END {
    printf "flash %d bytes; RAM %d bytes = %d static (.data+.bss+.uninit) + %d stack\n",
      flash, ram + stack, ram, stack
    printf "(size -A on the ELF; linker map: %s)\n", map
  }'

firmware="$(grep -E '^input [0-9a-f]{16} output [0-9a-f]{16}$' "$log" || true)"
native_target="$(realpath -m "${NATIVE_TARGET_DIR:-$target/native}")"
native="$(cd ../determinism && CARGO_TARGET_DIR="$native_target" cargo run --release --quiet)"
printf 'firmware: %s\nnative:   %s\n' "${firmware:-<no digest line>}" "$native"
if [ -z "$firmware" ] || [ "$firmware" != "$native" ]; then
  echo "firmware: digests differ from the native run" >&2
  exit 1
fi
echo "firmware: digests match the native run"
