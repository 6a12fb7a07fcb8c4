#!/usr/bin/env bash
# Commits of the project measured against each other on one machine, alternately (a GPU's clock and
# its host drift between calls, so figures of two calls do not compare).
#
#   bash benchmarks/ab.sh pack REV...              here: each REV's tree into .ab/<REV>.tgz (git archive;
#                                                  .ab/ is git-ignored: carry it to the machine)
#   bash benchmarks/ab.sh run OUT ROUNDS SCRIPT ARGS...
#                                                  there: SCRIPT (a benchmark, e.g. benchmarks/aa_cost.py)
#                                                  with ARGS in each packed tree in turn, ROUNDS times;
#                                                  each run writes OUT/<REV>_<round>/ (its --out) and its
#                                                  log beside; the table rows of every run are printed
#                                                  at the end, run by run
#
# The trees read the scenes of this checkout's .scenes/ and the Python path set up here (source
# benchmarks/gpu_env.sh first on the GPU machine). Example, 4 samples before and after a change:
#   bash benchmarks/ab.sh pack bf5103d HEAD           # here, then carry .ab, .gl, .whl, .scenes
#   source benchmarks/gpu_env.sh && bash benchmarks/ab.sh run "$OUT" 2 benchmarks/aa_cost.py \
#     --size 1024 --scene-names dragons hairball_v1 --samples 4
set -uo pipefail
cd "$(dirname "$0")/.."
root=$PWD
ab=${AB_DIR:-.ab}  # where the packed trees lie (AB_DIR: elsewhere)
mode=${1:-}
shift || true

if [[ $mode == pack ]]; then
  (($# > 0)) || { echo "ab.sh pack: name at least one revision" >&2; exit 2; }
  mkdir -p "$ab"
  for rev in "$@"; do
    sha=$(git rev-parse --short "$rev^{commit}") || { echo "ab.sh pack: no commit '$rev'" >&2; exit 2; }
    # named by the revision as given (HEAD stays HEAD) and by its commit in the archive's comment
    git archive --format=tar.gz -o "$ab/${rev//\//_}.tgz" "$sha" -- guaca_py shader_templates materials pipelines \
      benchmarks ':(exclude)benchmarks/results' pyproject.toml || exit 1
    echo "packed $rev ($sha) into $ab/${rev//\//_}.tgz"
  done
  exit 0
fi

if [[ $mode != run ]] || (($# < 3)); then
  echo "usage: ab.sh pack REV... | ab.sh run OUT ROUNDS SCRIPT ARGS..." >&2
  exit 2
fi
out=$1 rounds=$2 script=$3
shift 3
shopt -s nullglob
packs=("$ab"/*.tgz)
((${#packs[@]} > 0)) || { echo "ab.sh run: no $ab/*.tgz here (ab.sh pack REV... first, and carry .ab)" >&2; exit 2; }
[[ $rounds =~ ^[1-9][0-9]*$ ]] || { echo "ab.sh run: ROUNDS must be a positive whole number, got '$rounds'" >&2; exit 2; }
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
for pack in "${packs[@]}"; do
  name=$(basename "$pack" .tgz)
  mkdir -p "$work/$name" && tar -xzf "$pack" -C "$work/$name" || exit 1
  ln -s "$root/.scenes" "$work/$name/.scenes"
done
mkdir -p "$out"
# the Python path set up here, less this checkout (its package must not shadow the tree under test)
base_path=""
IFS=: read -ra entries <<< "${PYTHONPATH:-}"
for entry in "${entries[@]}"; do
  [[ -n $entry && $entry != "$root" && $entry != "$root/" ]] && base_path+="${base_path:+:}$entry"
done
failed=0
for ((round = 1; round <= rounds; round++)); do
  for pack in "${packs[@]}"; do
    name=$(basename "$pack" .tgz)
    run="$out/${name}_$round"
    echo "== $name, round $round/$rounds: $script $*"
    (cd "$work/$name" && PYTHONPATH="$work/$name${base_path:+:$base_path}" python3 "$script" "$@" --out "$run") \
      > "$run.log" 2>&1
    rc=$?
    ((rc == 0)) || { echo "   exit $rc: $run.log"; failed=1; }
  done
done
for ((round = 1; round <= rounds; round++)); do
  for pack in "${packs[@]}"; do
    name=$(basename "$pack" .tgz)
    echo "== $name, round $round"
    cat "$out/${name}_$round"/*.md 2>/dev/null | grep -E '^\| [^-]' | grep -v '^| scene |' || echo "   (no table)"
  done
done
exit $failed
