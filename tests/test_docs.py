"""The README and the documentation site's sources hold together (pure Python: no mkdocs needed).

- every page of mkdocs.yml's nav exists under docs/;
- every relative link and image in README.md and docs/**/*.md points to a file of the
  repository, resolved from the file that holds it (as the repository's web view does); a link
  from docs/ that leaves docs/ must land in a folder the site serves (results/, examples/:
  docs/hooks.py copies them into the site at the same path);
- the README is a short front door: at most 250 lines, a `lf-flame ...` command in a code block
  within its first 80 lines;
- no work-item numbers ("issue 35", "#56") in the README or the docs;
- every package name (``lf_flame.a.b.NAME``) and experiment script (``experiments/....py``) that the README,
  the docs or a results page names exists: a page written before code moved points the reader nowhere.
"""
from __future__ import annotations

import importlib
import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
DOCS = ROOT / "docs"
README = ROOT / "README.md"
#: folders outside docs/ that the site serves at the same path (docs/hooks.py, SHARED)
SITE_SHARED = ("results", "examples")
README_MAX_LINES = 250
QUICK_START_WITHIN = 80

LINK = re.compile(r"!?\[[^\]]*\]\(\s*<?([^)\s>]+)>?(?:\s+\"[^\"]*\")?\s*\)")
IMG_TAG = re.compile(r"<img\s[^>]*?src=[\"']([^\"']+)[\"']", re.IGNORECASE)
CODE_SPAN = re.compile(r"`[^`\n]*`")
SCHEME = re.compile(r"^[A-Za-z][A-Za-z0-9+.-]*:")
WORK_ITEM = re.compile(r"\bissues?\s*#?\s*\d+|(?<![\w&/#])#\d+\b", re.IGNORECASE)
PACKAGE_NAME = re.compile(r"\b(lf_flame(?:\.[A-Za-z_]\w*)+)")
SCRIPT = re.compile(r"\b(experiments/[\w/]+\.py)\b")


def markdown_files() -> list[Path]:
    return [README] + sorted(DOCS.rglob("*.md"))


def prose_lines(text: str):
    """(line number, line) outside fenced code blocks, with inline code spans blanked."""
    fenced = False
    for i, line in enumerate(text.split("\n"), 1):
        if line.lstrip().startswith(("```", "~~~")):
            fenced = not fenced
            continue
        if not fenced:
            yield i, CODE_SPAN.sub("``", line)


def relative_targets(path: Path):
    """(line number, target without its anchor) of every relative link and image in ``path``."""
    for i, line in prose_lines(path.read_text(encoding="utf-8")):
        for target in LINK.findall(line) + IMG_TAG.findall(line):
            if SCHEME.match(target) or target.startswith(("#", "/")):
                continue
            target = target.split("#", 1)[0].split("?", 1)[0]
            if target:
                yield i, target


def nav_pages(mkdocs_yml: str) -> list[str]:
    """The .md paths of mkdocs.yml's nav (``- Title: page.md`` or ``- page.md`` lines under ``nav:``)."""
    pages, in_nav = [], False
    for line in mkdocs_yml.splitlines():
        if re.match(r"^nav\s*:", line):
            in_nav = True
            continue
        if in_nav and line and not line[0].isspace():
            break
        m = re.match(r"^\s*-\s*(?:[^:]+:\s*)?([^\s:]+\.md)\s*$", line)
        if in_nav and m:
            pages.append(m.group(1))
    return pages


def test_nav_pages_exist():
    cfg = (ROOT / "mkdocs.yml").read_text(encoding="utf-8")
    assert re.search(r"^docs_dir:\s*docs\s*$", cfg, re.MULTILINE), "mkdocs.yml's docs_dir is not docs"
    pages = nav_pages(cfg)
    assert len(pages) >= 20, f"mkdocs.yml's nav lists only {pages}"
    missing = [p for p in pages if not (DOCS / p).is_file()]
    assert not missing, f"pages in mkdocs.yml's nav that docs/ lacks: {missing}"
    for kept in ("architecture.md", "deviations.md", "diagnostics.md", "hard_cases.md", "own_camera.md", "scenes.md"):
        assert kept in pages, f"docs/{kept} is not in the nav"


def test_every_relative_link_and_image_resolves():
    broken = []
    for md in markdown_files():
        for line, target in relative_targets(md):
            resolved = (md.parent / target).resolve()
            where = f"{md.relative_to(ROOT)}:{line}: {target}"
            if not resolved.exists():
                broken.append(f"{where} (no such file)")
                continue
            if md.is_relative_to(DOCS) and not resolved.is_relative_to(DOCS):
                rel = resolved.relative_to(ROOT).parts
                if rel[0] not in SITE_SHARED:
                    broken.append(f"{where} (outside docs/, and the site serves only {SITE_SHARED})")
    assert not broken, "broken links or images:\n" + "\n".join(broken)


