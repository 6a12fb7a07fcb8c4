"""Where each method breaks: error against the float64 reference as depth complexity grows.

Usage: python benchmarks/breaking_points.py OUTDIR [--size 128] [--layers 1 2 4 ...] [--replot]
Scene: tests/reference.py's layered quads (shuffled submission, one opaque quad mid-stack),
rendered through pipelines/exact.yaml; error on non-edge pixels in 1/255 (RMSE and max).
Each configuration is chosen to show one limit: approximate methods at their defaults, and
exact methods with a deliberately small bound (post_sort's local array, a peeling pass cap,
a fixed A-buffer pool, an early-termination threshold) whose counters must explain the error.
Accuracy does not depend on the device, so this runs anywhere (llvmpipe included).
Writes OUTDIR/breaking_points.json, .md and .png.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path[:0] = [str(ROOT), str(ROOT / "tests")]

from reference import compare, layered_quads_scene, reference_of  # noqa: E402

from guaca_py import GuacaError, Renderer  # noqa: E402
from guaca_py.context import create_context  # noqa: E402
from guaca_py.methods import method_class  # noqa: E402

# (label, method id, settings, counter that reports the limit being hit)
CONFIGS = [
    ("unsorted_blend", "unsorted_blend", {}, None),
    ("object_sorted_blend", "object_sorted_blend", {}, None),
    ("weighted_blended", "weighted_blended", {}, None),
    ("stochastic S=8", "stochastic", {"samples": 8}, None),
    ("stochastic S=32", "stochastic", {"samples": 32}, None),
    ("kbuffer k=4 merge", "kbuffer", {"k": 4, "overflow": "merge"}, "merged"),
    ("kbuffer k=8 merge", "kbuffer", {"k": 8, "overflow": "merge"}, "merged"),
    ("kbuffer k=8 drop", "kbuffer", {"k": 8, "overflow": "drop"}, "dropped"),
    ("post_sort max_fragments=8", "post_sort", {"max_fragments": 8}, "truncated"),
    ("depth_peeling max_passes=6", "depth_peeling", {"max_passes": 6}, "truncated"),
    ("presort_lf_et threshold=0.9", "presort_lf_et", {"threshold": 0.9}, "early_termination_culled"),
    ("presort_lf budget 0.05 MB", "presort_lf", {"budget_mb": 0.05}, "overflow"),
    ("presort_lf (exact)", "presort_lf", {}, None),
]


def run(out: Path, size: int, layer_counts: list[int]) -> dict:
    """Render every configuration at every depth complexity; rows of errors and counters."""
    ctx, caps = create_context()
    rows = []
    renderers = {}
    for n in layer_counts:
        scene = layered_quads_scene(n_layers=n, order="shuffled", seed=5)
        ref, mask, layers = reference_of(scene, size, size)
        for label, mid, settings, counter in CONFIGS:
            row = {"config": label, "method": mid, "layers": n, "max_depth_complexity": int(layers.max())}
            try:
                if label not in renderers:
                    renderers[label] = Renderer("exact", ctx=ctx, method=mid, method_overrides=settings)
                frame = renderers[label].render(scene, size, size)
                err = compare(frame.image, ref, mask)
                frags = frame.stats.get("fragments", {})
                row.update(
                    rmse_255=err["rmse_255"],
                    max_255=err["max_abs_255"],
                    counter=counter,
                    counted=int(frags.get(counter, 0)) if counter else None,
                    warnings=frame.stats.get("warnings", []),
                )
            except GuacaError as exc:
                row["unavailable"] = str(exc)
            rows.append(row)
        print(f"{n:>3} layers done", flush=True)
    for r in renderers.values():
        r.release()
    return {
        "meta": {
            "device": caps.gl_renderer,
            "size": size,
            "layers": layer_counts,
            "scene": "layered quads, shuffled, seed 5",
            "unit": "1/255, non-edge pixels",
        },
        "rows": rows,
    }


def table(data: dict) -> str:
    """Markdown: RMSE / max per configuration and depth complexity, with the limit counter."""
    meta, rows = data["meta"], data["rows"]
    ns = meta["layers"]
    out = [
        f"Error vs float64 reference (RMSE / max, {meta['unit']}), {meta['size']}² px, {meta['scene']}, "
        f"device {meta['device']}. In brackets: the counter that reports the limit (fragments).",
        "",
        "| config | " + " | ".join(f"{n} layers" for n in ns) + " |",
        "|---|" + "---|" * len(ns),
    ]
    for label, *_ in CONFIGS:
        cells = []
        for n in ns:
            r = next(r for r in rows if r["config"] == label and r["layers"] == n)
            if "unavailable" in r:
                cells.append("n/a")
                continue
            c = f"{r['rmse_255']:.2f} / {r['max_255']:.0f}"
            if r["counter"]:
                c += f" [{r['counter']} {r['counted']}]"
            cells.append(c)
        out.append(f"| {label} | " + " | ".join(cells) + " |")
    return "\n".join(out) + "\n"


def chart(data: dict, path: Path) -> None:
    """RMSE against depth complexity, one line per configuration."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(9, 5.5))
    floor = 0.01
    for i, (label, *_rest) in enumerate(CONFIGS):
        pts = [
            (r["layers"], max(r["rmse_255"], floor)) for r in data["rows"] if r["config"] == label and "rmse_255" in r
        ]
        if pts:
            exact = method_class(_rest[0]).exact
            ax.plot(
                *zip(*pts),
                marker="os^vD<>p*hH+x"[i % 13],
                label=label + ("" if exact else " ≈"),
                linestyle="--" if exact else "-",
            )
    ax.set_xscale("log", base=2)
    ax.set_yscale("log")
    ax.set_xticks(data["meta"]["layers"], [str(n) for n in data["meta"]["layers"]])
    ax.set_xlabel("transparent layers in the stack (shuffled submission)")
    ax.set_ylabel(f"RMSE vs float64 reference, 1/255 (floor {floor})")
    ax.set_title(
        "Where each method breaks (dashed: exact methods held to a deliberately small bound; ≈ approximate)",
        fontsize=10,
    )
    ax.legend(fontsize=7, ncol=2)
    fig.tight_layout()
    fig.savefig(path, dpi=120)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("out", type=Path)
    ap.add_argument("--size", type=int, default=128)
    ap.add_argument("--layers", type=int, nargs="*", default=[1, 2, 4, 8, 12, 16, 24, 32])
    ap.add_argument("--replot", action="store_true", help="only rebuild the table and chart from OUT's JSON")
    args = ap.parse_args(argv)
    args.out.mkdir(parents=True, exist_ok=True)
    jpath = args.out / "breaking_points.json"
    if args.replot:
        data = json.loads(jpath.read_text())
    else:
        data = run(args.out, args.size, args.layers)
        jpath.write_text(json.dumps(data, indent=2))
    md = table(data)
    (args.out / "breaking_points.md").write_text(md)
    chart(data, args.out / "breaking_points.png")
    print(md)
    return 0


if __name__ == "__main__":
    sys.exit(main())
