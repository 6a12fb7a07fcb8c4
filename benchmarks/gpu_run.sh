#!/usr/bin/env bash
# Everything measured on the GPU machine in one go; results under $1 (default $OUT).
#   source .gl/gpu-env.sh && bash benchmarks/gpu_run.sh "$OUT"
# Parts can be skipped: SKIP="tests table sweep lights methods" bash benchmarks/gpu_run.sh DIR
# The real scenes are read from .scenes/ (a git-ignored copy of ../shared/scenes; the hairball is
# generated there first when missing).
set -uo pipefail
out=${1:-$OUT}
mkdir -p "$out/logs"
skip=" ${SKIP:-} "
python3 -m guaca_py info > "$out/logs/info.txt" 2>&1; cat "$out/logs/info.txt"
if [[ $skip != *" tests "* ]]; then
  # the exact-method tests on the NVIDIA variants (64-bit insertion, interlock, conservative raster)
  timeout 240 python3 -m pytest -q -x -p no:cacheprovider tests > "$out/logs/pytest_gpu.txt" 2>&1
  tail -3 "$out/logs/pytest_gpu.txt"
fi
if [[ -f .scenes/make_hairball.py && ! -f .scenes/hairball.ply ]]; then
  (cd .scenes && python3 make_hairball.py . > /dev/null)
fi
if [[ $skip != *" table "* && -d .scenes ]]; then
  timeout 300 python3 benchmarks/paper_table.py "$out/paper_table" 2>&1 | tee "$out/logs/paper_table.txt"
fi
if [[ $skip != *" sweep "* ]]; then
  timeout 150 python3 benchmarks/raster_sweep.py "$out/raster_sweep" 2>&1 | tee "$out/logs/raster_sweep.txt"
fi
# demo scene, 1024x1024: one cold frame, then median of 10 after 3 warm-up
python3 -m guaca_py render --width 1024 --height 1024 --out "$out/logs/demo_cold.png" \
  --stats "$out/logs/demo_1024_cold.json" > "$out/logs/demo_cold.txt" 2>&1
python3 -m guaca_py render --width 1024 --height 1024 --warmup 3 --frames 10 --out "$out/demo_1024.png" \
  --stats "$out/logs/demo_1024_warm.json" 2>&1 | tee "$out/logs/demo_warm.txt"
if [[ $skip != *" lights "* && -f benchmarks/light_culling.py ]]; then
  timeout 240 python3 benchmarks/light_culling.py "$out/lights" --per-process 2>&1 | tee "$out/logs/light_culling.txt"
fi
if [[ $skip != *" methods "* ]]; then
  timeout 300 python3 benchmarks/methods_table.py "$out/methods" 2>&1 | tee "$out/logs/methods.txt"
fi
tar -czf "$out/results.tar.gz" -C "$out" logs $( [ -d "$out/lights" ] && echo lights ) $( [ -d "$out/methods" ] && echo methods ) 2>/dev/null
rm -rf "$out/logs" "$out/lights" "$out/methods"
ls -la "$out"
