#!/usr/bin/env bash
# Anti-aliasing cost on the dragons under insertion variants (env knobs), one aa_cost.py run each:
#   source .gl/gpu-env.sh && bash benchmarks/aa_variants.sh "$OUT"
set -uo pipefail
out=${1:-$OUT}
work=/tmp/aa_variants
mkdir -p "$work" "$out"
run() {  # name, env..., -- samples...
  local name=$1; shift
  local envs=()
  while [[ $1 != -- ]]; do envs+=("$1"); shift; done
  shift
  env GUACA_RASTER_STAGES=1 "${envs[@]}" timeout 120 python3 benchmarks/aa_cost.py "$work/$name" --scenes .scenes \
    --scene-names ${SCENES:-dragons} --samples "$@" > "$work/$name.log" 2>&1
  echo "== $name"; grep -E "^\| (dragons|sponza|hairball)" "$work/$name/aa_cost.md" | cut -c1-200
  tar -czf "$out/aa_variants.tgz" -C "$work" .
}
run base X=0 -- 1 4
run no_insert GUACA_EXP_NO_INSERT=1 -- 1 4
run b2f GUACA_EXP_BACK_TO_FRONT=1 -- 1 4
run merge GUACA_SURFACE_MERGE=1 -- 4
run merge_b2f GUACA_SURFACE_MERGE=1 GUACA_EXP_BACK_TO_FRONT=1 -- 4
run merge_cos099 GUACA_SURFACE_MERGE=1 GUACA_MERGE_COS=0.99 -- 4
run merge_cos09_b2f GUACA_SURFACE_MERGE=1 GUACA_MERGE_COS=0.9 GUACA_EXP_BACK_TO_FRONT=1 -- 4
