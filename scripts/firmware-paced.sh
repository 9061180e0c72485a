#!/usr/bin/env bash
# The fits off the sample path, under QEMU (docs/firmware.md, "Fits off the sample path"): the
# QEMU image replays a log with its samples delivered by SysTick at the log's own rate (QEMU
# `-icount shift=3,sleep=off`: 8 ns of virtual time per instruction, deterministic) into a
# ring, a lower-priority interrupt steps the sample loop, and the output-error fits run in
# thread mode on a copy of the pipeline. Two logs:
#
#  1. a drone throw at 8 kHz (`gen-throw --scenario board_throw --seed 1 --rate 8000`, a
#     flywheel), gated by the accelerometer: one end-of-flight fit while the bench samples
#     keep coming; its final estimate must equal `inertia identify`'s bit for bit;
#  2. a small satellite at 10 Hz (`gen-satellite`: four reaction wheels, a torque-free tumble,
#     20 s of magnetorquer activity flagged every 30 min; 2 h, 72 000 samples), continuous
#     mode (no accelerometer) re-fitting every 6000 samples fed (10 min): every re-fit of the
#     window so far and every ended stretch's fit; the final tensor must be within 1 % of the
#     simulated one on the diagonal and Converged.
#
# Checks, per log (non-zero exit on any failure): QEMU exit 0; samples delivered = the log's;
# stepped = delivered; dropped = 0; the ring's peak below its capacity; no fit run by the
# stepper itself (inline_fits = 0); at least one fit; the stack's painted high-water at least
# 1 KiB below its reservation (at the reservation it ran into the statics below it). Printed: each fit's latency in samples
# and in virtual seconds, and a summary table.
#
#   scripts/firmware-paced.sh [--quick]
# --quick (the test command): the satellite for 24 min (14 400 samples, flagged every 8 min,
# re-fit every 2400 samples) instead of 2 h.
# ICOUNT overrides QEMU's -icount setting (scripts/run.sh).
set -euo pipefail
source "$(dirname "${BASH_SOURCE[0]}")/setup.sh"
cd "$ROOT"

quick=0
[ "${1:-}" = "--quick" ] && quick=1
OUT=target/firmware-paced
TD="${CARGO_TARGET_DIR:-target}"
INERTIA="$TD/release/inertia"
mkdir -p "$OUT"
command -v python3 >/dev/null || { echo "firmware-paced: python3 is needed" >&2; exit 1; }

log "building the host tools"
cargo build -q --release -p inertia
cargo build -q --release -p host-tests --bin gen-throw --bin gen-satellite

log "8 kHz drone throw (gen-throw --scenario board_throw --seed 1 --rate 8000)"
"$TD/release/gen-throw" --scenario board_throw --seed 1 --rate 8000 --out "$OUT/throw8k.csv" >/dev/null
rotor=(--rotor-inertia 1.689e-6 --rotor-axis=-z)
"$INERTIA" identify --input "$OUT/throw8k.csv" "${rotor[@]}" --json "$OUT/throw8k.identify.json" >/dev/null 2>&1 || true
set +e
scripts/run.sh --log "$OUT/throw8k.csv" "${rotor[@]}" --json "$OUT/throw8k.firmware.json" >"$OUT/throw8k.run.txt" 2>&1
rc_drone=$?
set -e
cp target/firmware-run/defmt.txt "$OUT/throw8k.defmt.txt"

if [ "$quick" = 1 ]; then
    sat=(--hours 0.4 --actuate-every 480)
    refit=2400
else
    sat=(--hours 2 --actuate-every 1800)
    refit=6000
fi
log "10 Hz satellite, continuous mode (gen-satellite ${sat[*]}, re-fit every $refit samples)"
"$TD/release/gen-satellite" --out "$OUT/satellite.irpl" "${sat[@]}" >"$OUT/satellite.truth.txt"
cat "$OUT/satellite.truth.txt"
set +e
scripts/run.sh --replay "$OUT/satellite.irpl" --refit-every "$refit" --json "$OUT/satellite.firmware.json" \
    >"$OUT/satellite.run.txt" 2>&1
rc_sat=$?
set -e
cp target/firmware-run/defmt.txt "$OUT/satellite.defmt.txt"

python3 - "$OUT" "$rc_drone" "$rc_sat" <<'PY'
import json, re, struct, sys
out, rc_drone, rc_sat = sys.argv[1], int(sys.argv[2]), int(sys.argv[3])
fail = []
def bits(x):
    if x is None: return None
    if isinstance(x, list): return [bits(v) for v in x]
    return struct.unpack('<I', struct.pack('<f', x))[0]
