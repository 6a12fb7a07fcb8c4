"""MkDocs hooks (mkdocs.yml `hooks:`): the README is the site's home page, and pages written to be read
in the repository (on a forge or in an editor) read the same on the site.

* The home page is README.md itself, not a copy.
* A fence's info string keeps its language only: ```` ```python fragment ```` (the test of the
  documentation's code blocks reads the words after it, tests/test_docs.py) is highlighted as Python.
* Links are resolved from the page's place in the repository: a link into docs/ becomes a link
  between site pages, a link to examples/ the Examples page, and a link to any other file of the
  repository (a benchmark's results, a module) points into the repository at `repo_url`, or, with
  none configured, is left as its text: the site holds no copy of those files.
"""

from __future__ import annotations

import os
import re
from pathlib import Path

from mkdocs.structure.files import File, Files

FENCE = re.compile(r"^(\s*)(`{3,}|~{3,})\s*([\w+#.-]+)[^\n]*$")
LINK = re.compile(r"(!?)\[([^\]]*)\]\(([^)\s]+)\)")
EXAMPLES_PAGE = "examples.md"


def _root(config) -> Path:
    return Path(config.config_file_path).resolve().parent


def on_files(files: Files, config) -> Files:
    """Add README.md as the site's index.md."""
    files.append(File.generated(config, "index.md", abs_src_path=str(_root(config) / "README.md")))
    return files


def _outside_fences(markdown: str, fix_line) -> str:
    """Apply `fix_line` to every line outside fenced code; fences keep their language word only."""
    out, fence = [], None
    for line in markdown.split("\n"):
        m = FENCE.match(line)
        stripped = line.strip()
        if fence is None and m:
            fence = m.group(2)
            out.append(f"{m.group(1)}{m.group(2)}{m.group(3)}")
        elif fence is None and stripped[:3] in ("```", "~~~"):
            fence = stripped[: len(stripped) - len(stripped.lstrip(stripped[0]))]
            out.append(line)
        elif fence is not None:
            if stripped.startswith(fence) and stripped.strip(fence[0]) == "":
                fence = None
            out.append(line)
        else:
            out.append(fix_line(line))
    return "\n".join(out)


def on_page_markdown(markdown: str, page, config, files: Files) -> str:
    """Resolve the page's links from where its source lives in the repository; plain fence info strings."""
    root, docs = _root(config), Path(config.docs_dir).resolve()
    src = Path(page.file.abs_src_path).resolve()
    page_dir = (docs / page.file.src_uri).parent  # where the page sits among the site's pages

    def fix_link(m: re.Match) -> str:
        bang, text, target = m.groups()
        if re.match(r"^[a-z][a-z0-9+.-]*:|^#|^/", target):  # a URL, an anchor on the page, a site path
            return m.group(0)
        path, _, anchor = target.partition("#")
        resolved = (src.parent / path).resolve()
        suffix = f"#{anchor}" if anchor else ""
        if resolved == docs / "index.md" or resolved == root / "README.md":
            return f"{bang}[{text}]({os.path.relpath(docs / 'index.md', page_dir)}{suffix})"
        if resolved.is_relative_to(docs):
            return f"{bang}[{text}]({os.path.relpath(resolved, page_dir)}{suffix})"
        if resolved == root / "examples":
            return f"{bang}[{text}]({os.path.relpath(docs / EXAMPLES_PAGE, page_dir)})"
        if not resolved.is_relative_to(root):
            return m.group(0)
        rel = resolved.relative_to(root).as_posix() + ("/" if resolved.is_dir() else "")
        if config.repo_url:
            kind = "tree" if resolved.is_dir() else "blob"
            return f"{bang}[{text}]({config.repo_url.rstrip('/')}/{kind}/HEAD/{rel}{suffix})"
        return text if rel.strip("/") in text else f"{text} (`{rel}`)"

    return _outside_fences(markdown, lambda line: LINK.sub(fix_link, line))
