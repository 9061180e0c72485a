#!/usr/bin/env bash
# The project's main job (README): the flight firmware running under QEMU, with its defmt
# stream decoded on the host.
#
#   scripts/run.sh [gen-log options, e.g. --duration 30 --noise 2e-3 --seed 3 --bus-error-every 50] [--json OUT.json]
#   scripts/run.sh --log FILE [--rotor-inertia KG_M2 --rotor-axis x|y|z|-x|-y|-z [--rotor-poles N] [--rotor-raw | --rotor-unhold]
#                  | --vehicle FILE.toml]
#                  [--noise-std RAD_S] [--gyro-unit rad/s|deg/s] [--time-unit s|ms|us] [--json OUT.json]
#                  [--refit-every N | --refit-every-s S] [--lossless]
#   scripts/run.sh --replay FILE.irpl [--refit-every N | --refit-every-s S] [--lossless] [--json OUT.json]
#   scripts/run.sh --help
#
# Without --log (a simulated spinning body):
# 1. installs what is missing (thumbv7em target, qemu-system-arm, defmt-print);
# 2. builds the firmware for the Cortex-M4F (thumbv7em-none-eabihf, profile `firmware`);
# 3. simulates the paper's body A = (0.6, 1.54, 1.0) from omega0 = (1, 1, 1) rad/s and writes
#    the gyro log (1 kHz, 1 mrad/s noise, 20 s by default);
# 4. runs the firmware in QEMU (netduinoplus2, an STM32F405): the simulated ICM-42688-P on
#    SPI answers the driver from the log, every sample goes through both identifiers of
#    identifier-core (the paper's and the refined one) and the free-flight pipeline, and the
#    10 Hz reports come out over defmt/semihosting, decoded by defmt-print; shown once per
#    second here as a table of both estimates and their convergence, all of them in
#    target/firmware-run/defmt.txt. The same reports go out as telemetry frames on USART1,
#    captured in target/firmware-run/uart.bin.
#
# With --log FILE (any log `inertia identify` reads: blackbox, ULog, phyphox, CSV):
# `inertia export-replay` writes the per-sample f32 inputs `inertia identify` gives its
# FlightPipeline (rate, specific force, rotor speed, dt, at the log's own rate; on an orbit log
# with a known rotor momentum also each sample's time, attitude and position) and the
# pipeline's settings; the QEMU firmware (`--replay`) feeds them to its sample loop's
# FlightPipeline and both identifiers, reporting at 10 Hz of log time. An orbit log is replayed
# in identify's passes with the gravity-gradient torque folded in (one after another; the
# defmt lines `pass N ...`), and the final estimate is the pass identify reports. The driver and the
# simulated part are not in this path (their 16-bit counts cannot carry a log's f32 values
# unchanged). The final on-board estimate (status, a, std_a, tensor_kg_m2 or null,
# throws_detected, the counters) is decoded from the UART capture and written to --json;
# scripts/replay-check.sh compares it with `inertia identify`'s pooled result bit for bit.
# The samples come at the log's own rate from a timer interrupt (SysTick, QEMU run with
# `-icount $ICOUNT`, deterministic virtual time; default shift=3,sleep=off: 8 ns per
# instruction) into a ring, a lower-priority interrupt steps the loop, and the fits run in
# thread mode (docs/firmware.md, "Fits off the sample path"). --refit-every N: continuous
# mode's re-fit every N samples fed, or every S seconds of them at the log's rate
# (docs/firmware.md, "Continuous mode"). --lossless: a
# sample that finds the ring full waits for the next tick instead of being lost (a file can
# wait, a sensor cannot; scripts/replay-check.sh uses it for the bit-for-bit comparison).
# --replay FILE.irpl runs a replay file written elsewhere (`inertia export-replay`,
# `host-tests gen-satellite`).
#
# Options take `--opt value` or `--opt=value`. Anything a run cannot honour is refused before
# anything is built or run.
set -euo pipefail

usage() { sed -n '2,/^set -euo/p' "${BASH_SOURCE[0]}" | sed '$d; s/^# \{0,1\}//'; }

die() { echo "run.sh: $*" >&2; echo "run.sh: see scripts/run.sh --help" >&2; exit 2; }

log_file="" vehicle="" replay_file="" refit_every="" refit_every_s="" lossless="" json="" rotor_inertia="" rotor_axis="" rotor_poles="" rotor_hold="" noise_std=""
gyro_unit="" time_unit=""
gen_args=()
bus_every=0
# Split --opt=value, then parse.
norm=()
for a in "$@"; do
    case "$a" in
        --*=*) norm+=("${a%%=*}" "${a#*=}") ;;
        *) norm+=("$a") ;;
    esac
