#!/usr/bin/env bash
# make demo: the main job on its embedded default. Simulates a measurement of the built-in moving scene (the
# simulator's embedded default: textured disc and polygon moving over a textured background, random masks, no
# effects) and reconstructs it, printing PSNR, timings and where the outputs are.
set -euo pipefail
bin=${BUILD:-build}
out=$(mktemp -d /tmp/scicap-demo-XXXXXX)
echo "== scicap demo: outputs in $out"
t0=$EPOCHREALTIME
"$bin/scicap" sim --default -o "$out/measurement"
t1=$EPOCHREALTIME
"$bin/scicap" recon --method gap-tv "$out/measurement" -o "$out/recon"
t2=$EPOCHREALTIME
awk -v a="$t0" -v b="$t1" -v c="$t2" 'BEGIN { printf "== simulate %.2f s, reconstruct %.2f s (including file I/O)\n", b - a, c - b }'
echo "== truth, masks and measurement: $out/measurement/   reconstruction: $out/recon/ (frame_*.exr, preview_*.png, preview.gif, trace.csv)"
