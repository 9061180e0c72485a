#!/usr/bin/env bash
# The Basilisk spacecraft logs with true rates (inertia/tests/data/spacecraft: sat6u-pyramid-10hz,
# peer-cubesat-1hz, leo-gg-1hz, mems-walk-10hz) through `inertia::identify::identify` with their
# vehicle files, a gyro made per seed from the true rates (white noise of the truth file's std;
# on mems-walk-10hz the fixture's kind of MEMS gyro: bias random walk, constant bias, white
# noise, truncated to its LSB): the tensor's errors, the calibration of its stated std, the
# statuses, derivative least squares (the peer's method family) on the same noisy logs, and
# on sat6u, peer and leo-gg the Cramer-Rao bound of the model the product fits (its windows
# (W1), one initial rate each) with the ratio of each entry's RMS error to it. The bound's
# dynamics are J w' = (J w + h) x w - h' + tau(J): tau = 0 on sat6u and peer; on leo-gg the
# gravity-gradient torque tau_B = 3 mu / |r|^5 (r_B x J r_B), r_B = R(q)^T r, from the clean
# log's attitude and position, its dependence on J in the sensitivities. On mems-walk the ratio
# is to the bound of its gyro with the error treated as Gaussian (C1), per axis and window
#   y_k - w_k(theta) = c + d_k + v_k,  d_k = d_{k-1} + s e_k,  d_first = 0,  v_k ~ N(0, r),
#   r = sigma^2 + LSB^2/12
# (c a free bias per window, d the walk with the truth's step s, its clamp ignored, v the white
# noise and the truncation left once the readings are at their counts' centres): information
# U^T Sigma^-1 U (C2), each sensitivity column whitened by a scalar Kalman filter per axis
# started diffuse (C3): the model the product fits where it finds the walk ((F12), (F13) of
# the tensor fit) (host-tests/src/bin/spacecraft-bench.rs).
# Figures: BENCHMARKS.md. A benchmark: it prints figures, it asserts nothing.
# Usage: scripts/bench-spacecraft.sh [SEEDS] [--fixture NAME]... [more spacecraft-bench options]
#        (default 100 seeds, every fixture)
set -euo pipefail
source "$(dirname "${BASH_SOURCE[0]}")/setup.sh"
cd "$ROOT"
seeds="${1:-100}"
shift || true
log "building spacecraft-bench (release)"
cargo build -q --release -p host-tests --bin spacecraft-bench
TARGET_DIR="${CARGO_TARGET_DIR:-$ROOT/target}"
"$TARGET_DIR/release/spacecraft-bench" --seeds "$seeds" "$@"
