#!/usr/bin/env bash
# make demo: the main job as it runs on a lab bench, on the simulator. Starts scicapd on the simulated bench
# (embedded default scene, no configuration) in a temporary folder, captures one snapshot and reconstructs it
# through the socket with `scicap`, prints PSNR, timings and where the outputs are, and stops the daemon.
set -euo pipefail
bin=${BUILD:-build}
dir=$(mktemp -d /tmp/scicap-demo-XXXXXX)
export SCICAP_SOCKET=$dir/control.sock
echo "== scicap demo: scicapd on the simulated bench, outputs in $dir"
# as root outside systemd the daemon wants --allow-root (docs/man/scicapd.8)
"$bin/scicapd" --no-config --socket "$SCICAP_SOCKET" --storage "$dir/store" --runtime-dir "$dir/run" \
    $( [ "$(id -u)" = 0 ] && echo --allow-root ) 2> "$dir/scicapd.log" &
pid=$!
trap 'kill $pid 2>/dev/null || true' EXIT
for _ in $(seq 100); do [ -S "$SCICAP_SOCKET" ] && break; sleep 0.1; done
[ -S "$SCICAP_SOCKET" ] || { echo "scicapd did not start:"; cat "$dir/scicapd.log"; exit 1; }
"$bin/scicap" devices | sed -n '1,12p'
t0=$EPOCHREALTIME
"$bin/scicap" capture --recon --method gap-tv --preset default --wait | tee "$dir/capture.txt"
t1=$EPOCHREALTIME
cap=$(sed -n 's/.*stored \(c[0-9]*\) .*/\1/p' "$dir/capture.txt" | head -1)
psnr=$(sed -n 's/.*PSNR \([0-9.]*\) dB.*/\1/p' "$dir/capture.txt" | tail -1)
"$bin/scicap" shutdown >/dev/null
wait $pid || true
trap - EXIT
awk -v a="$t0" -v b="$t1" -v p="$psnr" 'BEGIN { printf "== PSNR %s dB; capture + store + reconstruct %.2f s through the socket\n", p, b - a }'
echo "== capture folder: $dir/store/captures/$cap/ (raw.tif, meta.json, masks, problem.json)"
echo "== reconstruction: $dir/store/captures/$cap/recon/gap-tv/ (frame_*.exr, preview_*.png, preview.gif, trace.csv)"
echo "== daemon log: $dir/scicapd.log"
