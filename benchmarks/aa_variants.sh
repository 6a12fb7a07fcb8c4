#!/usr/bin/env bash
# Where the dragons' 4-sample time goes: the anti-aliasing cost (benchmarks/aa_cost.py, stage times on)
# of the default frame, of the same frame without A-buffer insertion (GUACA_SKIP_INSERTION=1: the
# rasterizer's own cost) and of presort_lf (no early termination: its depth order runs back to front,
# its `auto` order is by screen tile) in both orders, at 1 and 4 samples:
#   source .gl/gpu-env.sh && bash benchmarks/aa_variants.sh "$OUT"      # ~1 min on the H100
# SCENES="dragons hairball_v1" picks other scenes of .scenes/; ONLY="base skip_insertion" runs only those variants.
set -uo pipefail
out=${1:-$OUT}
work=/tmp/aa_variants
mkdir -p "$work" "$out"
run() {  # name, VAR=value..., --, aa_cost.py arguments
  local name=$1
  shift
  [[ -n ${ONLY:-} && " $ONLY " != *" $name "* ]] && return 0
  local envs=()
  while [[ $1 != -- ]]; do
    envs+=("$1")
    shift
  done
  shift
  env GUACA_RASTER_STAGES=1 "${envs[@]}" timeout 150 python3 benchmarks/aa_cost.py "$work/$name" --scenes .scenes \
    --scene-names ${SCENES:-dragons} "$@" > "$work/$name.log" 2>&1
  echo "== $name"
  grep -E "^\| (dragons|sponza|hairball)" "$work/$name/aa_cost.md" | cut -c1-200
  tar -czf "$out/aa_variants.tgz" -C "$work" .
}
run base GUACA_SKIP_INSERTION=0 -- --samples 1 4
run skip_insertion GUACA_SKIP_INSERTION=1 -- --samples 1 4
run presort_lf GUACA_SKIP_INSERTION=0 -- --samples 1 4 --method presort_lf --raster auto auto/depth
