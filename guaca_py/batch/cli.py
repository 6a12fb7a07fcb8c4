"""`guaca batch JOB.yaml --out DIR`: the batch subcommand's options and its run."""

from __future__ import annotations

import argparse


def add_parser(sub) -> argparse.ArgumentParser:
    """Add `batch` to the `guaca` subcommands."""
    b = sub.add_parser("batch", help="render every frame of a job (camera path, variants) on local workers or Ray")
    b.add_argument("job", help="job YAML (scene, frames, camera path, variants; see docs/cluster.md)")
    b.add_argument("--out", required=True, help="output folder: <variant>/<frame>.png and manifest.jsonl")
    b.add_argument(
        "--workers", type=int, help="workers (default: one per GPU; without GPUs 1 locally, one per CPU on Ray)"
    )
    b.add_argument(
        "--ray",
        nargs="?",
        const=True,
        metavar="ADDRESS",
        help='run on Ray: RAY_ADDRESS or a new local instance, or the cluster at ADDRESS (pip install "guaca_py[cluster]")',
    )
    b.add_argument("--chunk", type=int, help="frames handed to a worker at once (default: about 4 chunks per worker)")
    b.add_argument("--no-progress", action="store_true", help="no progress bar or lines")
    b.set_defaults(fn=run)
    return b


def run(args) -> int:
    """Run the job; print what was done."""
    from .run import render_job

    result = render_job(
        args.job, args.out, workers=args.workers, ray=args.ray, chunk=args.chunk, progress=not args.no_progress
    )
    print(result.summary())
    for v in result.videos:
        print(f"video written to {v}")
    print(f"manifest: {result.out / 'manifest.jsonl'}")
    return 0
