#!/usr/bin/env bash
# Proof that identifier-core has no panic path in its thumbv7em-none-eabihf release build.
#
# checks/no-panic links every public entry of the core, on opaque inputs, into a
# thumbv7em-none-eabihf image whose panic handler calls an undefined symbol. Two checks:
#   1. the link succeeds, which it cannot if a panic path is reachable (undefined reference to
#      identifier_core_has_a_panic_path);
#   2. llvm-nm finds no symbol with "panic" in its name in the linked image.
# Both at the firmware's opt-level "s" and at opt-level 3.
#
# Then a self-test shows the check can fail: a scratch copy of the core with one out-of-bounds
# index planted in Identifier::step must be caught. `--no-self-test` skips it.
set -euo pipefail
source "$(dirname "${BASH_SOURCE[0]}")/setup.sh"
cd "$ROOT"

ensure_thumb_target
ensure_llvm_tools

SELF_TEST=1
[ "${1:-}" = "--no-self-test" ] && SELF_TEST=0

TARGET=thumbv7em-none-eabihf

# check_image DIR TARGET_DIR OPT -> 0 if linked and panic-free, 1 if a panic path was found,
# 2 if the build failed for another reason.
check_image() {
    local dir="$1" tdir="$2" opt="$3" out
    out="$(mktemp)"
    if ! (cd "$dir" && CARGO_TARGET_DIR="$tdir" CARGO_PROFILE_RELEASE_OPT_LEVEL="$opt" \
        cargo build --release --target "$TARGET" >"$out" 2>&1); then
        if grep -q identifier_core_has_a_panic_path "$out"; then
            echo "no-panic: opt-level $opt: LINK FAILED: a panic path is reachable:" >&2
            grep -m 3 -E "undefined symbol|referenced by|>>> " "$out" >&2 || true
        else
            echo "no-panic: opt-level $opt: build failed for another reason:" >&2
            tail -n 30 "$out" >&2
            rm -f "$out"
            return 2
        fi
        rm -f "$out"
        return 1
    fi
    rm -f "$out"
    local elf="$tdir/$TARGET/release/core-link-probe"
    local hits
    hits="$("$LLVM_BIN/llvm-nm" -C "$elf" | grep -iE "panic|unwind|unwrap_failed|expect_failed|_fail(::|$)|len_fail|order_fail" || true)"
    if [ -n "$hits" ]; then
        echo "no-panic: opt-level $opt: panic symbols in the image:" >&2
        echo "$hits" >&2
        return 1
    fi
    local text
    text="$("$LLVM_BIN/llvm-size" "$elf" | awk 'NR==2 {print $1}')"
    echo "no-panic: opt-level $opt: linked, $text bytes of text, no panic symbol"
}

log "no-panic check of identifier-core ($TARGET, release, fat LTO)"
for opt in s 3; do
    check_image "$ROOT/checks/no-panic" "$ROOT/checks/no-panic/target/opt-$opt" "$opt"
done

if [ "$SELF_TEST" -eq 1 ]; then
    log "self-test: a planted out-of-bounds index must be caught"
    scratch="$(mktemp -d)"
    trap 'rm -rf "$scratch"' EXIT
    mkdir -p "$scratch/checks/no-panic"
    cp -r "$ROOT/identifier-core" "$scratch/identifier-core"
    rm -rf "$scratch/identifier-core/target"
    cp -r "$ROOT/checks/no-panic/src" "$ROOT/checks/no-panic/Cargo.toml" \
        "$ROOT/checks/no-panic/.cargo" "$scratch/checks/no-panic/"
    # The core inherits edition etc. from the root workspace: give the copy a root of its own.
    {
        printf '[workspace]\nresolver = "2"\nmembers = ["identifier-core"]\n\n'
        sed -n '/^\[workspace.package\]/,/^$/p' "$ROOT/Cargo.toml"
    } >"$scratch/Cargo.toml"
    # Plant: index a 3-element array with a value derived from the input.
    perl -0pi -e 's/(pub fn step\(&mut self, omega: \[f32; 3\], dt: f32\) -> Estimate \{\n)/$1        let planted = [1.0f32, 2.0, 3.0];\n        let dt = dt * planted[(dt.to_bits() % 4) as usize];\n/' \
        "$scratch/identifier-core/src/identifier.rs"
    if ! grep -q planted "$scratch/identifier-core/src/identifier.rs"; then
        echo "no-panic: self-test could not plant the panic (step signature changed?)" >&2
        exit 1
    fi
    rc=0
    check_image "$scratch/checks/no-panic" "$ROOT/checks/no-panic/target/self-test" s \
        2>"$scratch/err" || rc=$?
    if [ "$rc" -ne 1 ]; then
        cat "$scratch/err" >&2
        echo "no-panic: SELF-TEST FAILED: the planted panic was not detected (rc $rc)" >&2
        exit 1
    fi
    echo "no-panic: self-test: planted out-of-bounds index detected:"
    sed 's/^/    /' "$scratch/err"
fi
echo "no-panic: identifier-core has no reachable panic path"
