#!/bin/sh
# Makes tier (b)'s full-wave channel data: every case of common.CASES at -8, 0, +8 degrees,
# two k-Wave runs at a time, then finalize.py into OUT (default bench/kwave/data).
# Needs a Python with k-wave-python 0.6.2, scipy and matplotlib (README.md); PYTHON selects it.
# Raw runs go to $KWAVE_SCRATCH/raw and are reused when present. 102 runs of 15-150 s each.
set -eu
HERE=$(cd "$(dirname "$0")" && pwd)
OUT=${1:-$HERE/data}
PY=${PYTHON:-python3}
export KWAVE_SCRATCH=${KWAVE_SCRATCH:-$HERE/scratch}
CASES=$($PY -c "import sys; sys.path.insert(0, '$HERE'); from common import CASES; print(' '.join(CASES))")
# Each case's background run first, then the case, geometry by geometry: a partial set is usable.
RUNS=$($PY -c "import sys; sys.path.insert(0, '$HERE'); from common import CASES
order = []
for c, p in CASES.items():
    for r in (p.get('ref'), p.get('raw', c)):
        if r and r not in order:
            order.append(r)
print(' '.join(order))")
JOBS=""
for c in $RUNS; do for a in -8 0 8; do JOBS="$JOBS $c:$a"; done; done
# Two workers, each taking every other job.
set -- $JOBS
A=""; B=""; i=0
for j in "$@"; do if [ $((i % 2)) -eq 0 ]; then A="$A $j"; else B="$B $j"; fi; i=$((i + 1)); done
$PY "$HERE/sim.py" $A & P1=$!
$PY "$HERE/sim.py" $B & P2=$!
wait $P1; wait $P2
FINAL=$($PY -c "import sys; sys.path.insert(0, '$HERE'); from common import CASES; print(' '.join(c for c in CASES if 'ref' in CASES[c]))")
$PY "$HERE/finalize.py" "$OUT" $FINAL
