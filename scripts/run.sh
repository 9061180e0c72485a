#!/usr/bin/env bash
# The project's main job (README): the flight firmware running under QEMU against a simulated
# spinning body, with its defmt stream decoded on the host and the estimates converging.
#
#   scripts/run.sh [gen-log options, e.g. --duration 30 --noise 2e-3 --seed 3 --bus-error-every 50]
#
# 1. installs what is missing (thumbv7em target, qemu-system-arm, defmt-print);
# 2. builds the firmware for the Cortex-M4F (thumbv7em-none-eabihf, profile `firmware`);
# 3. simulates the paper's body A = (0.6, 1.54, 1.0) from omega0 = (1, 1, 1) rad/s and writes
#    the gyro log (1 kHz, 1 mrad/s noise, 20 s by default);
# 4. runs the firmware in QEMU (netduinoplus2, an STM32F405): the simulated ICM-42688-P on
#    SPI answers the driver from the log, every sample goes through both identifiers of
#    identifier-core (the paper's and the refined one), and the 10 Hz reports come out over
#    defmt/semihosting, decoded by defmt-print; shown once per second here as a table of both
#    estimates and their convergence, all of them in target/firmware-run/defmt.txt.
set -euo pipefail
source "$(dirname "${BASH_SOURCE[0]}")/setup.sh"
cd "$ROOT"

OUT=target/firmware-run
# The ELF under the target directory cargo uses (CARGO_TARGET_DIR when set).
ELF="${CARGO_TARGET_DIR:-target}/thumbv7em-none-eabihf/firmware/firmware-qemu"
ensure_thumb_target
ensure_qemu
ensure_defmt_print

log "building the firmware (QEMU image)"
cargo build -q -p firmware --bin firmware-qemu --features qemu \
    --target thumbv7em-none-eabihf --profile firmware

log "simulating the spinning body and writing the gyro log"
mkdir -p "$OUT"
bus_every=0
args=("$@")
for i in "${!args[@]}"; do
    [ "${args[$i]}" = "--bus-error-every" ] && bus_every="${args[$((i + 1))]:-0}"
done
cargo run -q --release -p host-tests --bin gen-log -- \
    --out "$OUT/gyro.log" --reference "$OUT/reference.txt" "$@"

log "running the firmware under QEMU; decoded defmt stream (one report per second shown)"
set +e
scripts/firmware-qemu.sh "$ELF" "$OUT/gyro.log" "$bus_every" >"$OUT/defmt.txt"
rc=$?
set -e
grep -E ' gyro log |ERROR|WARN' "$OUT/defmt.txt" || true
# One line per second: t, each estimate with its convergence, the refined ratios.
awk '
    function vec(key,   s) {
        s = $0; sub(".*" key "=\\[", "", s); sub("\\].*", "", s); gsub(",", "", s); return s
    }
    function word_after(key,   s) {
        s = $0; sub(".*" key "=\\[[^]]*\\] ", "", s); sub(" .*", "", s); return s
    }
    function num(key,   s) { s = $0; sub(".*" key "=", "", s); sub(" .*", "", s); return s }
    BEGIN {
        printf "%7s  %-30s %-11s  %-30s %-11s %8s %8s\n", "t", "a_paper (Identifier)", "status", "a_refined (Refined)", "status", "A2/A1 (refined)", "A3/A1"
    }
    / t=[0-9]+\.0s / {
        t = $0; sub(".* t=", "", t); sub("s .*", "s", t)
        split(vec("a_paper"), p, " "); split(vec("a_refined"), r, " ")
        printf "%7s  [%8.5f %8.5f %8.5f]  %-11s  [%8.5f %8.5f %8.5f]  %-11s %8.5f %8.5f\n", t, p[1], p[2], p[3], word_after("a_paper"), r[1], r[2], r[3], word_after("a_refined"), num("A2/A1"), num("A3/A1")
    }' "$OUT/defmt.txt"
grep -E ' final |stack:' "$OUT/defmt.txt" || true
echo
echo "true a = ($(sed -n 's/^truth=//p' "$OUT/reference.txt")), A2/A1, A3/A1 = ($(sed -n 's/^truth_ratios=//p' "$OUT/reference.txt"))"
echo "host reference (same samples, same code on x86_64): a_paper $(sed -n 's/^a_paper=//p' "$OUT/reference.txt"), a_refined $(sed -n 's/^a_refined=//p' "$OUT/reference.txt")"
echo "firmware exit status: $rc (full stream: $OUT/defmt.txt)"
exit "$rc"
