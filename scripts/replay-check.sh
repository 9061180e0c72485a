#!/usr/bin/env bash
# Real logs through the real firmware: each log is replayed under QEMU by scripts/run.sh --log
# (the firmware's own sample loop and FlightPipeline, at the log's own rate) and its final
# on-board estimate must equal `inertia identify`'s pooled result on the same log, bit for
# bit: status, samples fed, and the f32 bits of a, std_a and the tensor (null on both sides
# when undetermined). Also, per log, the telemetry frames captured from the firmware's UART
# must decode and their last estimate must equal the one the firmware printed over defmt (its
# IEEE-754 bits).
#
# Logs: the 10 thrown-FC blackbox logs in ../shared/data/thrown-fc (skipped when absent;
# flywheel 1.689e-6 kg m^2 about -z, 14 poles), a simulated board throw CSV
# (host-tests gen-throw --scenario board_throw --seed 1, same flywheel, speed in rad/s) and
# the same throw as a Betaflight blackbox log (--format betaflight: filtered gyro and
# accelerometer, eRPM) and as a PX4 ULog (--format px4: interval means, esc_status), a toss
# without a rotor as a CSV and a ULog, user mistakes, and six spacecraft fixtures with
# reaction wheels and their vehicle files (inertia/tests/data/spacecraft), two of them on orbit
# with the gravity-gradient torque folded in (the firmware's passes as identify's).
# THROWN_FC_DIR overrides where the thrown-FC logs are looked for. --quick (the test command's)
# leaves out the second orbit log, leo-dipole-1hz, and replays the first 3000 s of leo-gg-1hz
# (the same passes, a quarter of the samples: the whole orbit's three passes take a minute under
# QEMU).
# Exit 1 when any log differs.
set -euo pipefail
quick=0
for a in "$@"; do [ "$a" = "--quick" ] && quick=1; done
source "$(dirname "${BASH_SOURCE[0]}")/setup.sh"
cd "$ROOT"

OUT=target/replay-check
TD="${CARGO_TARGET_DIR:-target}"
INERTIA="$TD/release/inertia"
DATA="${THROWN_FC_DIR:-$ROOT/../shared/data/thrown-fc}"
mkdir -p "$OUT"
command -v python3 >/dev/null || { echo "replay-check: python3 is needed for the bit comparison" >&2; exit 1; }

log "simulated board throw (gen-throw --scenario board_throw --seed 1)"
cargo run -q --release -p host-tests --bin gen-throw -- --scenario board_throw --seed 1 \
    --out "$OUT/board_throw.csv" >/dev/null
cargo build -q --release -p inertia

logs=()
if [ -d "$DATA" ]; then
    for f in "$DATA"/device_only/*.BFL "$DATA"/proof_body/*.BFL; do [ -f "$f" ] && logs+=("$f"); done
else
    echo "replay-check: $DATA absent: the thrown-FC logs are skipped"
fi
logs+=("$OUT/board_throw.csv")
# The same kind of throw as a Betaflight flight controller logs it: gyro and accelerometer
# through the firmware's filters (the reader reads each their delay later, the fits count the
# gyro filters' time spread), rotor as eRPM.
cargo run -q --release -p host-tests --bin gen-throw -- --scenario board_throw --seed 1 \
    --rate 8000 --format betaflight --out "$OUT/board_throw_betaflight.bbl" >/dev/null
logs+=("$OUT/board_throw_betaflight.bbl")
# And as PX4 logs it at 1 kHz (gyro and accelerometer the means over each interval, the
# flywheel's rpm in esc_status at 100 Hz); without a rotor below.
cargo run -q --release -p host-tests --bin gen-throw -- --scenario board_throw --seed 1 \
    --rate 4000 --format px4 --out "$OUT/board_throw_px4.ulg" >/dev/null
logs+=("$OUT/board_throw_px4.ulg")
# No rotor, principal axes (the paper's setting): the ratios come from the refined identifier
# fed by the same pipeline.
cargo run -q --release -p host-tests --bin gen-throw -- --scenario no_rotor_toss --seed 2 \
    --out "$OUT/no_rotor_toss.csv" >/dev/null
logs+=("$OUT/no_rotor_toss.csv")
cargo run -q --release -p host-tests --bin gen-throw -- --scenario no_rotor_toss --seed 2 \
    --rate 4000 --format px4 --out "$OUT/no_rotor_toss_px4.ulg" >/dev/null
logs+=("$OUT/no_rotor_toss_px4.ulg")
# User mistakes and bad data (issue 10): must never come out Converged, on board or on the host.
gen() { cargo run -q --release -p host-tests --bin gen-throw -- "$@" >/dev/null; }
gen --scenario still --seed 3 --out "$OUT/bad_still.csv"
gen --scenario board_throw --seed 4 --deg-per-s --out "$OUT/bad_degps.csv"
gen --scenario board_throw --seed 5 --time-unit ms --out "$OUT/bad_time_ms.csv"
gen --scenario clipped_toss --seed 2 --out "$OUT/bad_clipped.csv"
bad=("$OUT/bad_still.csv" "$OUT/bad_degps.csv" "$OUT/bad_time_ms.csv" "$OUT/bad_clipped.csv")
logs+=("${bad[@]}")
# Spacecraft with reaction wheels, their vehicle files (`--vehicle`, several rotors through
# Rotors::momentum on both sides). On the orbit logs with attitude and position columns
# (leo-gg-1hz, leo-dipole-1hz) identify folds the gravity-gradient torque into the momentum
# and refits at the tensor found: the replay carries the orbit (format version 6) and the
# firmware makes the same passes with the same function (identifier_core::gravity).
SC=inertia/tests/data/spacecraft
for n in leo-free-1hz sat6u-pyramid-10hz mems-walk-10hz peer-cubesat-1hz leo-gg-1hz leo-dipole-1hz; do
    if [ "$quick" = 1 ]; then
        [ "$n" = leo-dipole-1hz ] && continue
        if [ "$n" = leo-gg-1hz ]; then
            head -n 3001 "$SC/$n.csv" > "$OUT/leo-gg-1hz-3000s.csv"
            logs+=("$OUT/leo-gg-1hz-3000s.csv")
            continue
        fi
    fi
    logs+=("$SC/$n.csv")
done

fail=0
results=()
for f in "${logs[@]}"; do
    name="$(basename "$f")"
    d="$OUT/runs/$name"
    mkdir -p "$d"
    rotor=(--rotor-inertia 1.689e-6 --rotor-axis=-z)
    case "$f" in
        *.BFL | *.bbl) rotor+=(--rotor-poles 14) ;;
        *no_rotor*) rotor=() ;;
        "$SC"/*) rotor=(--vehicle "${f%.csv}.toml") ;;
        */leo-gg-1hz-3000s.csv) rotor=(--vehicle "$SC/leo-gg-1hz.toml") ;;
    esac
    set +e
    "$INERTIA" identify --input "$f" "${rotor[@]}" --json "$d/identify.json" 2>"$d/identify.err"
    id_rc=$?
    scripts/run.sh --log "$f" "${rotor[@]}" --lossless --json "$d/firmware.json" >"$d/run.txt" 2>&1
    fw_rc=$?
    set -e
    cp target/firmware-run/defmt.txt "$d/defmt.txt" 2>/dev/null || true
    line="$(python3 - "$d" "$id_rc" "$fw_rc" <<'PY'
