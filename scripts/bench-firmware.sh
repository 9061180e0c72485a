#!/usr/bin/env bash
# Firmware figures (a benchmark, not a test): instructions per identifier step on the
# Cortex-M4F build under QEMU with an instruction-counting TCG plugin, and cycles estimated at
# 168 MHz; flash and RAM of the firmware images and of identifier-core alone (llvm-size);
# worst-case stack use of the sample loop, measured by painting the stack under QEMU.
set -euo pipefail
source "$(dirname "${BASH_SOURCE[0]}")/setup.sh"
cd "$ROOT"

ensure_thumb_target
ensure_llvm_tools
ensure_qemu
ensure_defmt_print
ensure_gcc

OUT=target/firmware-bench
mkdir -p "$OUT"
TARGET=(--target thumbv7em-none-eabihf --profile firmware)
CLOCK_MHZ=168

# The path of a binary cargo just built (the uplifted name is shared between feature sets).
built_exe() {
    cargo build -q "$@" --message-format=json |
        sed -n 's/.*"executable":"\([^"]*\)".*/\1/p' | tail -n 1
}

log "building firmware images (qemu, qemu+bench, stm32f405)"
cp "$(built_exe -p firmware --bin firmware-qemu --features qemu "${TARGET[@]}")" "$OUT/firmware-qemu"
cp "$(built_exe -p firmware --bin firmware-qemu --features qemu,bench "${TARGET[@]}")" "$OUT/firmware-qemu-bench"
cp "$(built_exe -p firmware --bin firmware-stm32f405 --features stm32f405 "${TARGET[@]}")" "$OUT/firmware-stm32f405"

log "identifier-core alone: one object file, same target and optimisation, no LTO"
rm -rf "$OUT/core"
cargo rustc -q -p identifier-core --lib "${TARGET[@]}" --config 'profile.firmware.lto=false' \
    --target-dir "$OUT/core" -- --emit=obj
CORE_OBJ="$(find "$OUT/core" -name 'identifier_core-*.o' | head -n 1)"

log "gyro log (the e2e body, 20 s at 1 kHz, no bus errors)"
cargo run -q --release -p host-tests --bin gen-log -- \
    --out "$OUT/gyro.log" --reference "$OUT/reference.txt" >/dev/null

log "building the instruction-counting plugin"
gcc -O2 -shared -fPIC -Wall -Wextra -o "$OUT/libinsncount.so" firmware/bench/insn-count.c

log "counting instructions per identifier step (QEMU netduinoplus2 + TCG plugin)"
qemu-system-arm -machine netduinoplus2 -display none -monitor none -serial none \
    -semihosting-config "enable=on,target=native,arg=firmware-qemu,arg=$OUT/gyro.log" \
    -kernel "$OUT/firmware-qemu-bench" -plugin "$OUT/libinsncount.so" -d plugin \
    2>"$OUT/plugin.txt" >/dev/null
count="$(grep '^insn-count:' "$OUT/plugin.txt")"

log "stack painting run (flight image, no markers)"
scripts/firmware-qemu.sh "$OUT/firmware-qemu" "$OUT/gyro.log" >"$OUT/defmt.txt"
stack_line="$(grep 'stack:' "$OUT/defmt.txt")"

field() { sed -n "s/.* $1=\([0-9.]*\).*/\1/p" <<<"$count"; }
echo
echo "== Instructions per identifier step (Cortex-M4F, thumbv7em-none-eabihf, opt-level s, fat LTO)"
echo "   $count"
awk -v mean="$(field mean)" -v max="$(field max)" -v vd="$(field vdiv_max)" -v mhz="$CLOCK_MHZ" 'BEGIN {
    # Cortex-M4F timing (TRM): most instructions 1 cycle, VDIV.F32 14; loads, taken branches
    # and flash wait states (ART accelerator at 168 MHz) add about 20-40 %.
    lo = max + 13 * vd; hi = 1.4 * max + 13 * vd
    printf "   intervals are steps over 20 s of log; mean %.0f, worst %d instructions (%d VDIV.F32)\n", mean, max, vd
    printf "   cycles, worst step: %d (1 cycle per instruction + 13 per VDIV) to %d (x1.4 for loads, branches, wait states)\n", lo, hi
    printf "   at %d MHz (STM32F405): %.1f to %.1f us per step = %.2f to %.2f %% of the core at 1 kHz\n", mhz, lo / mhz, hi / mhz, lo / mhz / 10, hi / mhz / 10
}'
echo
echo "== Flash and RAM (llvm-size; flash = text + data, static RAM = data + bss)"
"$LLVM_BIN/llvm-size" "$OUT/firmware-stm32f405" "$OUT/firmware-qemu" | sed 's|target/firmware-bench/||; s/^/   /'
"$LLVM_BIN/llvm-size" "$CORE_OBJ" | sed "s|$CORE_OBJ|identifier-core (whole crate, one object)|; s/^/   /"
ident="$("$LLVM_BIN/llvm-nm" -C --size-sort -S -t d "$CORE_OBJ" |
    awk '$3 ~ /^[Tt]$/ && /identifier_core::(identifier|convergence|invariant|linalg|inertia|settings|status)::/ { s += $2 } END { print s + 0 }')"
echo "   identifier-core, the Identifier the firmware uses (identifier, convergence, invariant, linalg, inertia, settings, status): ${ident} bytes of code"
echo "   identifier-core RAM: no statics, no heap; its state lives in the firmware's SampleLoop on main's stack (size below)"
echo
echo "== Stack (painted under QEMU, flight image)"
echo "   ${stack_line#INFO  }"
