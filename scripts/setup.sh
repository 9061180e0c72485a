#!/usr/bin/env bash
# Idempotent set-up shared by scripts/run.sh and scripts/test.sh: each ensure_* installs what
# is missing on a fresh machine and does nothing when it is already there.
set -euo pipefail

ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
export PATH="$HOME/.cargo/bin:$PATH"

log() { printf '\033[1m==> %s\033[0m\n' "$*" >&2; }

apt_install() {
    # Root on these machines; sudo elsewhere.
    local SUDO=""
    [ "$(id -u)" -eq 0 ] || SUDO="sudo"
    $SUDO apt-get update -qq
    DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq "$@" >/dev/null
}

ensure_thumb_target() {
    if ! rustup target list --installed | grep -qx thumbv7em-none-eabihf; then
        log "adding rust target thumbv7em-none-eabihf"
        rustup target add thumbv7em-none-eabihf
    fi
}

ensure_llvm_tools() {
    if ! rustup component list --installed | grep -q '^llvm-tools'; then
        log "adding rustup component llvm-tools"
        rustup component add llvm-tools
    fi
    LLVM_BIN="$(rustc --print sysroot)/lib/rustlib/$(rustc -vV | sed -n 's/^host: //p')/bin"
    export LLVM_BIN
}

ensure_qemu() {
    if ! command -v qemu-system-arm >/dev/null; then
        log "installing qemu-system-arm (Debian package)"
        apt_install qemu-system-arm
    fi
}

ensure_defmt_print() {
    if ! command -v defmt-print >/dev/null; then
        log "installing defmt-print (cargo install, a few minutes)"
        cargo install defmt-print --locked
    fi
}

ensure_gcc() {
    if ! command -v gcc >/dev/null; then
        log "installing gcc (Debian package, for the QEMU instruction-counting plugin)"
        apt_install gcc libc6-dev
    fi
}
