#!/usr/bin/env bash
# Cargo runner for the board image (`cargo flash-board`): flash over SWD and stream defmt with
# probe-rs. Checks that probe-rs is installed and says how to get it instead of failing
# obscurely.
set -euo pipefail
if ! command -v probe-rs >/dev/null; then
    cat >&2 <<'MSG'
cargo flash-board: probe-rs is not installed.
  Install it (about 15 minutes to build):   cargo install probe-rs-tools --locked
  or use the installer from the probe-rs project's documentation.
  Then connect a debug probe (ST-LINK, J-Link, CMSIS-DAP) to the flight controller's SWD pads.
  Without a probe, read the board over its UART instead (see docs/firmware.md), or run
  the same firmware under QEMU: scripts/run.sh
MSG
    exit 127
fi
exec probe-rs run --chip STM32F405RGTx "$@"
