"""The benchmark harness: timing by the performance protocol, the GPU clock, results folders, charts.

`guaca render --frames N` times frames with measure(); the scripts under benchmarks/ are built from
the rest (docs: benchmarks/README.md):

- timing: measure() and measure_interleaved() (warm-up frames, per-pass medians), measure_point()
  (a configuration held at the full SM clock: warm-up by time, medians, re-run while throttled);
- clock: the SM clock sampled through nvidia-smi where it exists;
- harness: the device and its results folder benchmarks/results/<device>/<benchmark>/ (JSON,
  Markdown naming its command, chart), common arguments, progress with N/total and an ETA;
- charts, rows, scenes: plain-number log axes, the per-configuration loop, scenes built in code.
"""

from .charts import plain_log_axis, pyplot, time_label
from .clock import (
    RETRIES,
    ClockSampler,
    at_full_clock,
    below_max_clock,
    clock_summary,
    max_sm_clock,
    ratio_at_full_clock,
    top_clock,
)
from .harness import (
    Device,
    Progress,
    Results,
    add_reference_args,
    bench_args,
    device_slug,
    header,
    open_device,
    raster_overrides,
    scene_paths,
    timer_of,
    timer_sentence,
)
from .rows import config_rows
from .timing import Measurement, Point, measure, measure_interleaved, measure_point, warm_up

__all__ = [
    "RETRIES",
    "ClockSampler",
    "Device",
    "Measurement",
    "Point",
    "Progress",
    "Results",
    "add_reference_args",
    "at_full_clock",
    "bench_args",
    "below_max_clock",
    "clock_summary",
    "config_rows",
    "device_slug",
    "header",
    "max_sm_clock",
    "measure",
    "measure_interleaved",
    "measure_point",
    "open_device",
    "plain_log_axis",
    "pyplot",
    "ratio_at_full_clock",
    "raster_overrides",
    "scene_paths",
    "time_label",
    "timer_of",
    "timer_sentence",
    "top_clock",
    "warm_up",
]
