#!/usr/bin/env bash
# Objects of known inertia thrown on the rig (../shared/data/thrown-fc/objects/): each throw's
# object by difference (`inertia calibrate --board <5> --assembly <5> --object ONE_THROW`, the
# data README's masses, the proof body in the log's frame, a 14-pole rotor on -z), all of an
# object's throws pooled, and each assembly throw through `inertia identify` against the
# anchor's board plus the object's truth. Prints the figures and the anchor's published ones.
# A benchmark, not a test: it asserts nothing. Skips when ../shared is absent.
set -euo pipefail
source "$(dirname "${BASH_SOURCE[0]}")/setup.sh"
cd "$ROOT"
cargo run -q --release -p inertia --example bench-objects -- "$@"
