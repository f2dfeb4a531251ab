#!/usr/bin/env bash
# Times `trazo render` on the built-in default scene (Cornell box, 512×512,
# 64 spp, path tracer with MIS, max depth 8) and prints the median wall time of N runs (default 5),
# with the renderer's own samples/s and rays/s from the median run.
# Usage: bench/default-scene.sh [runs] [extra trazo flags...]
set -euo pipefail
cd "$(dirname "$0")/.."
runs=${1:-5}
shift || true
cargo build --release --quiet
out=$(mktemp -d)
trap 'rm -rf "$out"' EXIT
for i in $(seq "$runs"); do
    start=$(date +%s.%N)
    ./target/release/trazo render -o "$out/x.png" "$@" 2>"$out/log$i"
    end=$(date +%s.%N)
    awk -v s="$start" -v e="$end" -v i="$i" 'BEGIN { printf "%.3f %d\n", e - s, i }'
done | sort -n > "$out/times"
median_line=$(sed -n "$(( (runs + 1) / 2 ))p" "$out/times")
median=${median_line% *}
idx=${median_line#* }
echo "cores: $(nproc)"
echo "median wall time of $runs runs: ${median} s"
tail -n 1 "$out/log$idx"
