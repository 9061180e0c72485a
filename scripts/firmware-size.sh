#!/usr/bin/env bash
# Flash and static RAM of both firmware images (profile `firmware`), by llvm-size:
#   flash = .vector_table + .text + .rodata + .data (its initial values live in flash),
#   static RAM = .data + .bss + .uninit (the stack takes the rest of the 128 KiB).
#
#   scripts/firmware-size.sh [--against REV]
# --against REV: also builds REV's images (a temporary git worktree, its own target
# directory under the target directory) and prints before, after and the difference.
set -euo pipefail
source "$(dirname "${BASH_SOURCE[0]}")/setup.sh"
cd "$ROOT"

against=""
if [ "${1:-}" = "--against" ]; then
    [ -n "${2:-}" ] || { echo "firmware-size: --against needs a revision" >&2; exit 2; }
    against="$2"
fi
ensure_thumb_target
TD="${CARGO_TARGET_DIR:-$ROOT/target}"
case "$TD" in /*) ;; *) TD="$ROOT/$TD" ;; esac
LLVM_SIZE="$(rustc --print sysroot)/lib/rustlib/$(rustc -vV | sed -n 's/^host: //p')/bin/llvm-size"
[ -x "$LLVM_SIZE" ] || rustup component add llvm-tools >/dev/null 2>&1 || true
[ -x "$LLVM_SIZE" ] || { echo "firmware-size: llvm-size not found (rustup component add llvm-tools)" >&2; exit 1; }

build() { # dir target-dir
    for f in qemu stm32f405; do
        (cd "$1" && CARGO_TARGET_DIR="$2" cargo build -q -p firmware --bins --features "$f" \
            --target thumbv7em-none-eabihf --profile firmware)
    done
}

# "flash ram" of an ELF.
sizes() {
    "$LLVM_SIZE" -A "$1" | awk '
        $1 == ".vector_table" || $1 == ".text" || $1 == ".rodata" { flash += $2 }
        $1 == ".data" { flash += $2; ram += $2 }
        $1 == ".bss" || $1 == ".uninit" { ram += $2 }
        END { printf "%d %d\n", flash, ram }'
}

log "building both images (this tree)"
build "$ROOT" "$TD"
declare -A now before
for bin in firmware-qemu firmware-stm32f405; do
    now[$bin]="$(sizes "$TD/thumbv7em-none-eabihf/firmware/$bin")"
done
if [ -n "$against" ]; then
    base="$TD/size-base"
    wt="$base/tree"
    rm -rf "$wt"
    git worktree prune
    log "building both images at $against (worktree $wt)"
    git worktree add --detach "$wt" "$against" >/dev/null
    build "$wt" "$base/target"
    for bin in firmware-qemu firmware-stm32f405; do
        before[$bin]="$(sizes "$base/target/thumbv7em-none-eabihf/firmware/$bin")"
    done
    git worktree remove --force "$wt"
fi

echo
if [ -n "$against" ]; then
    echo "| image | flash at $against | flash now | difference | static RAM at $against | static RAM now | difference |"
    echo "|---|---|---|---|---|---|---|"
    for bin in firmware-qemu firmware-stm32f405; do
        read -r fn rn <<<"${now[$bin]}"
        read -r fb rb <<<"${before[$bin]}"
        printf "| %s | %d | %d | %+d | %d | %d | %+d |\n" "$bin" "$fb" "$fn" $((fn - fb)) "$rb" "$rn" $((rn - rb))
    done
else
    echo "| image | flash (bytes) | static RAM (bytes) |"
    echo "|---|---|---|"
    for bin in firmware-qemu firmware-stm32f405; do
        read -r fn rn <<<"${now[$bin]}"
        printf "| %s | %d | %d |\n" "$bin" "$fn" "$rn"
    done
fi
echo
echo "llvm-size -A, this tree:"
for bin in firmware-qemu firmware-stm32f405; do
    echo "$bin:"
    "$LLVM_SIZE" -A "$TD/thumbv7em-none-eabihf/firmware/$bin" | grep -E '^\.(vector_table|text|rodata|data|bss|uninit) '
done
