#!/usr/bin/env bash
# The GPU measurements the last changes still wait for, in two calls of under 10 minutes each;
# results in one archive $1/pending_<part>.tgz (the GPU machine returns few files).
#   source .gl/gpu-env.sh && PART=a bash benchmarks/pending_gpu_checks.sh "$OUT"   # 1-3, ~7 min
#   source .gl/gpu-env.sh && PART=b bash benchmarks/pending_gpu_checks.sh "$OUT"   # 4, ~5 min
#   source .gl/gpu-env.sh && PART=order bash benchmarks/pending_gpu_checks.sh "$OUT"   # 5, ~8 min
# 1. the whole test suite on the NVIDIA variants (~2-3 min; peeling's interlock path included)
# 2. anti-aliasing cost, 1 against 4 samples, pass by pass: dragons and hairball_v1 (~1 min;
#    exact compute-raster boxes and per-sample edge increments)
# 3. paper_table rows of the methods whose defaults changed: presort_cs_et (spin lock with the
#    compute rasterizer), post_sort and post_merge16 (index order), with unsorted_blend and
#    presort_lf_et beside them, on both hairballs and the dragons (~2 min)
#    and hairball_v2 with presort_lf and post_sort in both compute triangle orders (raster_order)
# 4. hairball_v2's accuracy table and chart (~2 min), then temporal stability of Sponza (~2.5 min)
# 5. the suite, then the compute rasterizer's triangle orders (depth, mesh, tile) per method and scene
set -uo pipefail
out=${1:-$OUT}
work=/tmp/pending
mkdir -p "$work" "$out"
if [[ -f .scenes/make_hairball.py && ! -f .scenes/hairball.ply ]]; then
  (cd .scenes && python3 make_hairball.py . > /dev/null)
fi
part=${PART:-a}
if [[ $part == a ]]; then
  timeout 200 python3 -m pytest -q -x -p no:cacheprovider tests > "$work/pytest_gpu.txt" 2>&1
  tail -3 "$work/pytest_gpu.txt"
  timeout 90 python3 benchmarks/aa_cost.py "$work/aa_cost" --scenes .scenes --scene-names dragons hairball_v1 \
    --samples 1 4 2>&1 | tail -5
  timeout 150 python3 benchmarks/paper_table.py "$work/paper_table" --skip-stacks --raster compute hardware \
    --only dragons hairball_v1 hairball_v2 \
    --methods presort_lf_et presort_cs_et post_sort post_merge16 unsorted_blend 2>&1 | grep -v "^\s*$" | tail -32
  # the compute rasterizer's triangle order against the composite's memory locality, hairball_v2
  for run in "presort_lf depth" "presort_lf mesh" "post_sort depth" "post_sort mesh"; do
    set -- $run
    timeout 60 python3 -m guaca_py render .scenes/hairball_v2.yaml --method "$1" --set raster=compute \
      --set raster_order="$2" --width 1024 --height 1024 --warmup 20 --frames 8 --out "$work/hb2_$1_$2.png" \
      --stats "$work/hb2_$1_$2.json" 2>&1 | tail -2
  done
elif [[ $part == order ]]; then
  # the compute rasterizer's triangle order (transparency.raster_order) against every method that
  # takes compute fragments, on every scene (~5 min), after the whole suite (~2 min)
  timeout 200 python3 -m pytest -q -p no:cacheprovider tests > "$work/pytest_gpu.txt" 2>&1
  tail -3 "$work/pytest_gpu.txt"
  timeout 330 python3 benchmarks/paper_table.py "$work/paper_table_order" --skip-stacks \
    --raster compute/depth compute/mesh compute/tile \
    --methods presort_lf_et presort_lf presort_cs_et post_sort post_merge16 2>&1 | grep -v "^\s*$" | tail -80
else
  PART=accuracy PART_S=130 SCENES_SUBSET="hairball_v2" bash benchmarks/aa_gpu_run.sh "$work/aa" \
    > "$work/aa_accuracy.txt" 2>&1
  PART=stability PART_S=150 SCENES_SUBSET="sponza_dabrovic_v1 sponza_dabrovic_v2" \
    bash benchmarks/aa_gpu_run.sh "$work/aa" > "$work/aa_stability.txt" 2>&1
  tail -4 "$work/aa_accuracy.txt" "$work/aa_stability.txt"
fi
tar -czf "$out/pending_$part.tgz" -C "$work" .
ls -la "$out"
