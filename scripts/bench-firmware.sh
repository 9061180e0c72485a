#!/usr/bin/env bash
# Firmware figures (a benchmark, not a test): instructions per step of the paper's identifier,
# per step of the refined identifier and per sample-loop iteration on the Cortex-M4F build
# under QEMU with an instruction-counting TCG plugin, and cycles estimated at 168 MHz; flash and RAM of the firmware images and of identifier-core alone (llvm-size);
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

log "checking the bench image's markers (firmware/src/bench.rs)"
"$LLVM_BIN/llvm-objdump" -d "$OUT/firmware-qemu-bench" >"$OUT/firmware-qemu-bench.dis"
for m in "r9, r9" "r10, r10" "r11, r11" "r12, r12" "r8, r8" "lr, lr"; do
    # Each marker: once in bench::calibrate, once or more (one per return path) in the loop.
    k="$(grep -cE "[[:space:]]mov[[:space:]]+$m\$" "$OUT/firmware-qemu-bench.dis" || true)"
    [ "$k" -ge 2 ] || { echo "marker mov $m found $k times in the bench image" >&2; exit 1; }
done

log "counting instructions per step and per loop iteration (QEMU netduinoplus2 + TCG plugin)"
qemu-system-arm -machine netduinoplus2 -display none -monitor none -serial none \
    -semihosting-config "enable=on,target=native,arg=firmware-qemu,arg=$OUT/gyro.log" \
    -kernel "$OUT/firmware-qemu-bench" -plugin "$OUT/libinsncount.so" -d plugin \
    2>"$OUT/plugin.txt" >/dev/null
grep -q '^insn-count paper: intervals' "$OUT/plugin.txt" || { cat "$OUT/plugin.txt" >&2; exit 1; }

log "stack painting run (flight image, no markers)"
scripts/firmware-qemu.sh "$OUT/firmware-qemu" "$OUT/gyro.log" >"$OUT/defmt.txt"
stack_line="$(grep 'stack:' "$OUT/defmt.txt")"

field() { sed -n "s/^insn-count $1: .* $2=\([0-9.]*\).*/\1/p" "$OUT/plugin.txt"; }
figures() { # channel title
    echo "   $2: $(grep "^insn-count $1:" "$OUT/plugin.txt" | sed 's/^insn-count [a-z]*: //')"
    awk -v mean="$(field "$1" mean)" -v max="$(field "$1" max)" -v vm="$(field "$1" vdiv_mean)" \
        -v vd="$(field "$1" vdiv_max)" -v mhz="$CLOCK_MHZ" 'BEGIN {
        # Cortex-M4F timing (TRM): most instructions 1 cycle, VDIV.F32 14; loads, taken
        # branches and flash wait states (ART accelerator at 168 MHz) add about 20-40 %.
        # Bounds for the worst interval (its count and the most VDIVs of any interval).
        lo = max + 13 * vd; hi = 1.4 * max + 13 * vd
        mlo = mean + 13 * vm; mhi = 1.4 * mean + 13 * vm
        printf "     mean %.0f, worst %d instructions (%d VDIV.F32 at most)\n", mean, max, vd
        printf "     cycles, mean: %.0f to %.0f = %.2f to %.2f %% of the core at 1 kHz\n", mlo, mhi, mlo / mhz / 10, mhi / mhz / 10
        printf "     cycles, worst: %d to %d = %.1f to %.1f us at %d MHz\n", lo, hi, lo / mhz, hi / mhz, mhz
    }'
}
echo
echo "== Instructions (Cortex-M4F, thumbv7em-none-eabihf, opt-level s, fat LTO; 20 s of log at 1 kHz)"
echo "   cycles: 1 per instruction + 13 per VDIV.F32, to x1.4 for loads, taken branches, wait states"
figures paper "paper's identifier, one step (Identifier::step)"
figures refined "refined identifier, one step (Refined::step; a 2x2 solve per axis every 32nd)"
figures loop "whole sample-loop iteration (SampleLoop::poll that stepped: data-ready poll, SPI read, both steps, counters, the 10 Hz report's values)"
echo "     (under QEMU the loop also runs the simulated ICM-42688-P's SPI side and its log reads,"
echo "      64 samples per semihosting call: code that is not on the board, so these loop figures are"
echo "      upper bounds for the MCU's own work; the report's defmt output is outside the interval)"
echo
echo "== Flash and RAM (llvm-size; flash = text + data, static RAM = data + bss)"
"$LLVM_BIN/llvm-size" "$OUT/firmware-stm32f405" "$OUT/firmware-qemu" | sed 's|target/firmware-bench/||; s/^/   /'
"$LLVM_BIN/llvm-size" "$CORE_OBJ" | sed "s|$CORE_OBJ|identifier-core (whole crate, one object)|; s/^/   /"
ident="$("$LLVM_BIN/llvm-nm" -C --size-sort -S -t d "$CORE_OBJ" |
    awk '$3 ~ /^[Tt]$/ && /identifier_core::(identifier|convergence|invariant|linalg|inertia|settings|status)::/ { s += $2 } END { print s + 0 }')"
