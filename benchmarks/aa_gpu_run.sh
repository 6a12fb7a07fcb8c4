#!/usr/bin/env bash
# Anti-aliasing benchmarks on the GPU machine (docs/antialiasing.md), 1024², results under $1:
#   $1/accuracy_scenes/<scene>/accuracy.{json,md,png}   speed against error, every scene
#   $1/temporal_stability/<scene>/stability.{json,md}    60-frame camera path
#
#   source .gl/gpu-env.sh && bash benchmarks/aa_gpu_run.sh "$OUT"                 # reduced, ~4 min
#   source .gl/gpu-env.sh && PART=accuracy FULL=1 bash benchmarks/aa_gpu_run.sh "$OUT"
#   source .gl/gpu-env.sh && PART=stability FULL=1 bash benchmarks/aa_gpu_run.sh "$OUT"
#
# Reduced: a representative method set (one-pass A-buffers, counted storage, multi-layer peeling,
# every approximate method) and presort_lf_et at 1/2/4/8 samples on the three Table 1 scenes;
# stability on the dragons only. FULL=1: every method the device runs, stability on every scene
# (each PART stays under 10 minutes). The scenes are read from .scenes/ (a git-ignored copy of
# ../shared/scenes); FLIP is reported where flip-evaluator is installed (pip install ".[accuracy]").
set -uo pipefail
out=${1:-$OUT}
part=${PART:-all}
scenes=${SCENES:-.scenes}
names="dragons sponza_dabrovic_v1 sponza_dabrovic_v2"
mkdir -p "$out"
if [[ -n "${FULL:-}" ]]; then
  methods=()
  stab_scenes=$names
else
  methods=(--methods presort_lf_et presort_lf presort_lf_merge2_et presort_cs_et post_sort dfb
           multilayer_depth_peeling unsorted_blend object_sorted_blend weighted_blended stochastic kbuffer)
  stab_scenes="dragons"
fi
if [[ $part == all || $part == accuracy ]]; then
  timeout 540 python3 benchmarks/accuracy_scenes.py "$out/accuracy_scenes" --scenes "$scenes" \
    --scene-names $names --size 1024 --ref-k 8 --frames 5 --warmup 2 "${methods[@]}" \
    2>&1 | tee "$out/accuracy_scenes.log"
fi
if [[ $part == all || $part == stability ]]; then
  args=()
  for s in $stab_scenes; do args+=(--scene "$scenes/$s.yaml"); done
  timeout 540 python3 benchmarks/temporal_stability.py "$out/temporal_stability" "${args[@]}" --size 1024 \
    --frames 60 --samples 4 8 "${methods[@]}" 2>&1 | tee "$out/temporal_stability.log"
fi
ls -R "$out" | head -40
