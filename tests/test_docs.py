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
    import importlib.util

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


_SPAN = re.compile(r"`([^`\n]+)`")
_FLAG = re.compile(r"(?<![\w-])--([a-z][a-z0-9-]*)")


def _commands(text: str) -> list[str]:
    """Every shell command the page shows: inline code spans and fenced lines (continuations
    joined), split at ``&&``, ``;`` and pipes."""
    out: list[str] = []
    fenced, block = False, []
    for line in text.splitlines():
        if line.lstrip().startswith("```"):
            if fenced:
                out += " ".join(block).replace("\\ ", " ").splitlines()
            fenced, block = not fenced, []
            continue
        if fenced:
            block.append(
                line.split("#", 1)[0].rstrip() + ("" if line.rstrip().endswith("\\") else "\n")
            )
        else:
            out += _SPAN.findall(line)
    return [piece for cmd in out for piece in re.split(r"&&|\|\|?|;", cmd)]


def test_documented_cli_flags_exist() -> None:
    """Every ``rgbd <command> --flag`` the README and the docs show is an option of that command
    (the docs cannot drift from the parsers)."""
    sys.path.insert(0, str(ROOT / "tools" / "mkdocs_hooks"))
    try:
        import cli_reference
    finally:
        sys.path.pop(0)
    from rgbd_rs.cli import build_parser

    options: dict[tuple[str, ...], set[str]] = {}
    for path, parser in cli_reference._walk(build_parser(), ()):
        options[path] = {s for a in parser._actions for s in a.option_strings}
    pages = [ROOT / "README.md", *sorted((ROOT / "docs").rglob("*.md"))]
    wrong, checked = [], 0
    for page in pages:
        for cmd in _commands(page.read_text()):
            words = cmd.split()
            if "rgbd" not in words:
                continue
            rest = words[words.index("rgbd") + 1 :]
            path: tuple[str, ...] = ()
            while rest and any(p[: len(path) + 1] == (*path, rest[0]) for p in options):
                path, rest = (*path, rest[0]), rest[1:]
            if path not in options:
                continue
            for flag in _FLAG.findall(" ".join(rest)):
                checked += 1
                if f"--{flag}" not in options[path]:
                    wrong.append(f"{page.relative_to(ROOT)}: rgbd {' '.join(path)} --{flag}")
    assert checked > 100, checked
    assert not wrong, "\n".join(wrong)


_IMPORT = re.compile(r"^\s*from (rgbd_rs[\w.]*) import (\([^)]*\)|[^\n#]+)", re.M)


def _is_submodule(name: str) -> bool:
    import importlib.util

    try:
        return importlib.util.find_spec(name) is not None
    except ModuleNotFoundError:  # the parent is a plain module, not a package
        return False


def test_documented_imports_exist() -> None:
    """Every ``from rgbd_rs... import ...`` the README and the docs show imports."""
    import importlib.util

    pages = [ROOT / "README.md", *sorted((ROOT / "docs").rglob("*.md"))]
    wrong, checked = [], 0
    for page in pages:
        for module, names in _IMPORT.findall(page.read_text()):
            mod = importlib.import_module(module)
            for name in names.strip("()").replace("\n", " ").split(","):
                name = name.split(" as ")[0].strip()
                if not name:
                    continue
                checked += 1
                if not hasattr(mod, name) and not _is_submodule(f"{module}.{name}"):
                    wrong.append(f"{page.relative_to(ROOT)}: from {module} import {name}")
    assert checked > 30, checked
    assert not wrong, "\n".join(wrong)
