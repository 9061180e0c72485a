#!/usr/bin/env bash
# Accuracy and cost of the on-board identifiers and their peers, one command:
#   1. instructions per step of the paper identifier, the refined identifier, two f32 EKFs, the
#      tensor estimator, the flight pipeline and the ratio fit (and per close() of the ratio fit,
#      the fit of one free flight, after its result was checked) on the Cortex-M4F, release and
#      flight (opt-level s, fat LTO) builds: bench-mcu under QEMU netduinoplus2 (STM32F405) with
#      -icount -> docs/bench/instructions.csv
#   2. all methods on the same Monte Carlo seeds, Cramer-Rao bounds, host ns/sample, racquet
#      spread -> stdout, BENCHMARKS.md, docs/bench/*.svg
# Options are passed to bench-estimators: --quick (8 seeds, writes nothing, prints no goal
# verdicts: those belong to the full run), --seeds N,
# --scenario NAME, --no-write, --no-racquet. With --quick the QEMU step is skipped.
set -euo pipefail
source "$(dirname "${BASH_SOURCE[0]}")/setup.sh"
cd "$ROOT"

quick=0
for a in "$@"; do [ "$a" = "--quick" ] && quick=1; done

if [ "$quick" = 0 ]; then
    ensure_thumb_target
    ensure_qemu
    mkdir -p docs/bench
    run_mcu() {
        timeout 600 qemu-system-arm -machine netduinoplus2 -nographic \
            -monitor none -serial none -semihosting-config enable=on,target=native \
            -icount shift=0,align=off,sleep=off -kernel "$1"
    }
    # Two builds: release (opt-level 3) and the firmware's flight profile (opt-level s, fat LTO).
    log "bench-mcu: instructions per step on the Cortex-M4F (QEMU netduinoplus2, -icount shift=0), release"
    TD="${CARGO_TARGET_DIR:-target}"
    cargo build -q -p bench-mcu --release --target thumbv7em-none-eabihf --features mcu
    rel="$(run_mcu "$TD/thumbv7em-none-eabihf/release/bench-mcu")"
    printf '%s\n' "$rel" >&2
    log "bench-mcu: the same with the firmware profile (opt-level s, fat LTO)"
    cargo build -q -p bench-mcu --profile firmware --target thumbv7em-none-eabihf --features mcu
    fl="$(run_mcu "$TD/thumbv7em-none-eabihf/firmware/bench-mcu")"
    printf '%s\n' "$fl" >&2
    {
        printf '%s\n' "$rel" | grep -v '^#'
        printf '%s\n' "$fl" | grep -v '^#' | grep -v '^method,' | sed 's/^\([a-z0-9-]*\),/\1@flight,/'
    } > docs/bench/instructions.csv
fi

log "bench-estimators $*"
cargo run -q --release -p host-tests --bin bench-estimators -- "$@"
