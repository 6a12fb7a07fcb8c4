"""Render the documentation's pictures (docs/images/) with the commands the pages show.

    python tools/doc_pictures.py            # every picture
    python tools/doc_pictures.py demo.png   # only these

Each picture is made by a command that appears as written in its page (tests/test_docs.py checks
that), run in a temporary folder holding the files that page writes (its ```` ```yaml file=NAME ````
blocks) and examples/; only the command's `--out` is pointed at docs/images/. Pictures are at
most 256 px a side: the commands ask for that size.
"""

from __future__ import annotations

import os
import re
import shlex
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
IMAGES = ROOT / "docs" / "images"

#: picture (under docs/images/) -> (the page showing the command, the command as the page writes it)
PICTURES = {
    "demo.png": ("docs/guide/first-render.md", "guaca render --width 256 --height 192 --out demo.png"),
    "panes.png": ("docs/guide/first-render.md", "guaca render panes.yaml --width 256 --height 192 --out panes.png"),
    "banner.png": (
        "docs/guide/configuration-files.md",
        "guaca render scene.yaml --pipeline pipeline.yaml --materials materials --width 256 --height 192 --out banner.png",
    ),
    "examples/embed_host_app.png": (
        "docs/examples.md",
        "python examples/embed_host_app.py --frames 3 --width 256 --height 192 --out host.png",
    ),
    "examples/animate_scene.png": (
        "docs/examples.md",
        "python examples/animate_scene.py --frames 30 --width 256 --height 192 --out animated.png",
    ),
    "examples/compare_methods.png": (
        "docs/examples.md",
        "python examples/compare_methods.py --left presort_lf_et --right unsorted_blend --width 128 --height 96 "
        "--out compare.png",
    ),
}
FILE_BLOCK = re.compile(r"^```\w+ file=(\S+)[^\n]*\n(.*?)^```\s*$", re.S | re.M)


def page_files(page: Path) -> dict[str, str]:
    """The files a page writes: its ```` ```LANG file=NAME ```` blocks."""
    return dict(FILE_BLOCK.findall(page.read_text()))


def render(name: str) -> Path:
    """Run picture `name`'s command in a temporary folder, its output going to docs/images/NAME."""
    page, command = PICTURES[name]
    out = IMAGES / name
    out.parent.mkdir(parents=True, exist_ok=True)
    argv = shlex.split(command)
    argv[argv.index("--out") + 1] = str(out)
    if argv[0] == "guaca":
        argv[:1] = [sys.executable, "-m", "guaca_py"]
    elif argv[0] == "python":
        argv[0] = sys.executable
    env = {**os.environ, "PYTHONPATH": os.pathsep.join(filter(None, [str(ROOT), os.environ.get("PYTHONPATH")]))}
    with tempfile.TemporaryDirectory() as tmp:
        (Path(tmp) / "examples").symlink_to(ROOT / "examples")
        for rel, text in page_files(ROOT / page).items():
            (Path(tmp) / rel).parent.mkdir(parents=True, exist_ok=True)
            (Path(tmp) / rel).write_text(text)
        subprocess.run(argv, cwd=tmp, env=env, check=True, stdout=subprocess.DEVNULL)
    return out


def main(argv: list[str] | None = None) -> int:
    """Render the named pictures, or all of them."""
    names = (argv if argv is not None else sys.argv[1:]) or list(PICTURES)
    for name in names:
        print(f"{render(name).relative_to(ROOT)} ({PICTURES[name][0]})")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
