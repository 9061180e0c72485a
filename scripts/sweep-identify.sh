#!/usr/bin/env bash
# Out-of-sample check of `inertia identify` (a benchmark, not a test): torque-free bodies,
# rates (60 Hz to 8 kHz) and noise levels (5e-5 to 1e-2 rad/s) that the benchmark's scenarios
# do not use, written as `t,wx,wy,wz` CSV text and identified by the `inertia` binary exactly
# as a user runs it; per scenario the RMS error of `pooled.a` over the constrained Cramer-Rao
# bound, RMS(error / pooled.std_a) and the statuses (host-tests/src/bin/sweep-identify.rs).
# Usage: scripts/sweep-identify.sh [SEEDS] [more sweep-identify options]   (default 100 seeds)
set -euo pipefail
source "$(dirname "${BASH_SOURCE[0]}")/setup.sh"
cd "$ROOT"
seeds="${1:-100}"
shift || true
log "building inertia and sweep-identify (release)"
cargo build -q --release -p inertia -p host-tests --bin inertia --bin sweep-identify
TARGET_DIR="${CARGO_TARGET_DIR:-$ROOT/target}"
"$TARGET_DIR/release/sweep-identify" --seeds "$seeds" --inertia "$TARGET_DIR/release/inertia" "$@"