done
set -- ${norm[@]+"${norm[@]}"}
need() { [ $# -ge 2 ] && [ -n "$2" ] || die "$1 needs a value"; }
while [ $# -gt 0 ]; do
    case "$1" in
        -h | --help) usage; exit 0 ;;
        --log) need "$@"; log_file="$2"; shift 2 ;;
        --replay) need "$@"; replay_file="$2"; shift 2 ;;
        --vehicle) need "$@"; vehicle="$2"; shift 2 ;;
        --refit-every) need "$@"; refit_every="$2"; shift 2 ;;
        --refit-every-s) need "$@"; refit_every_s="$2"; shift 2 ;;
        --lossless) lossless=1; shift ;;
        --json) need "$@"; json="$2"; shift 2 ;;
        --rotor-inertia) need "$@"; rotor_inertia="$2"; shift 2 ;;
        --rotor-axis) need "$@"; rotor_axis="$2"; shift 2 ;;
        --rotor-poles) need "$@"; rotor_poles="$2"; shift 2 ;;
        --rotor-raw|--rotor-unhold) rotor_hold="$1"; shift ;;
        --noise-std) need "$@"; noise_std="$2"; shift 2 ;;
        --gyro-unit) need "$@"; gyro_unit="$2"; shift 2 ;;
        --time-unit) need "$@"; time_unit="$2"; shift 2 ;;
        --bus-error-every) need "$@"; bus_every="$2"; gen_args+=("$1" "$2"); shift 2 ;;
        --duration | --noise | --seed) need "$@"; gen_args+=("$1" "$2"); shift 2 ;;
        *) die "unknown option $1" ;;
    esac
done

# Refuse what cannot be honoured, before anything runs.
if [ -n "$replay_file" ]; then
    [ -z "$log_file" ] || die "--replay and --log exclude each other"
    [ -f "$replay_file" ] && [ -r "$replay_file" ] || die "--replay $replay_file: no such readable file"
fi
if [ -n "$refit_every_s" ]; then
    [ -z "$refit_every" ] || die "--refit-every and --refit-every-s exclude each other"
    [ -n "$log_file$replay_file" ] || die "--refit-every-s applies to a replayed log: give --log or --replay"
    [[ "$refit_every_s" =~ ^[0-9]+\.?[0-9]*$ ]] || die "--refit-every-s $refit_every_s: not a positive number of seconds"
fi
if [ -n "$refit_every" ]; then
    [ -n "$log_file$replay_file" ] || die "--refit-every applies to a replayed log: give --log or --replay"
    [[ "$refit_every" =~ ^[0-9]+$ ]] || die "--refit-every $refit_every: not a whole number of samples"
fi
is_num() { [[ "$1" =~ ^[+]?([0-9]+\.?[0-9]*|\.[0-9]+)([eE][-+]?[0-9]+)?$ ]]; }
if [ -z "$log_file" ] && [ -z "$replay_file" ]; then
    for o in rotor_inertia rotor_axis rotor_poles noise_std gyro_unit time_unit vehicle; do
        [ -z "${!o}" ] || die "--${o//_/-} applies to a replayed log: give --log FILE"
    done
    [ -z "$rotor_hold" ] || die "$rotor_hold applies to a replayed log: give --log FILE"
else
    [ ${#gen_args[@]} -eq 0 ] || die "${gen_args[0]} applies to the simulated run, not to --log"
    [ -n "$replay_file" ] || { [ -f "$log_file" ] && [ -r "$log_file" ]; } || die "--log $log_file: no such readable file"
    if [ -n "$vehicle" ]; then
        [ -z "$rotor_inertia$rotor_axis$rotor_poles" ] || die "--vehicle and --rotor-* exclude each other"
        [ -f "$vehicle" ] && [ -r "$vehicle" ] || die "--vehicle $vehicle: no such readable file"
    fi
    if [ -n "$replay_file" ] && [ -n "$rotor_inertia$rotor_axis$rotor_poles$rotor_hold$noise_std$gyro_unit$time_unit$vehicle" ]; then
        die "the --rotor-*, --noise-std, --gyro-unit and --time-unit options apply to --log: a replay file carries its own"
    fi
    if [ -n "$rotor_axis$rotor_poles$rotor_hold" ]; then
        [ -n "$rotor_inertia" ] || die "--rotor-axis, --rotor-poles, --rotor-raw and --rotor-unhold need --rotor-inertia"
    fi
    if [ -n "$rotor_inertia" ]; then
        is_num "$rotor_inertia" && awk -v j="$rotor_inertia" 'BEGIN { exit !(j > 0) }' ||
            die "--rotor-inertia $rotor_inertia: not a positive number (kg m^2)"
        [ -n "$rotor_axis" ] || die "--rotor-inertia needs --rotor-axis"
    fi
    case "$rotor_axis" in "" | x | y | z | +x | +y | +z | -x | -y | -z) ;; *) die "--rotor-axis $rotor_axis: not one of x, y, z, -x, -y, -z" ;; esac
    [ -z "$rotor_poles" ] || [[ "$rotor_poles" =~ ^[1-9][0-9]*$ ]] || die "--rotor-poles $rotor_poles: not a positive integer"
    [ -z "$noise_std" ] || { is_num "$noise_std" && awk -v s="$noise_std" 'BEGIN { exit !(s > 0) }'; } ||
        die "--noise-std $noise_std: not a positive number (rad/s)"
    case "$gyro_unit" in "" | rad/s | deg/s) ;; *) die "--gyro-unit $gyro_unit: use rad/s or deg/s" ;; esac
    case "$time_unit" in "" | s | ms | us) ;; *) die "--time-unit $time_unit: use s, ms or us" ;; esac
