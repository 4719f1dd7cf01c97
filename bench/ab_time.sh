#!/bin/sh
# Times two commands alternately (one warm-up each, then A B A B ... N times) as whole
# processes with /usr/bin/time, and prints each one's median wall seconds and the median of
# the pairwise ratios A/B with their range: on a shared, noisy machine the ratio of
# neighbouring runs is the figure to quote (docs/performance.md).
#
#   bench/ab_time.sh N 'COMMAND A' 'COMMAND B'
set -eu
N=$1; A=$2; B=$3
OUT=$(mktemp -d)
trap 'rm -rf "$OUT"' EXIT
run() { /usr/bin/time -f %e -o "$OUT/t" sh -c "$1" > /dev/null 2>&1; cat "$OUT/t"; }
run "$A" > /dev/null; run "$B" > /dev/null
i=0
while [ $i -lt "$N" ]; do
  echo "$(run "$A") $(run "$B")" >> "$OUT/pairs"
  i=$((i + 1))
done
python3 - "$OUT/pairs" <<'PY'
import statistics, sys
pairs = [tuple(map(float, l.split())) for l in open(sys.argv[1])]
a, b = zip(*pairs)
r = [x / y for x, y in pairs]
print(f"A median {statistics.median(a):.3f} s, B median {statistics.median(b):.3f} s")
print(f"A/B median {statistics.median(r):.3f} (min {min(r):.3f}, max {max(r):.3f}) over {len(r)} pairs")
PY
