#!/usr/bin/env bash
# The GPU measurements the last changes still wait for, in calls of under 10 minutes each; results
# in one archive $1/pending_<part>.tgz (the GPU machine returns few files).
#   source .gl/gpu-env.sh && PART=a bash benchmarks/pending_gpu_checks.sh "$OUT"       # ~6 min
#   source .gl/gpu-env.sh && PART=b bash benchmarks/pending_gpu_checks.sh "$OUT"       # ~6 min
#   source .gl/gpu-env.sh && PART=order bash benchmarks/pending_gpu_checks.sh "$OUT"   # ~8 min
# a: the whole test suite on the NVIDIA variants (after `auto` took the tile order: ~2 min), then
#    Table 1 with raster: auto (~2.5 min: loop wall after the blending methods stopped waiting for
#    their samples query mid-frame), then anti-aliasing cost on the dragons (~15 s), then the
#    compute rasterizer's time per stage (GUACA_RASTER_STAGES=1) on the dragons and hairball_v2 (~40 s),
#    then the dragons' AA cost in each triangle order (~40 s)
# b: hairball_v2's temporal stability (~5.5 min), the one scene not yet run on the GPU
# c: the suite (after the 64-bit walk took plain loads), that walk against the atomic one (GUACA_ATOMIC_WALK=1)
#    by aa_cost on four scenes at 1 and 4 samples (~2.5 min), then benchmarks/frame_gaps.py (~2 min)
# d: Table 1 with raster: auto (~2.5 min; loop GPU time and idle time from timestamps), then the hairballs'
#    accuracy with FLIP (~4.5 min)
# e: Table 1's loop rows of the dragons and hairball_v2 over 24 and 96 frames (~2 min)
# f: the compute rasterizer's stages, the time between draws and outside it (~1 min)
# h: the suite, Table 1 with raster: auto, then the compute rasterizer's stages on the dragons,
#    Sponza v1 and hairball_v2 at 1 and 4 samples (~6 min; after the order stage's changes and the
#    fenced late counters)
# i: as h at the final one-thread bounds (128 px, 16 px²), then the area bound through 8, 16 px² and
#    none at 1 and 4 samples on the dragons, Sponza v2 and hairball_v2 (~7 min): what this round
#    could not run for lack of device time
# j1: the suite and Table 1 with raster: auto (~5 min); j2: the compute rasterizer's stages at 1 and 4
#    samples, the dragons at 1 and 4 samples (at 75fbdc5 also in a back_to_front order, since taken
#    out), the dragons' edge error at 1 and 4 samples, the area bound through 8, 16 px² and none (~5 min)
# k1: Table 1 and the anti-aliasing cost with stage times on four scenes (~3 min); k2: the suite and the
#    dragons' temporal stability (~4 min); both first ran at 82f719b, with a rule for `auto`'s depth
#    direction that was reverted after (benchmarks/results/h100/adaptive_order_1c671c8/)
# merge: the suite, antialiasing.merge: adjacent against unmerged 4 samples on every real scene (cost, stages),
#    then benchmarks/aa_merge.py's stored fragments and error on the dragons and Sponza v1 (~6 min)
# order: the suite, then the compute rasterizer's triangle orders (depth, mesh, tile) per method and
#    scene (benchmarks/results/h100/raster_order/orders.md)
set -uo pipefail
out=${1:-$OUT}
work=/tmp/pending
mkdir -p "$work" "$out"
if [[ -f .scenes/make_hairball.py && ! -f .scenes/hairball.ply ]]; then
  (cd .scenes && python3 make_hairball.py . > /dev/null)
