#!/usr/bin/env bash
# Checks the inertia blackbox reader against a second, independent decoder (the Python
# `orangebox` package): the first N main frames' time, gyroADC[0..2], accSmooth[0..2] and
# erpm[0] must agree exactly, in the log's own counts.
#
# usage: scripts/check-blackbox-reader.sh [N] [LOG...]
#   N     frames per log (default 50; a number above the log's length compares all of it)
#   LOG   blackbox files (default: one device_only and one proof_body log of
#         ../shared/data/thrown-fc)
# Not part of scripts/test.sh: it installs orangebox from PyPI into a virtualenv under
# ${TMPDIR:-/tmp} the first time.
set -euo pipefail
cd "$(dirname "$0")/.."

N=${1:-50}
shift || true
DATA=../shared/data/thrown-fc
if [ "$#" -gt 0 ]; then
    LOGS=("$@")
else
    LOGS=("$DATA/device_only/LOG00119.BFL" "$DATA/proof_body/LOG00122.BFL")
fi
for i in "${!LOGS[@]}"; do
    [ -f "${LOGS[$i]}" ] || { echo "missing ${LOGS[$i]} (shared data absent?)" >&2; exit 2; }
    # Absolute: the dump runs with the inertia crate's folder as working directory.
    LOGS[$i]=$(realpath "${LOGS[$i]}")
done

VENV=${TMPDIR:-/tmp}/inertia-orangebox-venv
if ! "$VENV/bin/python" -c 'import orangebox' 2>/dev/null; then
    python3 -m venv "$VENV"
    # orangebox 0.5.0 declares a malformed console script, which makes pip report an error
    # after the package itself is installed: judge by the import below, not by pip's status.
    "$VENV/bin/pip" install -q orangebox || true
    "$VENV/bin/python" -c 'import orangebox' || { echo "orangebox did not install" >&2; exit 2; }
fi

export CARGO_TARGET_DIR=${CARGO_TARGET_DIR:-target}
cargo test -q --release -p inertia --test readers_dump --no-run

WORK=$(mktemp -d)
trap 'rm -rf "$WORK"' EXIT
fail=0
for log in "${LOGS[@]}"; do
    INERTIA_DUMP_LOG="$log" INERTIA_DUMP_FRAMES="$N" \
        cargo test -q --release -p inertia --test readers_dump -- --ignored --nocapture \
        >"$WORK/dump.txt" 2>&1 || { echo "FAIL $log: the inertia reader failed:"; tail -20 "$WORK/dump.txt"; fail=1; continue; }
    sed -n 's/^DUMP //p' "$WORK/dump.txt" >"$WORK/rust.txt"
    "$VENV/bin/python" - "$log" "$N" >"$WORK/orangebox.txt" <<'EOF'
import sys
import logging
logging.disable(logging.WARNING)
from orangebox import Parser
path, n = sys.argv[1], int(sys.argv[2])
p = Parser.load(path)
names = p.field_names
cols = [names.index(c) for c in ("time", "gyroADC[0]", "gyroADC[1]", "gyroADC[2]",
                                  "accSmooth[0]", "accSmooth[1]", "accSmooth[2]", "erpm[0]")]
out = 0
for f in p.frames():
    if f.type.name not in ("INTRA", "INTER"):
        continue
    print(" ".join(str(int(f.data[c])) for c in cols))
    out += 1
    if out >= n:
        break
EOF
    rows=$(wc -l <"$WORK/rust.txt")
    want=$(wc -l <"$WORK/orangebox.txt")
    if [ "$rows" -ne "$want" ] || [ "$rows" -eq 0 ]; then
        echo "FAIL $log: the inertia reader gave $rows frames, orangebox $want"
        fail=1
    elif diff -u "$WORK/orangebox.txt" "$WORK/rust.txt" >"$WORK/diff.txt"; then
        echo "ok   $log: first $rows main frames identical (time, gyroADC[0..2], accSmooth[0..2], erpm[0])"
    else
        echo "FAIL $log: frames differ (- orangebox, + inertia):"
        head -20 "$WORK/diff.txt"
        fail=1
    fi
done
exit $fail
