#!/usr/bin/env bash
# Accuracy and cost of the on-board identifiers and their peers, one command:
#   1. instructions per step of the paper identifier, the refined identifier and an f32 EKF on
#      the Cortex-M4F (bench-mcu under QEMU netduinoplus2 (STM32F405) with -icount) -> docs/bench/instructions.csv
#   2. all methods on the same Monte Carlo seeds, Cramer-Rao bounds, host ns/sample, racquet
#      spread -> stdout, BENCHMARKS.md, docs/bench/*.svg
# Options are passed to bench-estimators: --quick (8 seeds, writes nothing), --seeds N,
# --scenario NAME, --no-write, --no-racquet. With --quick the QEMU step is skipped.
set -euo pipefail
source "$(dirname "${BASH_SOURCE[0]}")/setup.sh"
cd "$ROOT"

quick=0
for a in "$@"; do [ "$a" = "--quick" ] && quick=1; done

if [ "$quick" = 0 ]; then
    ensure_thumb_target
    ensure_qemu
    log "bench-mcu: instructions per step on the Cortex-M4F (QEMU, -icount shift=0)"
    cargo build -q -p bench-mcu --release --target thumbv7em-none-eabihf --features mcu
    mkdir -p docs/bench
    out="$(timeout 600 qemu-system-arm -machine netduinoplus2 -nographic \
        -monitor none -serial none -semihosting-config enable=on,target=native \
        -icount shift=0,align=off,sleep=off \
        -kernel target/thumbv7em-none-eabihf/release/bench-mcu)"
    printf '%s\n' "$out" >&2
    printf '%s\n' "$out" | grep -v '^#' > docs/bench/instructions.csv
fi

log "bench-estimators $*"
cargo run -q --release -p host-tests --bin bench-estimators -- "$@"
