#!/usr/bin/env bash
# The Basilisk spacecraft logs with true rates (inertia/tests/data/spacecraft: sat6u-pyramid-10hz,
# peer-cubesat-1hz) through `inertia::identify::identify` with their vehicle files, white gyro
# noise of the truth file's std added per seed: the tensor's errors against the Cramer-Rao bound
# of the model the product fits (its windows (W1), one initial rate each), the calibration of its
# stated std, the statuses, and derivative least squares (the peer's method family) on the same
# noisy logs (host-tests/src/bin/spacecraft-bench.rs). A benchmark: it prints figures, it
# asserts nothing.
# Usage: scripts/bench-spacecraft.sh [SEEDS] [more spacecraft-bench options]   (default 100 seeds)
set -euo pipefail
source "$(dirname "${BASH_SOURCE[0]}")/setup.sh"
cd "$ROOT"
seeds="${1:-100}"
shift || true
log "building spacecraft-bench (release)"
cargo build -q --release -p host-tests --bin spacecraft-bench
TARGET_DIR="${CARGO_TARGET_DIR:-$ROOT/target}"
"$TARGET_DIR/release/spacecraft-bench" --seeds "$seeds" "$@"
