#!/usr/bin/env bash
# The project's test command (README): all set-up, lint, builds and tests. CI runs this.
set -euo pipefail
source "$(dirname "${BASH_SOURCE[0]}")/setup.sh"
cd "$ROOT"

ensure_thumb_target

log "cargo fmt --check"
cargo fmt --all -- --check

log "cargo clippy -D warnings (host crates)"
cargo clippy --all-targets -- -D warnings

log "identifier-core for thumbv7em-none-eabihf"
cargo build -p identifier-core --release --target thumbv7em-none-eabihf
cargo clippy -p identifier-core --target thumbv7em-none-eabihf -- -D warnings

log "docs without warnings"
RUSTDOCFLAGS="-D warnings" cargo doc -p identifier-core --no-deps

log "host tests"
cargo test --release --workspace

# ---- reliability (robustness issue): no panic path on the MCU, faults under QEMU, fuzzing ----
# The proptest properties (host-tests/tests/robustness*.rs, readers_robustness.rs) already ran
# in `cargo test` above.
log "reliability: no panic path in identifier-core's thumbv7em release build"
scripts/check-no-panic.sh

log "reliability: fault injection on the MCU under QEMU (watchdog, re-initialisation, figure)"
checks/firmware-faults/run.sh

log "reliability: bounded fuzzing (30 s per target)"
scripts/fuzz.sh 30
# ---- end of reliability section ----
