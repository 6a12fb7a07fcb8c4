#!/usr/bin/env bash
# Anti-aliasing benchmarks on the GPU machine (docs/antialiasing.md), 1024², results under $1:
#   $1/accuracy_scenes/<scene>/accuracy.{json,md,png}   speed against error
#   $1/temporal_stability/<scene>/stability.{json,md}    60-frame camera path
#
#   source .gl/gpu-env.sh && PART=accuracy bash benchmarks/aa_gpu_run.sh "$OUT"
#   source .gl/gpu-env.sh && PART=stability SCENES_SUBSET="dragons sponza_dabrovic_v1 sponza_dabrovic_v2" \
#       bash benchmarks/aa_gpu_run.sh "$OUT"
#   source .gl/gpu-env.sh && PART=stability SCENES_SUBSET="hairball_v1 hairball_v2" bash benchmarks/aa_gpu_run.sh "$OUT"
#
# Scenes: dragons, sponza_dabrovic_v1/v2, hairball_v1/v2 (SCENES_SUBSET picks some), read from .scenes/
# (a git-ignored copy of ../shared/scenes; the hairball mesh and views are generated there when missing,
# ~55 MB, a few seconds). FLIP is reported where flip-evaluator is installed (pip install ".[accuracy]";
# on a machine without network, its wheel in .whl/: see docs/antialiasing.md).
#
# Methods. Dragons and Sponza: a representative set (one-pass A-buffers, counted storage, multi-layer
# peeling, every approximate method); FULL=1: every method the device runs. Hairballs (15.6M and 59.8M
# transparent fragments at 1024²; peeling and counted storage take hundreds of ms to seconds a frame):
# the one-pass A-buffers, unsorted_blend and weighted_blended, also with FULL=1. Accuracy: presort_lf_et at
# 1/2/4/8 samples first, then the methods; stability: presort_lf_et, then 4 and 8 samples (hairballs: 4),
# then the rest.
#
# PART=all (the default) runs both parts one after the other, each with its own deadline (~11 min in all:
# more than one 10-minute slot).
#
# Time. Each scene has a budget (--scene-budget-s, reference included): configurations after it is spent
# are recorded as skipped, so a PART ends within its deadline (PART_S, default 540 s) whatever a scene
# costs; a run killed at the deadline keeps the scenes it finished (their tables are rebuilt afterwards).
# Estimates from the H100 figures of benchmarks/results/h100/final/paper_table_hardware.md (1980 MHz):
#   accuracy, per configuration: ~0.3 s set-up and first frame, 1.5 s warm-up, 5 timed frames with
#     read-back (>= 0.3 s), errors ~0.2 s: ~2.3 s + 5 frames, +1.8 s per clock retry (the first few
#     configurations of a scene, after the CPU-bound reference let the clock drop).
#     dragons: reference 8x in 16 tiles of 2048² ~7 s (16 x ~0.4 s: 7M fragments, read-back, box filter),
#       16 configurations ~40 s, retries ~6 s, loading 3 s: ~56 s (budget 90 s)
#     sponza v1, v2: reference ~7 s, 16 configurations ~40 s: ~47 s each (budget 90 s each)
#     hairball_v1: reference 8x in 256 tiles of 512² (a central 1024² tile would hold ~65M fragments,
#       at the 2 GiB pool's ~67M nodes): presort_lf 64 x 171 ms = 11 s GPU + ~8 s per-tile overhead;
#       10 configurations (frames 8-300 ms) ~30 s; loading 3 s: ~55 s (budget 100 s)
#     hairball_v2: reference 8x, 256 tiles of 512²: 64 x 489 ms = 31 s GPU + 8 s; 4 and 8 samples keep
#       partly covering fragments that early termination cannot cull (llvmpipe at 48²: 7x the 1-sample
#       count), so assume presort_lf's ~60M fragments and ~0.5-1 s frames (their first frame grows the
#       pool: a few re-renders; a first frame over 3 s is timed once); the sample counts ~25 s, the six
#       methods (23-500 ms) ~17 s, retries ~5 s; loading 3 s: ~90 s (budget 130 s)
#     all five: ~5 min + start-up and hairball generation ~20 s (at most 9 min: budgets and deadline)
#   stability, per configuration: 64 frames (60 + 4 repeated) x (frame + ~40 ms read-back and
#     differences); reference 2x per pose, box filtered (~0.3 s of CPU per pose):
#     dragons: reference 60 x 0.35 s = 21 s, 9 configurations ~45 s: ~70 s (budget 120 s)
#     sponza v1, v2: ~60 s each (budget 120 s each)                 -> first three scenes: ~3.5 min
#     hairball_v1: reference 60 x (4 tiles of 1024², 0.7 s GPU, 0.35 s CPU) = 63 s, 4 configurations
#       (4 samples ~0.15 s a frame: 12 s) ~30 s: ~95 s (budget 150 s)
#     hairball_v2: reference 60 x (16 tiles of 512², 2 s GPU, 0.8 s other) = 165 s, 4 configurations:
#       4 samples 64 x ~0.9 s = 58 s, the rest ~20 s: ~245 s (budget 280 s) -> hairballs: ~6 min
#     all five in one PART (~9.5 min) would not fit: hence the two commands above.
set -uo pipefail
out=${1:-$OUT}
part=${PART:-all}
scenes=${SCENES:-.scenes}
subset=" ${SCENES_SUBSET:-dragons sponza_dabrovic_v1 sponza_dabrovic_v2 hairball_v1 hairball_v2} "
mkdir -p "$out"
if [[ $subset == *" hairball_"* && -f $scenes/make_hairball.py ]]; then
  if [[ ! -f $scenes/hairball.ply || ! -f $scenes/hairball_v1.yaml || ! -f $scenes/hairball_v2.yaml ]]; then
    (cd "$scenes" && python3 make_hairball.py . > /dev/null)
  fi
