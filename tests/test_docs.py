"""The front door: README length and links, the docs' generated CLI reference."""

from __future__ import annotations

import re
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
LINK = re.compile(r"\]\(([^)#\s]+)(#[^)]*)?\)")


def _links(path: Path) -> list[str]:
    return [m.group(1) for m in LINK.finditer(path.read_text()) if "://" not in m.group(1)]


def test_readme_is_short_and_its_links_exist() -> None:
    readme = ROOT / "README.md"
    assert len(readme.read_text().splitlines()) <= 250
    links = _links(readme)
    assert "docs/getting-started.md" in links
    for link in links:
        assert (ROOT / link).exists(), f"README links to missing {link}"


def test_docs_pages_link_to_existing_pages() -> None:
    pages = sorted((ROOT / "docs").rglob("*.md"))
    assert len(pages) >= 15
    for page in pages:
        for link in _links(page):
            assert (page.parent / link).exists(), f"{page.name} links to missing {link}"


def test_cli_reference_lists_every_command() -> None:
    sys.path.insert(0, str(ROOT / "tools" / "mkdocs_hooks"))
    try:
        import cli_reference
    finally:
        sys.path.pop(0)
    text = cli_reference.reference()
    for command in ("rgbd", "rgbd fuse", "rgbd eval fusion", "rgbd train shapes", "rgbd classify"):
        assert f"### `{command}`" in text
    assert "--tof-amplitude" in text and "usage: rgbd segment" in text
    page = "intro\n" + cli_reference.MARKER + "\nend"
    out = cli_reference.on_page_markdown(page)
    assert cli_reference.MARKER not in out and out.startswith("intro\n### `rgbd`")
    assert cli_reference.on_page_markdown("no marker") == "no marker"


def test_docstring_roles_become_code() -> None:
    sys.path.insert(0, str(ROOT / "tools" / "mkdocs_hooks"))
    try:
        import docstring_roles
    finally:
        sys.path.pop(0)
    html = "see :class:<code>~rgbd_rs.fusion.LcParams</code> and :func:<code>fuse</code>."
    assert docstring_roles.on_page_content(html) == (
        "see <code>LcParams</code> and <code>fuse</code>."
    )


def test_api_coverage_reports_a_public_name_without_an_entry(tmp_path: Path) -> None:
    import importlib

    sys.path.insert(0, str(ROOT / "tools" / "mkdocs_hooks"))
    try:
        import api_coverage
    finally:
        sys.path.pop(0)
    for page, packages in api_coverage.PAGES.items():
        ids = [
            f'<h2 id="{pkg}.{name}.{name}">' if name == "fuse" else f'<h2 id="{pkg}.{name}">'
            for pkg in packages
            for name in importlib.import_module(pkg).__all__
            if name != "lc_fuse"
        ]
        (tmp_path / page).parent.mkdir(parents=True, exist_ok=True)
        (tmp_path / page).write_text("\n".join(ids))
    assert api_coverage.missing(tmp_path) == ["api/fusion/index.html: rgbd_rs.fusion.lc_fuse"]
