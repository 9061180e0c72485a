#!/usr/bin/env bash
# Checks the MSRV claim (`rust-version` in the root Cargo.toml) of the publishable crates,
# identifier-core and the ICM-42688-P driver, with the one toolchain installed here (a second,
# older toolchain cannot be fetched on these machines). Two checks, each honest about its reach:
#   1. dependencies: a scratch crate that depends on both, with the same rust-version, is
#      resolved afresh with CARGO_RESOLVER_INCOMPATIBLE_RUST_VERSIONS=fallback; cargo marks a
#      dependency version it had to take although it needs a newer Rust "vN (requires Rust X)"
#      (not to be confused with "available: vM, requires Rust X", a newer version it skipped),
#      which fails the check.
#      Then it is built with `cargo check`.
#   2. the crates' own code: clippy's `incompatible_msrv` lint (clippy reads rust-version) denies
#      any standard-library API stabilised after the MSRV.
# Not covered: language features newer than the MSRV (only the old compiler would reject them).
set -euo pipefail
source "$(dirname "${BASH_SOURCE[0]}")/setup.sh"
cd "$ROOT"

msrv="$(sed -n 's/^rust-version = "\(.*\)"/\1/p' Cargo.toml | head -n 1)"
[ -n "$msrv" ] || { echo "check-msrv: no rust-version in Cargo.toml" >&2; exit 1; }
driver_dir=icm42688
driver="$(sed -n 's/^name = "\(.*\)"/\1/p' "$driver_dir/Cargo.toml" | head -n 1)"

log "MSRV $msrv: fresh dependency resolution of identifier-core and $driver (fallback resolver)"
scratch="$(mktemp -d)"
trap 'rm -rf "$scratch"' EXIT
mkdir -p "$scratch/src"
cat > "$scratch/Cargo.toml" <<TOML
[package]
name = "msrv-check"
version = "0.0.0"
edition = "2021"
rust-version = "$msrv"
publish = false

[workspace]

[dependencies]
identifier-core = { path = "$ROOT/identifier-core", features = ["defmt"] }
$driver = { path = "$ROOT/$driver_dir", features = ["defmt", "sim"] }
TOML
echo '#![no_std]' > "$scratch/src/lib.rs"
export CARGO_RESOLVER_INCOMPATIBLE_RUST_VERSIONS=fallback
out="$(cargo generate-lockfile --manifest-path "$scratch/Cargo.toml" 2>&1)"
printf '%s\n' "$out" | grep -v '^ *Updating' >&2 || true
if printf '%s\n' "$out" | grep -Eq ' v[0-9][^ ]* \(requires Rust'; then
    echo "check-msrv: a dependency needs a newer Rust than $msrv (above)" >&2
    exit 1
fi
cargo check -q --manifest-path "$scratch/Cargo.toml" \
    --target-dir "${CARGO_TARGET_DIR:-$ROOT/target}/msrv-check"

log "MSRV $msrv: clippy::incompatible_msrv on identifier-core and $driver (library code)"
for dir in identifier-core "$driver_dir"; do
    cargo clippy -q --manifest-path "$dir/Cargo.toml" --lib --all-features -- \
        -D warnings -D clippy::incompatible_msrv
done
echo "check-msrv: dependencies and library code within Rust $msrv"
