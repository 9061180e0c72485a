#!/usr/bin/env bash
# The project's main job (README): the identifier running against a simulated spinning body.
set -euo pipefail
source "$(dirname "${BASH_SOURCE[0]}")/setup.sh"
cd "$ROOT"
cargo run --release -q -p host-tests --bin demo -- "$@"
