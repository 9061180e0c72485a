#!/usr/bin/env bash
# Runs a firmware-qemu ELF under QEMU (netduinoplus2 = STM32F405, Cortex-M4F) and decodes its
# defmt stream (semihosting stdout) with defmt-print.
#   scripts/firmware-qemu.sh <elf> <gyro log> [bus error every n] [-- extra qemu args]
# Also usable as a cargo runner (`cargo qemu -- <log>`). Exits with the firmware's status.
# Semihosting paths are relative to the current directory. SERIAL=FILE captures USART1 (the
# firmware's telemetry frames) into FILE; without it the UART goes nowhere.
# QEMU counts instructions (`-icount $ICOUNT`, default shift=3,sleep=off): virtual time
# advances 8 ns per instruction (125 M instructions/s, about a 168 MHz Cortex-M4F with flash
# wait states) and jumps over idle waits, so the SysTick that paces the samples is
# deterministic and a run takes no longer than its instructions. ICOUNT=off: real time.
set -euo pipefail
elf="$1"; shift
args=("$@")
extra=()
for i in "${!args[@]}"; do
    if [ "${args[$i]}" = "--" ]; then
        extra=("${args[@]:$((i + 1))}")
        args=("${args[@]:0:$i}")
        break
    fi
done
cmdline="arg=firmware-qemu"
for a in "${args[@]}"; do cmdline+=",arg=$a"; done
set +e
serial=none
[ -n "${SERIAL:-}" ] && serial="file:$SERIAL"
icount=()
ICOUNT="${ICOUNT:-shift=3,sleep=off}"
[ "$ICOUNT" = off ] || icount=(-icount "$ICOUNT")
qemu-system-arm -machine netduinoplus2 -display none -monitor none -serial "$serial" \
    -semihosting-config "enable=on,target=native,$cmdline" \
    "${icount[@]}" "${extra[@]}" -kernel "$elf" | defmt-print -e "$elf" --log-format '{L} {s}'
status=("${PIPESTATUS[@]}")
set -e
[ "${status[1]}" -eq 0 ] || { echo "defmt-print failed (${status[1]})" >&2; exit 70; }
exit "${status[0]}"