import json, re, struct, sys
d, id_rc, fw_rc = sys.argv[1], int(sys.argv[2]), int(sys.argv[3])
def bits(x):
    if x is None: return None
    if isinstance(x, list): return [bits(v) for v in x]
    return struct.unpack('<I', struct.pack('<f', x))[0]
out = []
ok = True
try:
    fw = json.load(open(f"{d}/firmware.json"))
except Exception as e:
    print(f"different: no on-board result (run.sh exit {fw_rc}: {e})"); sys.exit()
if id_rc not in (0, 4):
    # identify found no free flight (exit 3): the firmware must have fed nothing either.
    same = fw["samples_fed"] == 0 and fw["a"] is None
    print(("equal" if same else "different") + f": identify exit {id_rc} (no free flight); on board {fw['throws_detected']} throws, {fw['samples_fed']} samples fed")
    sys.exit()
p = json.load(open(f"{d}/identify.json"))["pooled"]
diffs = []
if p["status"] != fw["status"]: diffs.append(f"status {p['status']} / {fw['status']}")
if p["samples"] != fw["samples_fed"]: diffs.append(f"samples {p['samples']} / {fw['samples_fed']}")
for k in ("tensor_uncertainty", "tensor_usable"):
    if p[k] != fw[k]: diffs.append(f"{k} {p[k]} / {fw[k]}")
for k_id, k_fw in (("a", "a"), ("std_a", "std_a"), ("tensor_kg_m2", "tensor_kg_m2")):
    if bits(p[k_id]) != bits(fw[k_fw]): diffs.append(f"{k_id} {p[k_id]} / {fw[k_fw]}")
# UART telemetry == defmt (the firmware's final tensor lines carry the bits).
tel = []
txt = open(f"{d}/defmt.txt").read()
tail = txt[txt.find("final replay"):]
def hexes(key):
    m = re.search(rf"{key}=\[([^\]]*)\]", tail)
    return [int(h, 16) for h in m.group(1).split(",")] if m else None
ba, bs, bj = hexes("bits_a"), hexes("bits_std_a"), hexes("bits_J")
flat = lambda m: None if m is None else [v for row in m for v in row]
if ba != bits(fw["a"]) or bs != bits(fw["std_a"]) or bj != bits(flat(fw["tensor_kg_m2"])):
    tel.append("UART telemetry != defmt")
st = re.findall(r"tensor status=(\w+) throws=(\d+) fed=(\d+)", tail)
if not st or st[-1][0] != fw["status"] or int(st[-1][1]) != fw["throws_detected"] or int(st[-1][2]) != fw["samples_fed"]:
    tel.append("UART status/counters != defmt")
verdict = "equal" if not diffs else "different"
a = fw["a"]
astr = "none" if a is None else "[" + ", ".join(f"{v:.4f}" for v in a) + "]"
use = ", usable" if fw["tensor_usable"] else ""
print(f"{verdict}: {fw['throws_detected']} free flights on board, {fw['samples_fed']} samples fed, {fw['status']}{use}, a={astr}; UART=defmt: {'yes' if not tel else '; '.join(tel)}" + ("" if not diffs else " | " + "; ".join(diffs)))
PY
)"
    case "$line" in equal*"UART=defmt: yes"*) ;; equal*"no free flight"*) ;; *) fail=1 ;; esac
    case "$name" in bad_*)
        case "$line" in *Converged,*) line="$line  <- a bad log came out Converged"; fail=1 ;; esac
        case "$line" in *", usable,"*) line="$line  <- a bad log came out usable"; fail=1 ;; esac ;;
    esac
    results+=("$(printf '%-18s %s' "$name" "$line")")
    echo "$(printf '%-18s %s' "$name" "$line")"
done
echo
echo "on-board (QEMU, replay) vs inertia identify pooled, bit for bit: ${#logs[@]} logs"
[ "$fail" -eq 0 ] || { echo "replay-check: FAILED" >&2; exit 1; }
echo "replay-check: OK"
