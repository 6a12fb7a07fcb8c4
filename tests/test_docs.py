"""The documentation runs: every fenced code block of README.md and docs/ is run as written, or marked a fragment.

A block's info string is its language, then optional words:

* `fragment`: not run (a piece of a file or of a program, a command that needs a GPU, a window
  or hours, a diagram). Every other block must be of a language this test runs.
* `file=PATH`: the block is also written to PATH, so that later blocks of the same page use it.

The blocks of one page run in order in one temporary folder (examples/ of this checkout linked
into it), with this checkout's guaca_py first on PYTHONPATH and `guaca`, `python` and `python3` on
PATH meaning this interpreter's:

* `python`: run as a script, headless (a block that needs a window must be a fragment);
* `bash`, `sh`: run by bash (`-e -o pipefail`), each command as written, except set-up
  commands: installing packages (`pip install`, `apt-get`), making or entering a virtual
  environment and running this test suite are what CI does before this test (.ci/run follows the
  README's set-up), so those commands are left out and the rest of the block runs;
* `yaml`: loaded as a scene file when it has a camera, nodes or lights, else as a pipeline file;
* `json`: loaded as a material description.
"""

from __future__ import annotations

import json
import os
import re
import shlex
import subprocess
import sys
from dataclasses import dataclass
from pathlib import Path

import pytest
import yaml

ROOT = Path(__file__).resolve().parents[1]
PAGES = [ROOT / "README.md", *sorted((ROOT / "docs").rglob("*.md"))]
RUNS = {"python", "bash", "sh", "yaml", "json"}
SHELLS = {"bash", "sh"}
#: commands that set up an environment: CI runs them before the suite (.ci/run), the test leaves them out
SETUP = re.compile(
    r"^\s*(sudo\s+)?((python3?\s+-m\s+)?pip3?\s+install\b|apt(-get)?\s|python3?\s+-m\s+venv\b|\.\s+\S*activate\b"
    r"|source\s+\S*activate\b|python3?\s+-m\s+pytest\b|pytest\b)"
)
SCENE_KEYS = {"camera", "nodes", "lights", "background"}
FENCE = re.compile(r"^(\s*)(`{3,}|~{3,})(.*)$")
BLOCK_TIMEOUT_S = 300


@dataclass
class Block:
    """One fenced code block: where it is, its info string's words and its text."""

    page: Path
    line: int
    lang: str
    words: list[str]
    text: str

    @property
    def where(self) -> str:
        return f"{self.page.relative_to(ROOT)}:{self.line}"

    @property
    def fragment(self) -> bool:
        return "fragment" in self.words

    @property
    def file(self) -> str | None:
        return next((w.split("=", 1)[1] for w in self.words if w.startswith("file=")), None)


def blocks(page: Path) -> list[Block]:
    """The fenced code blocks of a Markdown page, in order (indentation of a list item removed)."""
    out, open_, lines = [], None, []
    for n, line in enumerate(page.read_text().splitlines(), 1):
        m = FENCE.match(line)
        if open_ is None:
            if m:
                indent, fence, info = m.groups()
                words = info.split()
                open_ = (n, indent, fence, words[0] if words else "", words[1:])
                lines = []
            continue
        n0, indent, fence, lang, words = open_
        if m and m.group(2).startswith(fence) and not m.group(3).strip():
            out.append(Block(page, n0, lang.lower(), words, "\n".join(lines) + "\n"))
            open_ = None
        else:
            lines.append(line[len(indent) :] if line.startswith(indent) else line)
    assert open_ is None, f"{page.relative_to(ROOT)}:{open_[0]}: code block never closed"
    return out


def shell_commands(text: str) -> str:
    """The block's commands without the set-up ones (a line `a && b` loses only a set-up `a` or `b`)."""
    kept = []
    for line in text.replace("\\\n", " ").splitlines():
        parts = [p for p in line.split("&&") if not SETUP.match(p)]
        if parts and "".join(parts).strip():
            kept.append("&&".join(parts).strip())
    return "\n".join(kept)


def shims(bin_dir: Path) -> dict:
    """`guaca`, `python`, `python3` as this interpreter with this checkout's guaca_py; the environment to run in."""
    bin_dir.mkdir()
    for name, args in (("guaca", '-m guaca_py "$@"'), ("python", '"$@"'), ("python3", '"$@"')):
        p = bin_dir / name
        p.write_text(f"#!/bin/sh\nexec {shlex.quote(sys.executable)} {args}\n")
        p.chmod(0o755)
    path = os.pathsep.join([str(bin_dir), os.environ.get("PATH", "")])
    pythonpath = os.pathsep.join(filter(None, [str(ROOT), os.environ.get("PYTHONPATH")]))
    env = {**os.environ, "PATH": path, "PYTHONPATH": pythonpath}
    env.pop("DISPLAY", None)  # headless, as on CI: a block that opens a window fails here too
    env.pop("WAYLAND_DISPLAY", None)
    return env


# modules of the optional extras (pyproject.toml): a block that needs one runs where it is installed
OPTIONAL_MODULES = ("moderngl_window", "IPython", "jupyter_rfb", "ipywidgets", "ray", "imageio_ffmpeg", "tqdm", "vtk")


