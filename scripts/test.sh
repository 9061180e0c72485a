#!/usr/bin/env bash
# The project's test command (README): all set-up, lint, builds and tests. CI runs this.
set -euo pipefail
source "$(dirname "${BASH_SOURCE[0]}")/setup.sh"
cd "$ROOT"

ensure_thumb_target

log "cargo fmt --check"
cargo fmt --all -- --check

log "relative links and anchors in README.md, CHANGELOG.md, docs/*.md"
scripts/check-links.sh

log "cargo clippy -D warnings (host crates)"
cargo clippy --all-targets -- -D warnings
scripts/check-msrv.sh

log "identifier-core for thumbv7em-none-eabihf"
cargo build -p identifier-core --release --target thumbv7em-none-eabihf
cargo clippy -p identifier-core --target thumbv7em-none-eabihf -- -D warnings

log "docs without warnings"
RUSTDOCFLAGS="-D warnings" cargo doc -p identifier-core -p inertia -p host-tests --no-deps

log "host tests"
cargo test --release --workspace

log "doctests of identifier-core; its host example on a generated CSV"
cargo test --release --doc -p identifier-core
scripts/example-csv.sh

# ---- reliability (robustness issue): no panic path on the MCU, faults under QEMU, fuzzing ----
# The proptest properties (host-tests/tests/robustness*.rs, inertia/tests/readers_robustness.rs)
# already ran in `cargo test` above.
log "reliability: no panic path in identifier-core's thumbv7em release build"
scripts/check-no-panic.sh

log "reliability: fault injection on the MCU under QEMU (watchdog, re-initialisation, figure)"
checks/firmware-faults/run.sh

# A smoke run; the long runs are `scripts/fuzz.sh 600` (docs/validation.md, reliability).
log "reliability: bounded fuzzing (10 s per target)"
scripts/fuzz.sh 10
# ---- end of reliability section ----

# ---- firmware section (icm42688 driver, firmware crate, QEMU end to end) --------------------
# The driver and the firmware library are host-built and tested above (icm42688 is a default
# member; `cargo test --workspace` runs firmware's library tests). Here: the thumbv7em builds
# of both firmware images, clippy on them, and the QEMU end-to-end check.
ensure_qemu
ensure_defmt_print

log "icm42688 for thumbv7em-none-eabihf (no_std), clippy -D warnings"
cargo build -p icm42688p-driver --features sim,defmt --target thumbv7em-none-eabihf
cargo clippy -p icm42688p-driver --features sim,defmt --target thumbv7em-none-eabihf -- -D warnings

for features in qemu stm32f405; do
    log "firmware ($features) for thumbv7em-none-eabihf, clippy -D warnings"
    cargo build -p firmware --bins --features "$features" --target thumbv7em-none-eabihf --profile firmware
    cargo clippy -p firmware --bins --features "$features" --target thumbv7em-none-eabihf --profile firmware -- -D warnings
done
cargo clippy -p firmware --all-targets -- -D warnings

# The board examples are standalone crates (excluded from the workspace, own lock files).
for ex in embassy-stm32f405 rtic-stm32f405; do
    log "examples/$ex for thumbv7em-none-eabihf, fmt, clippy -D warnings"
    ex_args=(--manifest-path "examples/$ex/Cargo.toml" --release --target thumbv7em-none-eabihf
        --target-dir "${CARGO_TARGET_DIR:-$ROOT/target}/examples")
    cargo fmt --manifest-path "examples/$ex/Cargo.toml" -- --check
    cargo build "${ex_args[@]}"
    cargo clippy "${ex_args[@]}" -- -D warnings
done

log "docs of the driver and the firmware library without warnings"
RUSTDOCFLAGS="-D warnings" cargo doc -p icm42688p-driver -p firmware --no-deps --features icm42688p-driver/sim

log "firmware end to end under QEMU (simulated body -> gyro log -> firmware -> defmt -> checks)"
scripts/firmware-e2e.sh

log "logs replayed through the firmware under QEMU: on-board == inertia identify pooled (bit for bit), UART telemetry == defmt"
scripts/replay-check.sh --quick

log "fits off the sample path under QEMU: 8 kHz throw and 10 Hz satellite paced by SysTick, no sample dropped"
scripts/firmware-paced.sh --quick
# ---- end of firmware section ----

# ---- benchmarks, quick mode: every estimator and the Cramer-Rao bound on 8 seeds -------------
# The figures in BENCHMARKS.md come from the full run (scripts/bench-estimators.sh); this
# checks that the benchmark itself runs end to end and prints its table.
log "estimator benchmark, quick mode"
scripts/bench-estimators.sh --quick
