#!/bin/sh
# Runs `usray diagnose SCENE --measured DATA $FLAGS` on every case of a tier's table and
# prints one line per case: case, expected verdict, verdict, then (round 2 if any), the
# simulation noise share and rays, and the wall time. FLAGS defaults to `--budget 180`,
# the withheld check's command line.
#
#   bench/run_tier.sh CASES.tsv DATA_DIR OUT_DIR [CASE ...]
#
# CASES.tsv: a header line, then `case <TAB> scene <TAB> measured <TAB> expected`, the scene
# relative to the table's folder and the measured data relative to DATA_DIR. USRAY selects the
# binary (default: target/release/usray of this checkout). Only the named cases when given.
set -eu
TABLE=$1; DATA=$2; OUT=$3; shift 3
HERE=$(cd "$(dirname "$0")/.." && pwd)
USRAY=${USRAY:-$HERE/target/release/usray}
FLAGS=${FLAGS:---budget 180}
DIR=$(cd "$(dirname "$TABLE")" && pwd)
mkdir -p "$OUT"
tail -n +2 "$TABLE" | while IFS="$(printf '\t')" read -r case scene measured expected; do
  if [ $# -gt 0 ]; then
    keep=0; for c in "$@"; do [ "$c" = "$case" ] && keep=1; done
    [ $keep -eq 1 ] || continue
  fi
  start=$(date +%s)
  # shellcheck disable=SC2086
  if "$USRAY" diagnose "$DIR/$scene" --measured "$DATA/$measured" $FLAGS --out "$OUT/$case" --quiet \
      2> "$OUT/$case.log"; then
    python3 - "$OUT/$case/diagnosis.json" "$case" "$expected" "$(( $(date +%s) - start ))" <<'PY'
import json, sys
d = json.load(open(sys.argv[1]))
rounds = [r["verdict"]["effect"] for r in d["rounds"]]
nc = d["noise_check"]
print("\t".join([sys.argv[2], sys.argv[3], rounds[0], ",".join(rounds[1:]) or "-",
                 f"{nc['share']:.2f}@{nc['rays']}", sys.argv[4] + "s"]), flush=True)
PY
  else
    printf '%s\t%s\tERROR\t-\t-\t%ss\n' "$case" "$expected" "$(( $(date +%s) - start ))"
  fi
done
