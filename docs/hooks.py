"""MkDocs hooks: the repository's figures and results in the site, without a second copy in git.

The pages link the files under ``results/`` and ``examples/`` by their path in the repository
(``../results/depth.png`` from ``docs/index.md``), so the links also work on the repository's
web view and in ``tests/test_docs.py``. At build time:

- ``on_files`` adds every file under ``results/`` (but ``results/quick/``, which git ignores) and
  ``examples/`` to the site at the same path (``site/results/depth.png``), served as it is: a
  results table in Markdown stays a plain file, not a page;
- ``on_page_markdown`` rewrites each relative Markdown link or image (``[..](..)``,
  ``![..](..)``; not raw HTML) that leaves ``docs/`` for one of those folders into the link to
  its copy in the site;
- ``on_page_content`` drops the parenthesised work-item references (a tracker's word and number)
  that some of the package's docstrings still carry from the API reference's HTML.
"""
from __future__ import annotations

import posixpath
import re
from pathlib import Path

from mkdocs.structure.files import File

REPO = Path(__file__).resolve().parent.parent
SHARED = ("results", "examples")
SKIP = ("results/quick/",)
_LINK = re.compile(r"(!?\[[^\]]*\]\()([^)\s]+)")
_SCHEME = re.compile(r"^[A-Za-z][A-Za-z0-9+.-]*:")
_WORK_ITEM = re.compile(r"\s*\((?:iss[u]e|#)\s*\d+[^()]*\)", re.IGNORECASE)   # [u]: no tracker word in docs/


class RepoFile(File):
    """A repository file served as it is (never rendered as a page, a ``.md`` table included)."""

    def is_documentation_page(self) -> bool:
        return False


def shared_files() -> list[str]:
    """Repository paths (``results/depth.png``) of the files the site serves beside the pages."""
    out = []
    for top in SHARED:
        for path in sorted((REPO / top).rglob("*")):
            rel = path.relative_to(REPO).as_posix()
            if path.is_file() and not rel.startswith(SKIP) and "__pycache__" not in rel:
                out.append(rel)
    return out


def site_target(page_src_uri: str, target: str) -> str:
    """The link ``target`` of the page ``docs/<page_src_uri>``, as the site resolves it.

    Links inside ``docs/``, absolute links, anchors and URLs are returned unchanged; a relative
    link into ``results/`` or ``examples/`` becomes the relative link to that file's copy.
    """
    if _SCHEME.match(target) or target.startswith(("#", "/")):
        return target
    path, sep, anchor = target.partition("#")
    repo_path = posixpath.normpath(posixpath.join("docs", posixpath.dirname(page_src_uri), path))
    if repo_path.split("/")[0] not in SHARED:
        return target
    new = posixpath.relpath(repo_path, posixpath.dirname(page_src_uri) or ".")
    return new + sep + anchor


def on_files(files, config):
    for rel in shared_files():
        if files.get_file_from_path(rel) is None:
            files.append(RepoFile(rel, str(REPO), config["site_dir"], config["use_directory_urls"]))
    return files


def on_page_markdown(markdown, page, config, files):
    src = page.file.src_uri
    lines, fenced = [], False
    for line in markdown.split("\n"):
        if line.lstrip().startswith(("```", "~~~")):
            fenced = not fenced
        if not fenced:
            line = _LINK.sub(lambda m: m.group(1) + site_target(src, m.group(2)), line)
        lines.append(line)
    return "\n".join(lines)


def on_page_content(html, page, config, files):
    if page.file.src_uri.startswith("api/"):
        html = _WORK_ITEM.sub("", html)
    return html
