#!/usr/bin/env bash
# The frame loop in two trees, alternating, each run in its own process (a loop's pace differs from
# process to process): a base tree in ab_base/ (git archive of the base commit, with this tree's
# benchmarks/loop_profile.py and paper_table.py) and this tree.
#   source .gl/gpu-env.sh && ROUNDS=3 bash benchmarks/ab_loop.sh OUT [scene ...]
set -uo pipefail
out=$1; shift
scenes=${*:-dragons sponza_dabrovic_v1 sponza_dabrovic_v2}
mkdir -p "$out"
here=$PWD
for k in $(seq "${ROUNDS:-2}"); do
  for side in base new; do
    root=$here; [ "$side" = base ] && root=$here/ab_base
    (cd "$root" && timeout 200 python3 benchmarks/loop_profile.py "$out/${side}_$k" --scenes "$here/.scenes" \
      --scene-names $scenes --loops "${LOOPS:-2}" 2>&1 | grep -v wrote)
  done
done
