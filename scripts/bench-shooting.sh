#!/usr/bin/env bash
# The tensor fit with and without multiple shooting ((F11) of identifier-core's tensor_fit) on
# simulated thrown boards with what the torque-free model lacks (air drag on the body, the
# flywheel's drag, gyro vibration lines): error and calibration of both. A benchmark, not a
# test. Usage: scripts/bench-shooting.sh [SEEDS] (16 by default).
set -euo pipefail
source "$(dirname "${BASH_SOURCE[0]}")/setup.sh"
cd "$ROOT"
cargo run -q --release -p host-tests --bin shooting-bench -- "$@"
