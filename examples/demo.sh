#!/usr/bin/env bash
# The main job of bench, run by `./dev demo`: a complete simulated ISO 9283 pose campaign on the 5-DOF PKM
# (simulator on a pseudo-terminal, simulated mice, every sample stored), analysed, ending in an HTML + PDF report.
set -euo pipefail
out=${1:-demo-out}
bench demo --out "$out"
echo "report and raw data in $out/ (open the .html file in a browser)" >&2