fi
if [ -n "$json" ]; then
    jdir="$(dirname -- "$json")"
    [ -d "$jdir" ] && [ -w "$jdir" ] || die "--json $json: directory $jdir does not exist or is not writable"
fi
if [ ${#gen_args[@]} -gt 0 ]; then
    for ((i = 1; i < ${#gen_args[@]}; i += 2)); do
        is_num "${gen_args[$i]}" || die "${gen_args[$((i - 1))]} ${gen_args[$i]}: not a number"
    done
fi
# Absolute paths: the script changes to the repository root.
abspath() { case "$1" in /*) echo "$1" ;; *) echo "$PWD/$1" ;; esac; }
[ -z "$log_file" ] || log_file="$(abspath "$log_file")"
[ -z "$replay_file" ] || replay_file="$(abspath "$replay_file")"
[ -z "$vehicle" ] || vehicle="$(abspath "$vehicle")"
[ -z "$json" ] || json="$(abspath "$json")"

source "$(dirname "${BASH_SOURCE[0]}")/setup.sh"
cd "$ROOT"

OUT=target/firmware-run
# QEMU's instruction counting for the paced replay: virtual time advances 2^shift ns per
# instruction (shift 3: 125 M instructions/s, about a 168 MHz Cortex-M4F's rate with flash wait
# states), and idles jump to the next timer (sleep=off): the same run gives the same figures.
ICOUNT="${ICOUNT:-shift=3,sleep=off}"
TD="${CARGO_TARGET_DIR:-target}"
# The ELF under the target directory cargo uses (CARGO_TARGET_DIR when set).
ELF="$TD/thumbv7em-none-eabihf/firmware/firmware-qemu"
INERTIA="$TD/release/inertia"
ensure_thumb_target
ensure_qemu
ensure_defmt_print

log "building the host tool"
cargo build -q --release -p inertia
mkdir -p "$OUT"
rm -f "$OUT/uart.bin"
build_firmware() {
    log "building the firmware (QEMU image)"
    cargo build -q -p firmware --bin firmware-qemu --features qemu \
        --target thumbv7em-none-eabihf --profile firmware
}

if [ -n "$log_file$replay_file" ]; then
    # First the export: it refuses a log it cannot read or a rotor the log has no channel for.
    log "exporting the log's pipeline inputs (inertia export-replay)"
    ex=(--input "$log_file" --out "$OUT/replay.bin")
    [ -z "$rotor_inertia" ] || ex+=(--rotor-inertia "$rotor_inertia" --rotor-axis="$rotor_axis")
    [ -z "$rotor_poles" ] || ex+=(--rotor-poles "$rotor_poles")
    [ -z "$vehicle" ] || ex+=(--vehicle "$vehicle")
    [ -z "$rotor_hold" ] || ex+=("$rotor_hold")
    [ -z "$noise_std" ] || ex+=(--noise-std "$noise_std")
    [ -z "$gyro_unit" ] || ex+=(--gyro-unit "$gyro_unit")
    [ -z "$time_unit" ] || ex+=(--time-unit "$time_unit")
    if [ -n "$replay_file" ]; then
        cp "$replay_file" "$OUT/replay.bin"
    else
        "$INERTIA" export-replay "${ex[@]}" || { echo "run.sh: the log cannot be replayed (above)" >&2; exit 3; }
    fi
    build_firmware
    log "replaying it through the firmware under QEMU (telemetry captured from USART1)"
    set +e
    refit=()
    [ -z "$refit_every" ] || refit=(--refit-every "$refit_every")
    [ -z "$refit_every_s" ] || refit=(--refit-every-s "$refit_every_s")
    [ -z "$lossless" ] || refit+=(--lossless)
    SERIAL="$OUT/uart.bin" ICOUNT="$ICOUNT" scripts/firmware-qemu.sh "$ELF" --replay "$OUT/replay.bin" \
        ${refit[@]+"${refit[@]}"} >"$OUT/defmt.txt"
    rc=$?
    set -e
    grep -E ' replay |ERROR|WARN| paced ' "$OUT/defmt.txt" || true
    # The tensor estimate once a second of log time.
    awk '/ t=[0-9]+\.[0-9]*s a_paper=/ { t = $0; sub(".* t=", "", t); sub("s .*", "", t); keep = 0 }
         / tensor status=/ { st = $0; sub(".*tensor ", "", st) }
         / tensor a=/ { a = $0; sub(".*tensor ", "", a); if (t - last >= 1 || last == "") { printf "t=%ss %s %s\n", t, st, a; last = t } }' "$OUT/defmt.txt"
    echo "final (on board):"
    sed -n '/final replay/,$p' "$OUT/defmt.txt" | grep -E 'tensor (status|a|J)=' | sed 's/^INFO  /  /'
    "$INERTIA" telemetry --input "$OUT/uart.bin" --final-json "$OUT/final.json" >"$OUT/telemetry.jsonl"
    [ -z "$json" ] || cp "$OUT/final.json" "$json"
    echo "firmware exit status: $rc (full stream: $OUT/defmt.txt; telemetry: $OUT/telemetry.jsonl; final estimate: ${json:-$OUT/final.json})"
    exit "$rc"
fi

build_firmware
log "simulating the spinning body and writing the gyro log"
cargo run -q --release -p host-tests --bin gen-log -- \
    --out "$OUT/gyro.log" --reference "$OUT/reference.txt" ${gen_args[@]+"${gen_args[@]}"}

log "running the firmware under QEMU; decoded defmt stream (one report per second shown)"
set +e
SERIAL="$OUT/uart.bin" ICOUNT="$ICOUNT" scripts/firmware-qemu.sh "$ELF" "$OUT/gyro.log" "$bus_every" >"$OUT/defmt.txt"
rc=$?
set -e
grep -E ' gyro log |ERROR|WARN' "$OUT/defmt.txt" || true
# One line per second: t, each estimate with its convergence, the refined ratios.
awk '
    function vec(key,   s) {
        s = $0; sub(".*" key "=\\[", "", s); sub("\\].*", "", s); gsub(",", "", s); return s
    }
    function word_after(key,   s) {
        s = $0; sub(".*" key "=\\[[^]]*\\] ", "", s); sub(" .*", "", s); return s
    }
    function num(key,   s) { s = $0; sub(".*" key "=", "", s); sub(" .*", "", s); return s }
    BEGIN {
        printf "%7s  %-30s %-11s  %-30s %-11s %8s %8s\n", "t", "a_paper (Identifier)", "status", "a_refined (Refined)", "status", "A2/A1 (refined)", "A3/A1"
    }
    / t=[0-9]+\.0s / {
        t = $0; sub(".* t=", "", t); sub("s .*", "s", t)
        split(vec("a_paper"), p, " "); split(vec("a_refined"), r, " ")
        printf "%7s  [%8.5f %8.5f %8.5f]  %-11s  [%8.5f %8.5f %8.5f]  %-11s %8.5f %8.5f\n", t, p[1], p[2], p[3], word_after("a_paper"), r[1], r[2], r[3], word_after("a_refined"), num("A2/A1"), num("A3/A1")
    }' "$OUT/defmt.txt"
grep -E ' final |stack:' "$OUT/defmt.txt" || true
echo
echo "true a = ($(sed -n 's/^truth=//p' "$OUT/reference.txt")), A2/A1, A3/A1 = ($(sed -n 's/^truth_ratios=//p' "$OUT/reference.txt"))"
echo "host reference (same samples, same code on x86_64): a_paper $(sed -n 's/^a_paper=//p' "$OUT/reference.txt"), a_refined $(sed -n 's/^a_refined=//p' "$OUT/reference.txt")"
echo "free-flight pipeline (the simulated part reads zero specific force: the gate takes every sample after the release guard as free):"
grep -E 'tensor (status|a|J)=' "$OUT/defmt.txt" | tail -n 3 | sed 's/^INFO  /  /' || true
if [ -s "$OUT/uart.bin" ]; then
    "$INERTIA" telemetry --input "$OUT/uart.bin" --final-json "$OUT/final.json" >"$OUT/telemetry.jsonl"
    [ -z "$json" ] || cp "$OUT/final.json" "$json"
fi
echo "firmware exit status: $rc (full stream: $OUT/defmt.txt; telemetry: $OUT/telemetry.jsonl)"
exit "$rc"