echo "   identifier-core, the Identifier the firmware uses (identifier, convergence, invariant, linalg, inertia, settings, status): ${ident} bytes of code"
refined="$("$LLVM_BIN/llvm-nm" -C --size-sort -S -t d "$CORE_OBJ" |
    awk '$3 ~ /^[Tt]$/ && /identifier_core::refined::/ { s += $2 } END { print s + 0 }')"
echo "   identifier-core, the Refined beside it (refined; it shares convergence, invariant, status): ${refined} bytes of code"
echo "   identifier-core RAM: no statics, no heap; both identifiers' state lives in the firmware's SampleLoop on main's stack (sizes below)"
echo
echo "== Stack (painted under QEMU, flight image)"
echo "   ${stack_line#INFO  }"

# The tensor estimator, the flight pipeline, the ratio fit and the tensor fit (bench-mcu, the same
# SysTick/-icount method as scripts/bench-estimators.sh; flight profile: opt-level s, fat LTO).
# The rows starting "tensor" include tensor-fit-step and tensor-fit-close-throw; the "# check"
# and "# ratio-fit"/"# tensor-fit" lines are the fits' on-target checks and times at 168 MHz.
log "bench-mcu (flight profile): TensorEstimator::step, FlightPipeline::step, estimate(), FlightRatioFit step and close, sizes"
TD="${CARGO_TARGET_DIR:-target}"
cargo build -q -p bench-mcu --profile firmware --target thumbv7em-none-eabihf --features mcu
mcu="$(timeout 600 qemu-system-arm -machine netduinoplus2 -nographic -monitor none -serial none \
    -semihosting-config enable=on,target=native -icount shift=0,align=off,sleep=off \
    -kernel "$TD/thumbv7em-none-eabihf/firmware/bench-mcu")"
echo
echo "== Tensor estimator, flight pipeline, ratio fit (instructions per call, mean over 4000 samples and worst single call; a close is one call per free flight)"
printf '%s\n' "$mcu" | grep -E '^(tensor|pipeline|profile|ratio-fit)' | awk -F, -v mhz="$CLOCK_MHZ" '{
    printf "   %-28s %8s  %s\n", $1, $2, $3
}'
printf '%s\n' "$mcu" | grep -E '^# (sizes|check|ratio-fit|tensor-fit)' | sed 's/^# /   /'
mean8="$(printf '%s\n' "$mcu" | sed -n 's/^pipeline-8khz,\([0-9]*\),.*/\1/p')"
[ -n "$mean8" ] && awk -v m="$mean8" -v mhz="$CLOCK_MHZ" 'BEGIN {
    printf "   pipeline at 8 kHz: %d instructions/sample = %.1f to %.1f %% of a %d MHz core (x1 to x1.4 cycles per instruction); issue 9 target: 400 (2 %%)\n", m, m * 8000 / (mhz * 1e4), 1.4 * m * 8000 / (mhz * 1e4), mhz
}'
