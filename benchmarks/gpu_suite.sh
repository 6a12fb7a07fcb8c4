#!/usr/bin/env bash
# The GPU suite in calls of the GPU machine of under 10 minutes each; every benchmark writes its
# folder in place under benchmarks/results/<device>/ (h100 on an NVIDIA H100):
#     bash benchmarks/gpu_suite.sh [COPY_TO]                                   # the tests
#     PARTS="paper_table aa_cost scaling" bash benchmarks/gpu_suite.sh [COPY_TO]   # the tables the issues read
# COPY_TO (the machine's "$OUT", say): the device's results folder packed into COPY_TO/gpu_suite.tgz
# (the machine hands back few files; unpack it at the project root here) and the logs into
# COPY_TO/gpu_suite_logs.tgz.
#
# Needs, beside the checkout (git-ignored; carry them to the machine): .gl/ and .whl/ (what they hold
# and how to fetch them: benchmarks/gpu_env.sh, which this sources), and .scenes/, a copy of
# ../shared/scenes (the hairball is generated there with its make_hairball.py when missing).
#
# Parts, in this order, each under its own time limit and all under SUITE_S seconds (default 570);
# PARTS="tests paper_table" runs only those, SIZE=256 renders the benchmarks at that size (default 1024).
# The default list is the tests alone, a call of its own: at 62bda1e they outgrew the 330 s they had beside
# Table 1 (an H200 ran 1010 of 1314 in that time, the rest in 230 s more). A second call:
# PARTS="paper_table aa_cost scaling"; a third: PARTS="methods_table accuracy aa_chart".
#   tests          the whole test suite                      ~8 min (H200, 62bda1e), limit 560 s
#   paper_table    Table 1 with raster: auto for every method, 1024²             ~2 min, limit 145 s
#   aa_cost        presort_lf_et at 1 and 4 samples on every real scene          ~1 min, limit 70 s
#   methods_table  every method on the demo scene, each in its own process       ~1 min, limit 80 s
#   accuracy       speed against error on the dragons, every method, 8x reference ~1.5 min, limit 100 s
#   scaling        cost against frame size (512² to 4096²), a stereo pair against one frame, fields of
#                  1 to 64 dragons (paper_table.py scaling)                     ~4 min, limit 250 s
#   aa_chart       (not in the default PARTS) the anti-aliasing chart on the dragons and both Sponza
#                  views: 1 sample +- FXAA, 2/4/8 samples, supersample 2/3, auto   ~3 min, limit 300 s
# The test log and each part's console output go to /tmp/gpu_suite/ (and into the archive), never
# into the tree.
set -uo pipefail
cd "$(dirname "$0")/.."
copy_to=${1:-}
parts=" ${PARTS:-tests} "
logs=/tmp/gpu_suite
mkdir -p "$logs"
start=$SECONDS
deadline=$((start + ${SUITE_S:-570}))

if [[ ${GPU_ENV:-1} == 1 ]]; then
  # shellcheck source=benchmarks/gpu_env.sh
  source benchmarks/gpu_env.sh || exit 1
fi
py=${PYTHON:-python3}
size=${SIZE:-1024}
if [[ ! -f .scenes/dragons.yaml ]]; then
  echo "gpu_suite.sh: .scenes/ must hold a copy of ../shared/scenes (carry it to the machine)" >&2
  exit 1
fi
if [[ ! -f .scenes/hairball_v1.yaml && -f .scenes/make_hairball.py ]]; then
  (cd .scenes && $py make_hairball.py . > "$logs/make_hairball.log" 2>&1) || echo "hairball not generated: $logs/make_hairball.log"
fi
$py -m guaca_py info 2>&1 | tee "$logs/info.log" | head -5
slug=$($py -c "from guaca_py.benchmarking import open_device; print(open_device().slug)")
echo "results: benchmarks/results/$slug/"

failed=""
# part NAME LIMIT_S COMMAND...: run COMMAND under min(LIMIT_S, time left), its output in $logs/NAME.log
part() {
  local name=$1 limit=$2
  shift 2
  [[ $parts == *" $name "* ]] || return 0
  local left=$((deadline - SECONDS))
  ((limit > left)) && limit=$left
  if ((limit < 10)); then
    echo "== $name: skipped, the suite's time is spent"
    failed+=" $name"
    return 0
  fi
  echo "== $name (at most $limit s): $*"
  local t0=$SECONDS
  timeout -k 5 "$limit" "$@" > "$logs/$name.log" 2>&1
  local rc=$?
  tail -n 4 "$logs/$name.log"
  echo "== $name: exit $rc after $((SECONDS - t0)) s"
  ((rc == 0)) || failed+=" $name"
}

part tests 560 $py -m pytest -q -p no:cacheprovider -rf tests
part paper_table 145 $py benchmarks/paper_table.py --size "$size" --raster auto
part aa_cost 70 $py benchmarks/aa_cost.py --size "$size" --scene-names dragons sponza_dabrovic_v1 sponza_dabrovic_v2 \
  hairball_v1 hairball_v2 --samples 1 4
part methods_table 80 $py benchmarks/methods_table.py --size "$size"
part accuracy 100 $py benchmarks/accuracy_scenes.py --size "$size" --scene-names dragons
part scaling 250 $py benchmarks/paper_table.py scaling --budget-s 225
part aa_chart 300 $py benchmarks/accuracy_scenes.py --aa-chart --size "$size" --scene-names dragons \
  sponza_dabrovic_v1 sponza_dabrovic_v2 --scene-budget-s 90

if [[ -n $copy_to ]]; then
  mkdir -p "$copy_to"
  tar -czf "$copy_to/gpu_suite.tgz" "benchmarks/results/$slug"
  tar -czf "$copy_to/gpu_suite_logs.tgz" -C "$logs" .
  echo "packed benchmarks/results/$slug into $copy_to/gpu_suite.tgz, $logs into $copy_to/gpu_suite_logs.tgz"
fi
echo "suite: $((SECONDS - start)) s${failed:+; failed or cut:$failed}"
[[ -z $failed ]]