rows = []
for name, rc in (("throw8k", rc_drone), ("satellite", rc_sat)):
    txt = open(f"{out}/{name}.defmt.txt").read()
    head = re.search(r" replay \S+: (\d+) samples at ([\d.]+) Hz", txt)
    paced = re.search(r" paced (.*)", txt)
    if rc != 0 or not head or not paced:
        fail.append(f"{name}: QEMU exit {rc}, no paced summary")
        continue
    samples, rate = int(head.group(1)), float(head.group(2))
    p = dict(re.findall(r"(\w+)=([\d.]+)", paced.group(1)))
    g = lambda k: int(float(p[k]))
    fits = re.findall(r" fit (\d+) kind=(\w+) started at sample (\d+) latency (\d+) samples ([\d.e-]+) s fed=(\d+)", txt)
    print(f"\n{name}: {samples} samples at {rate:g} Hz")
    for n, kind, start, lat, sec, fed in fits:
        print(f"  fit {n:>2} {kind:<12} at sample {start:>6} ({int(fed):>6} fed): latency {lat:>5} samples, {float(sec):.3f} s virtual")
    checks = [
        ("delivered = the log's samples", g("delivered") == samples),
        ("stepped = delivered", g("stepped") == g("delivered")),
        ("dropped = 0", g("dropped") == 0),
        ("ring peak below capacity", g("ring_peak") < g("ring_capacity")),
        ("no fit in the stepper (inline_fits = 0)", g("inline_fits") == 0),
        ("at least one fit off the sample path", len(fits) >= 1),
    ]
    st = re.search(r"stack: (\d+) bytes reserved; high-water (\d+)", txt)
    if st:
        reserved, high = int(st.group(1)), int(st.group(2))
        print(f"  stack high-water {high} of {reserved} bytes")
        # A high-water at the reservation means the stack ran into the statics below it.
        checks.append(("stack high-water below its reservation (1 KiB margin)", high + 1024 <= reserved))
    else:
        checks.append(("stack figures printed", False))
    for what, ok in checks:
        print(f"  {'PASS' if ok else 'FAIL'} {what}")
        if not ok: fail.append(f"{name}: {what}")
    ended = [int(l) for _, k, _, l, _, _ in fits if k == "EndedFlight"]
    refits = [int(l) for _, k, _, l, _, _ in fits if k == "Refit"]
    worst = lambda v: (max(v), max(v) / rate) if v else (0, 0.0)
    rows.append((name, rate, samples, g("stepped"), g("dropped"), g("ring_peak"), g("ring_capacity"),
                 len(ended), worst(ended), len(refits), worst(refits), g("held_for_fit")))
# The drone: bit for bit with inertia identify.
try:
    fw = json.load(open(f"{out}/throw8k.firmware.json"))
    idp = json.load(open(f"{out}/throw8k.identify.json"))["pooled"]
    same = all(bits(idp[a]) == bits(fw[b]) for a, b in (("a", "a"), ("std_a", "std_a"), ("tensor_kg_m2", "tensor_kg_m2"))) \
        and idp["status"] == fw["status"] and idp["samples"] == fw["samples_fed"]
    print(f"\n  {'PASS' if same else 'FAIL'} throw8k: on board == inertia identify pooled, bit for bit ({fw['status']}, {fw['samples_fed']} samples fed)")
    if not same: fail.append("throw8k: on board != identify")
except Exception as e:
    fail.append(f"throw8k: no result to compare ({e})")
# The satellite: its tensor against the simulated one.
try:
    fw = json.load(open(f"{out}/satellite.firmware.json"))
    truth = open(f"{out}/satellite.truth.txt").read()
    m = re.search(r"true J = (\[\[.*\]\])", truth)
    tj = json.loads(m.group(1))
    j = fw["tensor_kg_m2"]
    errs = [abs(j[k][k] - tj[k][k]) / tj[k][k] for k in range(3)]
    ok = fw["status"] == "Converged" and max(errs) < 0.01
    print(f"  {'PASS' if ok else 'FAIL'} satellite: {fw['status']}, diagonal of J within {100 * max(errs):.3f} % of the simulated body (tolerance 1 %)")
    if not ok: fail.append("satellite: tensor")
except Exception as e:
    fail.append(f"satellite: no tensor ({e})")
print("\n| log | rate | samples stepped | dropped | ring peak / capacity | ended-flight fits, worst latency | re-fits, worst latency | held out for a fit |")
print("|---|---|---|---|---|---|---|---|")
for (name, rate, n, st, dr, pk, cap, ne, (ws, wt), nr, (rs, rt), hf) in rows:
    print(f"| {name} | {rate:g} Hz | {st} of {n} | {dr} | {pk} / {cap} | {ne}, {ws} samples = {wt:.3f} s | {nr}, {rs} samples = {rt:.3f} s | {hf} |")
if fail:
    print("\nfirmware-paced: FAILED: " + "; ".join(fail), file=sys.stderr)
    sys.exit(1)
print("\nfirmware-paced: OK")
PY
