#!/usr/bin/env bash
# A/B of benchmarks/aa_cost.py: the same arguments run in a base tree (another commit's package,
# templates and benchmarks) and then in this one, in one session of the GPU machine, so both sides
# share its clock and state. Results in OUT/base/ and OUT/new/ (aa_cost.{md,json}, the logs).
#   mkdir ab_base && git archive BASE guaca_py shader_templates materials pipelines benchmarks pyproject.toml \
#     | tar -x -C ab_base
#   source .gl/gpu-env.sh && NEW_ARGS="--small-fragments 4 8 16" bash benchmarks/ab_aa_cost.sh ab_base "$OUT" \
#     --scene-names dragons hairball_v2 --samples 1 4
# Scenes come from .scenes/ of this tree (the hairball is made there first when missing); NEW_ARGS
# go to this tree's run only (a setting the base has no counterpart for).
set -uo pipefail
base=$(cd "$1" && pwd)
out=$2
shift 2
root=$PWD
mkdir -p "$out/base" "$out/new"
if [[ -f .scenes/make_hairball.py && ! -f .scenes/hairball.ply ]]; then
  (cd .scenes && python3 make_hairball.py . > /dev/null)
fi
run() {  # side, tree, extra arguments...
  local side=$1 tree=$2
  shift 2
  (cd "$tree" && PYTHONPATH="/tmp/site:$tree" timeout 280 python3 benchmarks/aa_cost.py "$out/$side" \
    --scenes "$root/.scenes" "$@") > "$out/$side/log.txt" 2>&1
  echo "== $side (exit $?)"
  grep -E "^\| (dragons|sponza|hairball)" "$out/$side/aa_cost.md" | cut -c1-160
}
run base "$base" "$@"
# shellcheck disable=SC2086  # NEW_ARGS is a list of words
run new "$root" "$@" ${NEW_ARGS:-}