def run(cmd: list[str], block: Block, cwd: Path, env: dict) -> None:
    r = subprocess.run(cmd, cwd=cwd, env=env, capture_output=True, text=True, timeout=BLOCK_TIMEOUT_S)
    if r.returncode != 0:
        for name in OPTIONAL_MODULES:
            if f"No module named '{name}'" in r.stderr:
                pytest.skip(f"{block.where} needs the optional module {name}, not installed here")
    assert r.returncode == 0, f"{block.where}: exit status {r.returncode}\n{r.stdout[-3000:]}\n{r.stderr[-3000:]}"


def check_yaml(block: Block, cwd: Path) -> None:
    from guaca_py.errors import GuacaError
    from guaca_py.pipeline.config import pipeline_from_text
    from guaca_py.scene.loader import load_scene_text

    doc = yaml.safe_load(block.text)
    assert isinstance(doc, dict), f"{block.where}: not a YAML mapping (a piece of a file? mark it `fragment`)"
    try:
        if SCENE_KEYS & set(doc):
            load_scene_text(block.text, block.where, cwd)
        else:
            pipeline_from_text(block.text, block.where)
    except GuacaError as exc:
        pytest.fail(f"{block.where}: {exc} (a piece of a file? mark it `fragment`)")


def check_json(block: Block, cwd: Path) -> None:
    from guaca_py.materials import load_material

    doc = json.loads(block.text)
    path = cwd / (block.file or f"{doc.get('name', 'material')}.json")
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(block.text)
    load_material(path)


@pytest.mark.parametrize("page", PAGES, ids=[str(p.relative_to(ROOT)) for p in PAGES])
def test_page_blocks_run(page, tmp_path):
    env = shims(tmp_path / "bin")
    cwd = tmp_path / "work"
    cwd.mkdir()
    (cwd / "examples").symlink_to(ROOT / "examples")
    for block in blocks(page):
        if block.fragment:
            continue
        assert block.lang in RUNS, f"{block.where}: ```{block.lang}: not runnable here; mark it `fragment`"
        if block.file:
            target = cwd / block.file
            target.parent.mkdir(parents=True, exist_ok=True)
            target.write_text(block.text)
        if block.lang == "python":
            script = tmp_path / f"block_{block.line}.py"
            script.write_text(block.text)
            run([sys.executable, str(script)], block, cwd, env)
        elif block.lang in SHELLS:
            commands = shell_commands(block.text)
            if commands:
                run(["bash", "-e", "-o", "pipefail", "-c", commands], block, cwd, env)
        elif block.lang == "yaml":
            check_yaml(block, cwd)
        else:
            check_json(block, cwd)


def test_block_reader_and_setup_filter(tmp_path):
    page = tmp_path / "p.md"
    page.write_text(
        "text\n\n```python fragment\nx = 1\n```\n\n- item\n\n  ```bash file=run.sh\n  echo hi\n  ```\n\n"
        "````text\n```yaml\n````\n"
    )
    b = blocks(page)
    assert [(x.lang, x.fragment, x.file, x.text) for x in b] == [
        ("python", True, None, "x = 1\n"),
        ("bash", False, "run.sh", "echo hi\n"),
        ("text", False, None, "```yaml\n"),
    ]
    assert shell_commands('pip install ".[test]" && python -m pytest -q\n') == ""
    assert shell_commands("pip install . && guaca render --out demo.png\n") == "guaca render --out demo.png"
    assert shell_commands("guaca info\npython3 -m venv .venv && . .venv/bin/activate\n") == "guaca info"
    assert shell_commands("python examples/a.py \\\n  --frames 2\n") == "python examples/a.py    --frames 2"


def test_every_page_is_in_the_site_and_every_picture_exists():
    """docs/ pages are all in mkdocs.yml's nav; the pictures they show exist."""
    config = (ROOT / "mkdocs.yml").read_text()
    nav = set(re.findall(r":\s*(\S+\.md)\s*$", config, re.M))
    pages = {p.relative_to(ROOT / "docs").as_posix() for p in (ROOT / "docs").rglob("*.md")}
    assert pages | {"index.md"} == nav, f"not in the nav: {pages - nav}; no such page: {nav - pages - {'index.md'}}"
    shown = 0
    for page in PAGES:
        for target in re.findall(r"!\[[^\]]*\]\(([^)\s]+)\)", page.read_text()):
            if re.match(r"^[a-z]+:", target):
                continue
            path = (page.parent / target).resolve()
            assert path.is_file(), f"{page.relative_to(ROOT)}: no picture {target}"
            shown += 1
    assert shown >= 3


def test_pictures_come_from_the_commands_their_pages_show():
    """tools/doc_pictures.py makes each picture with a command its page shows (and runs, above); small PNGs."""
    import importlib.util

    from PIL import Image

    spec = importlib.util.spec_from_file_location("doc_pictures", ROOT / "tools" / "doc_pictures.py")
    tool = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(tool)
    for name, (page, command) in tool.PICTURES.items():
        shell = [shell_commands(b.text) for b in blocks(ROOT / page) if b.lang in SHELLS and not b.fragment]
        assert any(command in text.splitlines() for text in shell), f"{page} runs no `{command}`"
        picture = ROOT / "docs" / "images" / name
        assert picture.is_file(), f"docs/images/{name}: run python tools/doc_pictures.py"
        assert max(Image.open(picture).size) <= 256, f"docs/images/{name}: larger than 256 px"
        shown = f"images/{name}"
        assert shown in (ROOT / page).read_text(), f"{page} does not show {shown}"