fi

# the scenes of $1 (space-separated) that SCENES_SUBSET asks for
pick() { local s picked=(); for s in $1; do [[ $subset == *" $s "* ]] && picked+=("$s"); done; echo "${picked[*]}"; }

# seconds left before the deadline
left() { echo $((deadline - SECONDS)); }

accuracy() {  # scenes, budget per scene, then options
  local names budget=$2
  names=$(pick "$1"); shift 2
  [[ -n $names ]] || return 0
  (($(left) > 30)) || { echo "accuracy: no time left for $names"; return 0; }
  timeout "$(left)" python3 benchmarks/accuracy_scenes.py "$out/accuracy_scenes" --scenes "$scenes" \
    --scene-names $names --size 1024 --ref-k 8 --frames 5 --warmup 2 --warmup-s 1.5 --scene-budget-s "$budget" \
    "$@" 2>&1 | tee -a "$out/accuracy_scenes.log"
}

stability() {  # scenes, budget per scene, then options
  local names budget=$2 s args=()
  names=$(pick "$1"); shift 2
  [[ -n $names ]] || return 0
  (($(left) > 30)) || { echo "stability: no time left for $names"; return 0; }
  for s in $names; do args+=(--scene "$scenes/$s.yaml"); done
  timeout "$(left)" python3 benchmarks/temporal_stability.py "$out/temporal_stability" "${args[@]}" --size 1024 \
    --frames 60 --scene-budget-s "$budget" "$@" 2>&1 | tee -a "$out/temporal_stability.log"
}

if [[ -n "${FULL:-}" ]]; then
  acc_methods=()
  stab_methods=()
else
  acc_methods=(--methods presort_lf_et presort_lf presort_lf_merge2_et presort_cs_et post_sort dfb
               multilayer_depth_peeling unsorted_blend object_sorted_blend weighted_blended stochastic kbuffer)
  stab_methods=(--methods presort_lf_et presort_lf_merge2_et multilayer_depth_peeling kbuffer
                unsorted_blend weighted_blended stochastic)
fi
hair_acc=(--methods presort_lf_et unsorted_blend weighted_blended presort_lf_merge2_et presort_cs_et post_sort)
hair_stab=(--methods presort_lf_et unsorted_blend weighted_blended)

if [[ $part == all || $part == accuracy ]]; then
  deadline=$((SECONDS + ${PART_S:-540}))
  accuracy "dragons sponza_dabrovic_v1 sponza_dabrovic_v2" 90 "${acc_methods[@]}"
  accuracy "hairball_v1" 100 --tile 512 "${hair_acc[@]}"
  accuracy "hairball_v2" 130 --tile 512 "${hair_acc[@]}"
  python3 benchmarks/accuracy_scenes.py "$out/accuracy_scenes" --scenes "$scenes" --replot > /dev/null
fi
if [[ $part == all || $part == stability ]]; then
  deadline=$((SECONDS + ${PART_S:-540}))
  stability "dragons sponza_dabrovic_v1 sponza_dabrovic_v2" 120 --samples 4 8 "${stab_methods[@]}"
  stability "hairball_v1" 150 --tile 1024 --samples 4 "${hair_stab[@]}"
  stability "hairball_v2" 280 --tile 512 --samples 4 "${hair_stab[@]}"
  python3 benchmarks/temporal_stability.py "$out/temporal_stability" --replot > /dev/null
fi
ls -R "$out" | head -40
