"""Batch rendering: many frames of one or more scenes, on local worker processes or a Ray cluster.

`render_job(job, out)` (and `guaca batch JOB.yaml --out DIR`) renders a job (guaca_py/batch/job.py
describes the file) into DIR/<variant>/<frame:05d>.png with DIR/manifest.jsonl, skipping frames
a previous run wrote; docs/cluster.md covers workers, Ray and how throughput scales.

- job: the job file, checked with file, line and key; variants through the pipeline checks
- plan: scenes loaded once on the driver and shipped as objects; each frame's camera and transforms
- worker: a Renderer per variant on one context, scenes kept warm, PNG encoding on threads
- local, ray_backend: worker processes (spawn) or Ray actors; run: the driver; store: lock, manifest, files
"""

from .job import Job, Variant, load_job
from .run import BatchError, BatchResult, render_job

__all__ = ["Job", "Variant", "load_job", "render_job", "BatchError", "BatchResult"]