fi
part=${PART:-a}
# packed after every step: a call cut at its time limit still returns what was measured
pack() { tar -czf "$out/pending_$part.tgz" -C "$work" .; }
# the whole test suite on the NVIDIA variants
suite() {
  timeout 200 python3 -m pytest -q -p no:cacheprovider tests > "$work/pytest_gpu.txt" 2>&1
  tail -3 "$work/pytest_gpu.txt"
  pack
}
# the compute rasterizer's time per stage, with the time between draws and outside the rasterizer
stages() {
  GUACA_RASTER_STAGES=1 timeout 120 python3 benchmarks/aa_cost.py "$work/raster_stages" --scenes .scenes \
    --scene-names dragons sponza_dabrovic_v1 hairball_v2 --samples 1 4 2>&1 | tail -2
  tail -12 "$work/raster_stages/aa_cost.md"
  pack
}
# Table 1 with raster: auto; $1: how many lines of its log to show
table() {
  timeout 240 python3 benchmarks/paper_table.py "$work/paper_table" --raster auto 2>&1 | grep -v "^\s*$" \
    > "$work/paper_table_log.txt"
  tail -"$1" "$work/paper_table_log.txt"
  pack
}
if [[ $part == a ]]; then
  suite
  table 12
  timeout 60 python3 benchmarks/aa_cost.py "$work/aa_cost" --scenes .scenes --scene-names dragons --samples 1 4 2>&1 | tail -3
  # where the compute rasterizer's time goes, stage by stage (dragons' x10 target, its AA cost; hairball_v2)
  GUACA_RASTER_STAGES=1 timeout 90 python3 benchmarks/aa_cost.py "$work/raster_stages" --scenes .scenes \
    --scene-names dragons hairball_v2 --samples 1 4 2>&1 | tail -3
  # the dragons store 3.1x the fragments at 4 samples and early termination culls ~2 % of them there:
  # does an order with cheaper insertion (index or back to front) pay at 4 samples?
  timeout 60 python3 benchmarks/aa_cost.py "$work/aa_cost_orders" --scenes .scenes --scene-names dragons \
    --samples 1 4 --raster compute/depth compute/mesh compute/tile 2>&1 | tail -3
elif [[ $part == b ]]; then
  PART=stability PART_S=340 SCENES_SUBSET="hairball_v2" bash benchmarks/aa_gpu_run.sh "$work/aa" \
    > "$work/aa_stability.txt" 2>&1
  tail -8 "$work/aa_stability.txt"
elif [[ $part == c ]]; then
  suite
  # the 64-bit list walk: a plain load per node passed (default) against an atomicMax per node
  for walk in 0 1; do
    GUACA_ATOMIC_WALK=$walk timeout 100 python3 benchmarks/aa_cost.py "$work/walk_atomic$walk" --scenes .scenes \
      --scene-names dragons sponza_dabrovic_v1 hairball_v1 hairball_v2 --samples 1 4 2>&1 | tail -2
    pack
  done
  # where the frame loop's wall time beyond the GPU's goes: gaps between frames, per pass GPU span / CPU
  timeout 200 python3 benchmarks/frame_gaps.py "$work/frame_gaps" \
    --methods presort_lf_et presort_cs unsorted_blend multilayer_depth_peeling 2>&1 | tail -25
elif [[ $part == d ]]; then
  table 12
  # the hairballs' speed against error with FLIP (the first H100 tables were made without flip-evaluator)
  PART=accuracy PART_S=280 SCENES_SUBSET="hairball_v1 hairball_v2" bash benchmarks/aa_gpu_run.sh "$work/aa" \
    > "$work/aa_accuracy.txt" 2>&1
  tail -8 "$work/aa_accuracy.txt"
elif [[ $part == e ]]; then
  # is the loop wall's excess over the loop's GPU time on hairball_v2's non-ET rows (up to +1.06 ms
  # over 24 frames) paid once per loop or per frame? The same rows over 24 and 96 frames
  for n in 24 96; do
    timeout 200 python3 benchmarks/paper_table.py "$work/loop$n" --raster auto --skip-stacks --loop-frames $n \
      --only dragons hairball_v2 --methods presort_lf_et presort_lf post_sort presort_cs_et 2>&1 | tail -9
    pack
  done