def test_readme_is_a_short_front_door():
    lines = README.read_text(encoding="utf-8").split("\n")
    n = len(lines) - (lines[-1] == "")
    assert n <= README_MAX_LINES, f"README.md has {n} lines (at most {README_MAX_LINES})"
    fenced, first = False, None
    for i, line in enumerate(lines, 1):
        if line.lstrip().startswith("```"):
            fenced = not fenced
        elif fenced and line.startswith("lf-flame "):
            first = i
            break
    assert first is not None, "no `lf-flame ...` command in a code block of README.md"
    assert first <= QUICK_START_WITHIN, f"the first `lf-flame` command is on line {first} (want <= {QUICK_START_WITHIN})"


@pytest.mark.parametrize("md", markdown_files(), ids=lambda p: str(p.relative_to(ROOT)))
def test_no_work_item_numbers(md):
    hits = [f"{md.relative_to(ROOT)}:{i}: {m.group(0)!r}" for i, line in enumerate(md.read_text(encoding="utf-8").split("\n"), 1)
            for m in WORK_ITEM.finditer(line)]
    assert not hits, "work-item numbers (name the feature instead):\n" + "\n".join(hits)


def resolves(name: str) -> bool:
    """Whether a dotted name is a module of the package or an attribute of one (imported as its readers would)."""
    parts = name.split(".")
    for k in range(len(parts), 0, -1):
        try:
            obj = importlib.import_module(".".join(parts[:k]))
        except ImportError:
            continue
        for attr in parts[k:]:
            if not hasattr(obj, attr):
                return False
            obj = getattr(obj, attr)
        return True
    return False


def named_code(paths):
    """(where, package name or script path) of every ``lf_flame...`` name and ``experiments/...py`` path in
    ``paths``, code spans and blocks included."""
    for md in paths:
        page = md.relative_to(ROOT) if md.is_relative_to(ROOT) else md
        for i, line in enumerate(md.read_text(encoding="utf-8").split("\n"), 1):
            for m in list(PACKAGE_NAME.finditer(line)) + list(SCRIPT.finditer(line)):
                yield f"{page}:{i}", m.group(1)


def test_every_named_module_function_and_script_exists():
    pages = markdown_files() + sorted((ROOT / "results").rglob("*.md"))
    missing = [f"{where}: {name}" for where, name in named_code(pages)
               if not ((ROOT / name).is_file() if name.startswith("experiments/") else resolves(name))]
    assert not missing, "names of code that does not exist (moved or renamed?):\n" + "\n".join(missing)


def test_the_checks_catch_what_they_should(tmp_path):
    """The parsers find links, images, nav pages and work items, and skip code."""
    md = tmp_path / "page.md"
    md.write_text('See [a](a.md#x), ![b](../results/b.png){ width="3" } and <img src="c.png" width="9">.\n'
                  "`[not](a link.md)` [web](https://example.org) [here](#top)\n"
                  "```\n[in code](nowhere.md)\n```\n", encoding="utf-8")
    assert [t for _, t in relative_targets(md)] == ["a.md", "../results/b.png", "c.png"]
    assert nav_pages("site_name: x\nnav:\n  - Home: index.md\n  - Guide:\n      - One: guide/one.md\n"
                     "  - api/x.md\nplugins:\n  - search\n") == ["index.md", "guide/one.md", "api/x.md"]
    assert WORK_ITEM.search("see issue 35") and WORK_ITEM.search("Issue #7") and WORK_ITEM.search("as in #56")
    assert not WORK_ITEM.search("| # | case |") and not WORK_ITEM.search("[x](a.md#56-b)") and not WORK_ITEM.search("&#8212;")
    md.write_text("`lf_flame.tomo.found_planes.find_planes` and `lf_flame.tomo.depth.find_planes` in "
                  "`python experiments/depth.py` beside experiments/flame_tail.py.\n", encoding="utf-8")
    assert [n for _, n in named_code([md])] == ["lf_flame.tomo.found_planes.find_planes",
                                                "lf_flame.tomo.depth.find_planes", "experiments/depth.py",
                                                "experiments/flame_tail.py"]
    assert resolves("lf_flame.tomo.found_planes.find_planes") and resolves("lf_flame.tomo.found_planes")
    assert not resolves("lf_flame.tomo.depth.find_planes") and not resolves("lf_flame.diagnostics.EMISSION_MEASURE")
