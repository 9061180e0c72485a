#!/usr/bin/env bash
# Runs identifier-core's host example (examples/csv.rs) on a generated gyro CSV and checks its
# estimate: the paper's body A = (0.6, 1.54, 1.0) (a = 0.9, 0.2597, -0.94), omega0 = (1, 1, 1)
# rad/s, torque-free, RK4 at 1 kHz for 20 s, Gaussian noise 1e-3 rad/s (awk, seed 1).
# Usage: scripts/example-csv.sh [TOLERANCE]   (default 5e-3 on each component of a)
set -euo pipefail
source "$(dirname "${BASH_SOURCE[0]}")/setup.sh"
cd "$ROOT"
tol="${1:-5e-3}"
csv="$(mktemp --suffix .csv)"
trap 'rm -f "$csv"' EXIT

awk 'BEGIN {
    srand(1); pi = 3.14159265358979
    A1 = 0.6; A2 = 1.54; A3 = 1.0
    k1 = (A2 - A3) / A1; k2 = (A3 - A1) / A2; k3 = (A1 - A2) / A3
    w1 = 1; w2 = 1; w3 = 1; h = 0.001; sigma = 1e-3
    print "t,wx,wy,wz"
    for (n = 0; n <= 20000; n++) {
        printf "%.3f,%.6f,%.6f,%.6f\n", n * h, w1 + sigma * g(), w2 + sigma * g(), w3 + sigma * g()
        a1 = k1 * w2 * w3; a2 = k2 * w3 * w1; a3 = k3 * w1 * w2
        x1 = w1 + h/2 * a1; x2 = w2 + h/2 * a2; x3 = w3 + h/2 * a3
        b1 = k1 * x2 * x3; b2 = k2 * x3 * x1; b3 = k3 * x1 * x2
        x1 = w1 + h/2 * b1; x2 = w2 + h/2 * b2; x3 = w3 + h/2 * b3
        c1 = k1 * x2 * x3; c2 = k2 * x3 * x1; c3 = k3 * x1 * x2
        x1 = w1 + h * c1; x2 = w2 + h * c2; x3 = w3 + h * c3
        d1 = k1 * x2 * x3; d2 = k2 * x3 * x1; d3 = k3 * x1 * x2
        w1 += h/6 * (a1 + 2*b1 + 2*c1 + d1)
        w2 += h/6 * (a2 + 2*b2 + 2*c2 + d2)
        w3 += h/6 * (a3 + 2*b3 + 2*c3 + d3)
    }
}
# Standard normal by Box-Muller.
function g(   u, v) { u = rand(); if (u < 1e-12) u = 1e-12; v = rand(); return sqrt(-2 * log(u)) * cos(2 * pi * v) }' > "$csv"

out="$(cargo run -q --release -p identifier-core --example csv -- 1e-3 < "$csv")"
printf '%s\n' "$out"
printf '%s\n' "$out" | awk -v tol="$tol" '
    /^a = / { found = 1
        t[1] = 0.9; t[2] = 0.4 / 1.54; t[3] = -0.94
        for (i = 1; i <= 3; i++) { e = $(i + 2) - t[i]; if (e < 0) e = -e; if (e > tol) bad = 1
            printf "a%d: estimate %s, truth %.6f, error %.2e\n", i, $(i + 2), t[i], e } }
    END { if (!found || bad) { print "example-csv: FAIL (tolerance " tol ")"; exit 1 }
          print "example-csv: estimate within " tol " of the truth" }'