elif [[ $part == f ]]; then
  stages
elif [[ $part == h ]]; then
  suite
  table 3
  stages
elif [[ $part == i ]]; then
  suite
  table 3
  stages
  pack
  timeout 150 python3 benchmarks/aa_cost.py "$work/frag4" --scenes .scenes --samples 1 4 --small-fragments 8 16 1e9 \
    --scene-names dragons sponza_dabrovic_v2 hairball_v2 2>&1 | tail -1
elif [[ $part == j1 ]]; then
  suite
  table 3
elif [[ $part == j2 ]]; then
  stages
  # the dragons at 1 and 4 samples (at 75fbdc5 also with --raster auto/back_to_front, an order taken out since)
  timeout 200 python3 benchmarks/aa_cost.py "$work/aa_orders" --scenes .scenes --samples 1 4 --raster auto 2>&1 | tail -1
  tail -22 "$work/aa_orders/aa_cost.md" | head -22
  pack
  # the dragons' edge error at 1 and 4 samples against the 8x8-supersampled exact frame
  timeout 120 python3 benchmarks/accuracy_scenes.py "$work/accuracy" --scenes .scenes --scene-names dragons \
    --methods presort_lf_et --samples 1 4 2>&1 | tail -4
  pack
  timeout 150 python3 benchmarks/aa_cost.py "$work/frag4" --scenes .scenes --samples 1 4 --small-fragments 8 16 1e9 \
    --scene-names dragons sponza_dabrovic_v2 hairball_v2 2>&1 | tail -1
elif [[ $part == k1 ]]; then
  table 3
  GUACA_RASTER_STAGES=1 timeout 120 python3 benchmarks/aa_cost.py "$work/aa_auto" --scenes .scenes --samples 1 4 \
    --scene-names dragons sponza_dabrovic_v1 hairball_v1 hairball_v2 2>&1 | tail -1
  grep -E "^\| (dragons|sponza|hairball)" "$work/aa_auto/aa_cost.md" | head -8
elif [[ $part == k2 ]]; then
  suite
  PART=stability PART_S=200 SCENES_SUBSET="dragons" bash benchmarks/aa_gpu_run.sh "$work/aa" > "$work/aa_stability.txt" 2>&1
  tail -6 "$work/aa_stability.txt"
elif [[ $part == merge ]]; then
  # antialiasing.merge: adjacent (not yet run on a GPU): the suite (its setup kernels build on NVIDIA),
  # the 4-sample cost merged and not on every real scene, then the dragons' and Sponza v1's error
  suite
  GUACA_RASTER_STAGES=1 timeout 200 python3 benchmarks/aa_cost.py "$work/aa_merge_cost" --scenes .scenes \
    --scene-names dragons sponza_dabrovic_v1 sponza_dabrovic_v2 hairball_v1 hairball_v2 --samples 1 4 \
    --merge off adjacent 2>&1 | tail -1
  grep -E "^\| (dragons|sponza|hairball)" "$work/aa_merge_cost/aa_cost.md" | head -15
  pack
  timeout 200 python3 benchmarks/aa_merge.py "$work/aa_merge" --scenes .scenes \
    --scene-names dragons sponza_dabrovic_v1 2>&1 | tail -8
elif [[ $part == order ]]; then
  timeout 200 python3 -m pytest -q -p no:cacheprovider tests > "$work/pytest_gpu.txt" 2>&1
  tail -3 "$work/pytest_gpu.txt"
  timeout 330 python3 benchmarks/paper_table.py "$work/paper_table_order" --skip-stacks \
    --raster compute/depth compute/mesh compute/tile \
    --methods presort_lf_et presort_lf presort_cs_et post_sort post_merge16 2>&1 | grep -v "^\s*$" | tail -80
fi
pack
ls -la "$out"
