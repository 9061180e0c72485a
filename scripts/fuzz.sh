#!/usr/bin/env bash
# Bounded fuzzing with cargo-fuzz (libFuzzer): scripts/fuzz.sh [SECONDS] [TARGET...]
#
# Runs each target (default: every target in fuzz/) for SECONDS (default 30) on one core and
# prints the number of executions. Fails if a target finds a crash or an invariant violation;
# the input is kept under fuzz/artifacts/TARGET/ and can be replayed with
#   RUSTC_BOOTSTRAP=1 cargo fuzz run TARGET fuzz/artifacts/TARGET/<file>   (from fuzz/)
#
# cargo-fuzz needs nightly-only flags (-Z sanitizer=address, ...); on this stable toolchain
# RUSTC_BOOTSTRAP=1 unlocks them. The fuzz crate has its own workspace and its own target
# directory (fuzz/target), so it never touches the root build.
set -euo pipefail
source "$(dirname "${BASH_SOURCE[0]}")/setup.sh"

SECONDS_PER_TARGET="${1:-30}"
shift || true

if ! command -v cargo-fuzz >/dev/null; then
    log "installing cargo-fuzz (cargo install, about a minute)"
    cargo install cargo-fuzz --locked
fi

cd "$ROOT/fuzz"
export RUSTC_BOOTSTRAP=1

TARGETS=("$@")
if [ "${#TARGETS[@]}" -eq 0 ]; then
    mapfile -t TARGETS < <(cargo fuzz list)
fi

log "building fuzz targets: ${TARGETS[*]}"
for t in "${TARGETS[@]}"; do
    cargo fuzz build "$t" 2>&1 | tail -n 2
done

total=0
for t in "${TARGETS[@]}"; do
    mkdir -p "corpus/$t" "artifacts/$t"
    # Seed inputs shipped with the repository, if any, join the (ignored) working corpus.
    if [ -d "seeds/$t" ]; then cp -n "seeds/$t"/* "corpus/$t"/ 2>/dev/null || true; fi
    out="$(mktemp)"
    log "fuzzing $t for ${SECONDS_PER_TARGET}s"
    set +e
    cargo fuzz run "$t" "corpus/$t" -- \
        -max_total_time="$SECONDS_PER_TARGET" -max_len=4096 -rss_limit_mb=2048 \
        -print_final_stats=1 -artifact_prefix="artifacts/$t/" >"$out" 2>&1
    rc=$?
    set -e
    runs="$(sed -n 's/^Done \([0-9]*\) runs in \([0-9]*\) second.*/\1/p' "$out" | tail -n 1)"
    secs="$(sed -n 's/^Done \([0-9]*\) runs in \([0-9]*\) second.*/\2/p' "$out" | tail -n 1)"
    cov="$(grep -o 'cov: [0-9]*' "$out" | tail -n 1 || true)"
    if [ "$rc" -ne 0 ] || [ -z "$runs" ]; then
        grep -m 1 -A 3 "panicked at" "$out" >&2 || true
        grep -E "^(Error|SUMMARY|artifact_prefix)" "$out" >&2 || tail -n 30 "$out" >&2
        rm -f "$out"
        echo "fuzz: $t FAILED (exit $rc); see fuzz/artifacts/$t/" >&2
        exit 1
    fi
    rm -f "$out"
    total=$((total + runs))
    echo "fuzz: $t: $runs executions in ${secs}s, ${cov:-cov: ?}, corpus $(ls "corpus/$t" | wc -l) inputs, no crash"
done
echo "fuzz: all targets: $total executions, no crash"
