"""Where each method breaks: error against the float64 CPU reference as depth complexity grows.

Usage: python benchmarks/breaking_points.py [--out DIR] [--size 128] [--layers 1 2 4 ...] [--replot]
The sweep is guaca_py.benchmarking.breaking_points (its docstring says what each configuration
shows): layered quads rendered through pipelines/exact.yaml, errors on non-edge pixels in 1/255,
and the counter that reports each bounded configuration's limit. No times: accuracy does not
depend on the device, so this runs anywhere (llvmpipe included).
Writes benchmarks/results/<device>/breaking_points/breaking_points.{json,md,png}.
"""

from __future__ import annotations

from guaca_py.benchmarking import Results, bench_args, open_device
from guaca_py.benchmarking.breaking_points import CONFIGS, run, table
from guaca_py.methods import method_class


def chart(data: dict):
    """A drawing function: RMSE against depth complexity, one line per configuration."""

    def draw(plt):
        fig, ax = plt.subplots(figsize=(9, 5.5))
        floor = 0.01
        for i, (label, mid, *_rest) in enumerate(CONFIGS):
            pts = [
                (r["layers"], max(r["rmse_255"], floor))
                for r in data["rows"]
                if r["config"] == label and "rmse_255" in r
            ]
            if pts:
                exact = method_class(mid).exact
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
        return fig

    return draw


def main(argv: list[str] | None = None) -> int:
    """Run the sweep (or rebuild its table and chart with --replot)."""
    ap = bench_args(__file__, __doc__, size=128, frames=1)
    ap.add_argument("--layers", type=int, nargs="*", default=[1, 2, 4, 8, 12, 16, 24, 32])
    args = ap.parse_args(argv)
    if args.replot:
        res = Results.existing(args, argv)
        data = res.read_json()
    else:
        device = open_device()
        res = Results(args, device.name, argv)
        data = run(device.ctx, args.size, args.layers)
    print(res.finish(data, lambda d: table(d) + f"\nCommand: `{d['command']}`\n", chart))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
