#!/usr/bin/env bash
# Re-makes the spacecraft fixtures in inertia/tests/data/spacecraft/ with the Basilisk simulator
# (scripts/spacecraft/make_logs.py). Basilisk lives in a Python venv under target/bsk-venv, made
# here when missing; the test command never needs it, the fixtures are committed.
# Usage: scripts/make-spacecraft-logs.sh [SCENARIO...]   (default: every scenario)
set -euo pipefail
source "$(dirname "${BASH_SOURCE[0]}")/setup.sh"
cd "$ROOT"

venv="$ROOT/target/bsk-venv"
# The fixtures were made with this Basilisk; another version may differ in its conventions.
bsk_version="${BSK_VERSION:-2.12.1}"

if [ ! -x "$venv/bin/python" ]; then
    python="$(command -v python3.11 || command -v python3)"
    log "creating $venv with $("$python" --version)"
    "$python" -m venv "$venv"
fi
log "installing bsk==$bsk_version and numpy into $venv"
"$venv/bin/pip" install --quiet --disable-pip-version-check "bsk==$bsk_version" numpy
log "making the spacecraft logs"
"$venv/bin/python" "$ROOT/scripts/spacecraft/make_logs.py" "$@"
