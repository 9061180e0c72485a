#!/usr/bin/env bash
# Fault injection on the MCU under QEMU (mps2-an386): builds checks/firmware-faults, runs it
# with semihosting, decodes its defmt stream, and fails unless every scenario passed and the
# watchdog reset the machine out of the injected hang.
#   checks/firmware-faults/run.sh [--selftest-no-watchdog]
set -euo pipefail
source "$(dirname "${BASH_SOURCE[0]}")/../../scripts/setup.sh"
ensure_thumb_target
ensure_qemu
ensure_defmt_print

cd "$ROOT/checks/firmware-faults"
# Its own target directory, whatever the caller's CARGO_TARGET_DIR: the ELF path is fixed below.
export CARGO_TARGET_DIR="$ROOT/checks/firmware-faults/target"
features=()
limit=120
if [ "${1:-}" = "--selftest-no-watchdog" ]; then
    features=(--features selftest-no-watchdog)
    limit=20
fi
cargo build --release "${features[@]}" 2>&1 | tail -n 1
elf=target/thumbv7em-none-eabihf/release/firmware-faults
out="$(mktemp)"
set +e
timeout "$limit" qemu-system-arm -machine mps2-an386 -cpu cortex-m4 -display none \
    -monitor none -serial none -semihosting-config enable=on,target=native -kernel "$elf" \
    | defmt-print -e "$elf" --log-format '{L} {s}' | tee "$out"
status=("${PIPESTATUS[@]}")
set -e
fail() { echo "firmware-faults: FAILED: $*" >&2; rm -f "$out"; exit 1; }
[ "${status[0]}" -eq 124 ] && fail "QEMU did not finish within ${limit}s (a hang the watchdog did not end?)"
[ "${status[0]}" -eq 0 ] || fail "firmware exit code ${status[0]}"
grep -q "reset by the watchdog after the injected hang" "$out" || fail "no watchdog reset seen"
grep -q "fault injection: all checks passed" "$out" || fail "checks failed"
[ "$(grep -c '; PASS$' "$out")" -eq 6 ] || fail "expected 6 passing scenarios"
rm -f "$out"
echo "firmware-faults: all fault scenarios passed under QEMU, watchdog reset seen"
