#!/usr/bin/env bash
# The main job: the aluminium-bar collapse of Bui et al. (2008), headless, then a picture of it.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh
OUT=${OUT:-out/bui2008}
# --overwrite: this script owns $OUT; a re-run replaces its own earlier results (nothing else)
.venv/bin/runout run projects/examples/bui2008_aluminium_bars.toml --out "$OUT" --overwrite "$@"
.venv/bin/runout render "$OUT" --field displacement -o "$OUT/final_displacement.png"
echo "results: $OUT (particles.pvd opens in ParaView), picture: $OUT/final_displacement.png"
