#!/usr/bin/env bash
# The whole sample-loop iteration at a given ODR (default 8 kHz), instructions counted under
# QEMU by the TCG plugin of scripts/bench-firmware.sh (firmware/bench/insn-count.c), and the
# stack high-water of the flight image at that rate; flash/RAM of both images.
#
#   scripts/firmware-bench-rate.sh [RATE_HZ]     (8000 by default; 1000 is bench-firmware.sh's)
#
# The log is the e2e body's 20 s gyro log (gen-log, 1 kHz) with its header's rate set to
# RATE_HZ: the QEMU image then configures the simulated ICM-42688-P at that ODR, and the
# identifiers and the free-flight pipeline take their settings for that rate (the motion is
# the same samples, 8x slower in time at 8 kHz: the work per sample is what is measured).
set -euo pipefail
source "$(dirname "${BASH_SOURCE[0]}")/setup.sh"
cd "$ROOT"
RATE="${1:-8000}"
ensure_thumb_target
ensure_llvm_tools
ensure_qemu
ensure_defmt_print
ensure_gcc

OUT=target/firmware-bench-rate
mkdir -p "$OUT"
TARGET=(--target thumbv7em-none-eabihf --profile firmware)
CLOCK_MHZ=168
built_exe() {
    cargo build -q "$@" --message-format=json |
        sed -n 's/.*"executable":"\([^"]*\)".*/\1/p' | tail -n 1
}
log "building firmware images (qemu, qemu+bench, stm32f405)"
cp "$(built_exe -p firmware --bin firmware-qemu --features qemu "${TARGET[@]}")" "$OUT/firmware-qemu"
cp "$(built_exe -p firmware --bin firmware-qemu --features qemu,bench "${TARGET[@]}")" "$OUT/firmware-qemu-bench"
cp "$(built_exe -p firmware --bin firmware-stm32f405 --features stm32f405 "${TARGET[@]}")" "$OUT/firmware-stm32f405"
log "gyro log at $RATE Hz"
cargo run -q --release -p host-tests --bin gen-log -- \
    --out "$OUT/gyro-1k.log" --reference "$OUT/reference.txt" --reports "$OUT/reports.txt" >/dev/null
# Header: magic, version, f32 rate at offset 8 (little-endian), sample count.
python3 - "$OUT/gyro-1k.log" "$OUT/gyro.log" "$RATE" <<'PY'
import struct, sys
b = bytearray(open(sys.argv[1], "rb").read())
b[8:12] = struct.pack("<f", float(sys.argv[3]))
open(sys.argv[2], "wb").write(b)
PY
gcc -O2 -shared -fPIC -Wall -Wextra -o "$OUT/libinsncount.so" firmware/bench/insn-count.c
log "counting instructions per loop iteration at $RATE Hz"
qemu-system-arm -machine netduinoplus2 -display none -monitor none -serial none \
    -semihosting-config "enable=on,target=native,arg=firmware-qemu,arg=$OUT/gyro.log" \
    -kernel "$OUT/firmware-qemu-bench" -plugin "$OUT/libinsncount.so" -d plugin \
    2>"$OUT/plugin.txt" >"$OUT/bench-defmt.bin"
grep -q '^insn-count loop: intervals' "$OUT/plugin.txt" || { cat "$OUT/plugin.txt" >&2; exit 1; }
scripts/firmware-qemu.sh "$OUT/firmware-qemu" "$OUT/gyro.log" >"$OUT/defmt.txt"
field() { sed -n "s/^insn-count $1: .* $2=\([0-9.]*\).*/\1/p" "$OUT/plugin.txt"; }
echo
echo "== Sample loop at $RATE Hz ($(grep -o 'gyro .* at [A-Za-z0-9_]*' "$OUT/defmt.txt" | head -n 1))"
for ch in paper refined loop; do
    echo "   $ch: $(grep "^insn-count $ch:" "$OUT/plugin.txt" | sed 's/^insn-count [a-z]*: //')"
done
awk -v mean="$(field loop mean)" -v max="$(field loop max)" -v vm="$(field loop vdiv_mean)" \
    -v vd="$(field loop vdiv_max)" -v mhz="$CLOCK_MHZ" -v rate="$RATE" 'BEGIN {
    mlo = mean + 13 * vm; mhi = 1.4 * mean + 13 * vm
    printf "   whole loop iteration: mean %.0f, worst %d instructions; mean cycles %.0f to %.0f = %.1f to %.1f %% of a %d MHz core at %d Hz\n", mean, max, mlo, mhi, mlo * rate / (mhz * 1e4), mhi * rate / (mhz * 1e4), mhz, rate
}'
echo "   $(grep 'stack:' "$OUT/defmt.txt" | sed 's/^INFO  //')"
echo "== Flash and RAM (llvm-size)"
"$LLVM_BIN/llvm-size" "$OUT/firmware-stm32f405" "$OUT/firmware-qemu" | sed "s|$OUT/||; s/^/   /"
