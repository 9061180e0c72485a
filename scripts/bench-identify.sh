#!/usr/bin/env bash
# Issue 9's long-log figure (a benchmark, not a test): a 10-minute 8 kHz log (4.8 M rows of
# t,wx,wy,wz,ax,ay,az,rotor_rad_s) through `inertia identify`, wall time and peak memory.
#
# The log is made of simulated board throws (host-tests' gen-throw, scenario board_throw, 8 kHz,
# one seed per throw, about 2.7 s each: still, hand, free flight with the flywheel spin-up,
# catch, held) laid end to end until 600 s are filled. It goes to a temporary directory that
# is removed at the end (KEEP=1 keeps it; LOG=FILE reuses a log made before instead of making
# one). Usage: scripts/bench-identify.sh [MINUTES]
#
# `inertia identify` reads the log sample by sample (a first reading for the rate, noise and
# rotor steps, then the pipeline's), so its peak memory does not grow with the log; its time
# is mostly identifier-core's fits, spread over the cores (the per-throw pipelines run beside
# the pooled one).
set -euo pipefail
source "$(dirname "${BASH_SOURCE[0]}")/setup.sh"
cd "$ROOT"

minutes="${1:-10}"
rate=8000
TMP="$(mktemp -d)"
[ "${KEEP:-0}" = 1 ] || trap 'rm -rf "$TMP"' EXIT
TARGET_DIR="${CARGO_TARGET_DIR:-$ROOT/target}"

log "building inertia and gen-throw (release)"
cargo build -q --release -p inertia -p host-tests --bin inertia --bin gen-throw

need=$((minutes * 60 * rate))
log_csv="$TMP/long.csv"
generate() {
    log "generating ${minutes} min at ${rate} Hz in $TMP"
    rows=0
    seed=1
    : >"$TMP/parts"
    while [ "$rows" -lt "$need" ]; do
        "$TARGET_DIR/release/gen-throw" --scenario board_throw --seed "$seed" --rate "$rate" \
            --out "$TMP/throw-$seed.csv" >/dev/null
        k=$(($(wc -l <"$TMP/throw-$seed.csv") - 1))
        rows=$((rows + k))
        echo "$TMP/throw-$seed.csv" >>"$TMP/parts"
        seed=$((seed + 1))
    done
    # End to end: each throw's time shifted to follow the previous one by one sample period;
    # the last throw cut at exactly `need` rows.
    awk -v need="$need" -v dt="$(echo "1 / $rate" | bc -l)" -F, '
        FNR == 1 { if (NR == 1) print; off = next_off; next }
        {
            if (count >= need) exit
            t = $1 + off
            $1 = sprintf("%.7f", t)
            print
            next_off = t + dt
            count++
        }' OFS=, $(cat "$TMP/parts") >"$log_csv"
    rm -f "$TMP"/throw-*.csv
    echo "log: $(($(wc -l <"$log_csv") - 1)) rows, $(du -h "$log_csv" | cut -f1), $((seed - 1)) throws"
}
if [ -n "${LOG:-}" ]; then
    log_csv="$LOG"
    echo "log: $(($(wc -l <"$log_csv") - 1)) rows, $(du -h "$log_csv" | cut -f1) (given)"
else
    generate
fi

log "inertia identify (wall time, peak memory: /usr/bin/time -v)"
/usr/bin/time -v "$TARGET_DIR/release/inertia" identify --input "$log_csv" \
    --rotor-inertia 1.69e-6 --rotor-axis -z --json "$TMP/out.json" \
    >"$TMP/stdout.txt" 2>"$TMP/time.txt" || {
    echo "inertia identify failed:" >&2
    cat "$TMP/time.txt" "$TMP/stdout.txt" >&2
    exit 1
}
wall="$(sed -n 's/.*Elapsed (wall clock) time (h:mm:ss or m:ss): //p' "$TMP/time.txt")"
rss="$(sed -n 's/.*Maximum resident set size (kbytes): //p' "$TMP/time.txt")"
user="$(sed -n 's/.*User time (seconds): //p' "$TMP/time.txt")"
sys="$(sed -n 's/.*System time (seconds): //p' "$TMP/time.txt")"
cpu="$(sed -n 's/.*Percent of CPU this job got: //p' "$TMP/time.txt")"
echo
echo "== inertia identify on ${minutes} min of ${rate} Hz (${need} rows, accelerometer and rotor speed)"
echo "   wall ${wall}, user ${user} s, system ${sys} s (${cpu} of a core, $(nproc) cores: on a shared"
echo "   machine the wall time includes waiting for the cores; user + system is the work),"
echo "   peak RSS $((rss / 1024)) MiB"
if command -v python3 >/dev/null; then
    python3 - "$TMP/out.json" <<'PY'
import json, sys
r = json.load(open(sys.argv[1]))
th = r.get("throws", [])
p = r.get("pooled", {})
print(f"   throws found: {len(th)}; pooled status {p.get('status')}, a = {p.get('a')}")
t = p.get("tensor_kg_m2")
if t:
    print("   pooled tensor (kg m^2): " + "; ".join(", ".join(f"{v:.4e}" for v in row) for row in t))
PY
fi
