#!/usr/bin/env bash
# The main job of bench, run by `./dev demo`: a complete simulated ISO 9283 pose campaign on the 5-DOF PKM
# (simulator on a pseudo-terminal, simulated mice, every sample stored), analysed, ending in an HTML + PDF report.
set -euo pipefail
out=${1:-demo-out}
paths=$(bench demo --out "$out")
echo "$paths"
html=$(grep '\.html$' <<<"$paths" | tail -n 1)
pdf=$(grep '\.pdf$' <<<"$paths" | tail -n 1)
cat >&2 <<TEXT
report: $html (and $pdf)
the run is stored in $out/bench.db: bench runs --store $out/bench.db
(bench is installed in .venv: run '. .venv/bin/activate' to have it on your PATH)
TEXT
