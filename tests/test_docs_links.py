"""The documentation holds together: docs/index.md links every page, and every relative link in the
README and docs/ (files and #anchors) points at something that exists. Pure text, no device."""
from __future__ import annotations

import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
DOCS = ROOT / "docs"
LINK = re.compile(r"\]\(([^)\s]+)\)")


def anchors(path: Path) -> set:
    """GitHub's heading anchors: lower case, punctuation dropped, spaces to hyphens."""
    out = set()
    for line in path.read_text().splitlines():
        m = re.match(r"#+\s+(.*)", line)
        if m:
            text = re.sub(r"[^\w\- ]", "", m.group(1).strip().lower())
            out.add(text.replace(" ", "-"))
    return out


def broken_links(page: Path, root: Path = ROOT) -> list:
    bad = []
    for target in LINK.findall(page.read_text()):
        if re.match(r"[a-z]+:", target):             # http:, https:, mailto:
            continue
        file, _, anchor = target.partition("#")
        dest = (page.parent / file).resolve() if file else page
        if not dest.exists():
            bad.append(f"{page.relative_to(root)}: {target} (no such file)")
        elif anchor and dest.suffix == ".md" and anchor not in anchors(dest):
            bad.append(f"{page.relative_to(root)}: {target} (no such heading)")
    return bad


def test_docs_index_links_every_page():
    linked = {t.partition("#")[0] for t in LINK.findall((DOCS / "index.md").read_text())}
    pages = {p.name for p in DOCS.glob("*.md") if p.name != "index.md"}
    assert pages - linked == set(), f"pages docs/index.md does not list: {sorted(pages - linked)}"


@pytest.mark.parametrize("page", [ROOT / "README.md", *sorted(DOCS.glob("*.md"))], ids=lambda p: p.name)
def test_relative_links_resolve(page):
    assert broken_links(page) == []


def test_the_link_checker_reports_a_broken_link(tmp_path):
    page = tmp_path / "a.md"
    (tmp_path / "b.md").write_text("# Real heading\n")
    page.write_text("[x](b.md#real-heading) [y](missing.md) [z](b.md#no-heading) [w](https://example.org)\n")
    assert [b.split(": ", 1)[1] for b in broken_links(page, tmp_path)] == ["missing.md (no such file)",
                                                                           "b.md#no-heading (no such heading)"]
