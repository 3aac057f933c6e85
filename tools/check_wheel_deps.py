"""Check a package's imports against its declared requirements (``make wheel`` runs it).

``python tools/check_wheel_deps.py dist/rgbd_rs-*.whl`` reads the wheel's ``Requires-Dist``
(its METADATA, extras markers included) and parses every ``.py`` file in it with :mod:`ast`;
``python tools/check_wheel_deps.py pyproject.toml --source python/rgbd_rs`` does the same from a
``pyproject.toml`` and a source folder. It fails (exit 1, one line per problem) when

* a third-party module the package imports belongs to no declared requirement;
* a module imported at module level (run by ``import rgbd_rs.x``) is declared only in an extra:
  users without the extra could not import that module. Imports inside functions, or guarded
  by ``try: ... except ImportError``, are optional features and may come from an extra;
* a declared requirement installed here (the dev environment, where the package is developed
  and tested) does not satisfy its specifier, e.g. ``numpy<1`` with numpy 2.x installed;
* the running Python is outside ``Requires-Python``.

Imports under ``if TYPE_CHECKING:`` are ignored, as are the standard library, the package
itself and relative imports; ``importlib.import_module("x")`` / ``__import__("x")`` with a
constant name count as imports. Modules map to distributions through
:func:`importlib.metadata.packages_distributions` of the running environment (a module nothing
installed provides may still match a requirement of the same name).

``--link-into SITE_PACKAGES`` then fills a fresh venv's site-packages with symbolic links to
exactly the distributions the core requirements need: their closure over ``Requires-Dist`` of
the installed metadata, markers and extras evaluated for this interpreter. That venv sees what a
user's ``pip install`` would give (same versions as the dev environment), without downloading
torch again: an undeclared dependency is simply absent there and ``pip check`` can verify the
declared pins. Runs in seconds.
"""

from __future__ import annotations

import argparse
import ast
import email.parser
import functools
import sys
import zipfile
from collections.abc import Iterable, Iterator
from dataclasses import dataclass, field
from importlib import metadata
from pathlib import Path

import tomllib
from packaging.markers import default_environment
from packaging.requirements import Requirement
from packaging.specifiers import SpecifierSet
from packaging.utils import canonicalize_name

MODULE, DEFERRED, GUARDED = "module level", "in a function", "guarded by except ImportError"
IMPORT_ERRORS = {"ImportError", "ModuleNotFoundError"}
DEV_EXTRAS = ("dev",)  # the developers' extra: an import of the package may not rely on it


@dataclass(frozen=True)
class Import:
    """One absolute import of a top-level module ``name`` at ``where`` (``path:line``)."""

    name: str
    where: str
    kind: str  # MODULE, DEFERRED or GUARDED


@dataclass(frozen=True)
class Declared:
    """A requirement and the extra it belongs to (None: a core dependency)."""

    req: Requirement
    extra: str | None


@dataclass
class Package:
    """What the checks need: name, declared requirements, Requires-Python and the sources."""

    name: str
    requires: list[Declared]
    requires_python: str | None
    sources: dict[str, str] = field(default_factory=dict)  # path -> text


# -- reading a wheel or a pyproject ------------------------------------------------------------


def _environment() -> dict[str, str]:
    """The marker variables of the running interpreter (``extra`` is set per evaluation)."""
    return {k: str(v) for k, v in default_environment().items()}


def _split_extra(req: Requirement, extras: Iterable[str]) -> str | None:
    """The extra a Requires-Dist line belongs to (None when it applies without any)."""
    if req.marker is None:
        return None
    env = _environment()
    if req.marker.evaluate({**env, "extra": ""}):
        return None
    for extra in extras:
        if req.marker.evaluate({**env, "extra": extra}):
            return extra
    return None  # a platform marker that is false here: core, not for this platform


def read_wheel(path: Path) -> Package:
    with zipfile.ZipFile(path) as z:
        names = z.namelist()
        meta_name = next(n for n in names if n.endswith(".dist-info/METADATA"))
        meta = email.parser.Parser().parsestr(z.read(meta_name).decode())
        sources = {n: z.read(n).decode() for n in names if n.endswith(".py")}
    extras = meta.get_all("Provides-Extra") or []
    reqs = [Requirement(r) for r in meta.get_all("Requires-Dist") or []]
    return Package(
        meta["Name"],
        [Declared(r, _split_extra(r, extras)) for r in reqs],
        meta.get("Requires-Python"),
        sources,
    )


def read_pyproject(path: Path, source: Path | None) -> Package:
    data = tomllib.loads(path.read_text())
    project = data["project"]
    requires = [Declared(Requirement(r), None) for r in project.get("dependencies", [])]
    for extra, reqs in project.get("optional-dependencies", {}).items():
        requires += [Declared(Requirement(r), extra) for r in reqs]
    if source is None:  # maturin's layout: python-source / <top package of module-name>
        maturin = data.get("tool", {}).get("maturin", {})
        top = maturin.get("module-name", project["name"]).split(".")[0]
        source = path.parent / maturin.get("python-source", ".") / top
    files = sorted(source.rglob("*.py"))
    if not files:
        raise SystemExit(f"{source}: no .py files, expected the package's source folder")
    sources = {str(f.relative_to(source.parent)): f.read_text() for f in files}
    return Package(project["name"], requires, project.get("requires-python"), sources)


# -- the imports -------------------------------------------------------------------------------


def _catches_import_error(node: ast.Try) -> bool:
    for handler in node.handlers:
        types = handler.type
        names = types.elts if isinstance(types, ast.Tuple) else [types]
        for t in names:
            if isinstance(t, ast.Name) and t.id in IMPORT_ERRORS:
                return True
    return False


def _is_type_checking(test: ast.expr) -> bool:
    return (isinstance(test, ast.Name) and test.id == "TYPE_CHECKING") or (
        isinstance(test, ast.Attribute) and test.attr == "TYPE_CHECKING"
    )


def _dynamic_import(node: ast.Call) -> str | None:
    """``importlib.import_module("x.y")`` / ``import_module(...)`` / ``__import__(...)``."""
    f = node.func
    name = f.attr if isinstance(f, ast.Attribute) else f.id if isinstance(f, ast.Name) else ""
    if name not in ("import_module", "__import__") or not node.args:
        return None
    arg = node.args[0]
    return arg.value if isinstance(arg, ast.Constant) and isinstance(arg.value, str) else None


def imports_of(path: str, text: str) -> Iterator[Import]:
    """Every absolute import in one source file, with where it runs."""

    def walk(node: ast.AST, kind: str) -> Iterator[Import]:
        for child in ast.iter_child_nodes(node):
            k = kind
            if isinstance(child, (ast.FunctionDef, ast.AsyncFunctionDef, ast.Lambda)):
                k = DEFERRED if kind == MODULE else kind
            if isinstance(child, ast.If) and _is_type_checking(child.test):
                for sub in child.orelse:  # the body is for the type checker only
                    yield from walk_one(sub, k)
                continue
            if isinstance(child, ast.Try) and _catches_import_error(child):
                for guarded in child.body:
                    yield from walk_one(guarded, GUARDED)
                rest: list[ast.AST] = [*child.handlers, *child.orelse, *child.finalbody]
                for other in rest:
                    yield from walk_one(other, k)
                continue
            yield from walk_one(child, k)

    def walk_one(node: ast.AST, kind: str) -> Iterator[Import]:
        where = f"{path}:{getattr(node, 'lineno', 0)}"
        if isinstance(node, ast.Import):
            for alias in node.names:
                yield Import(alias.name.split(".")[0], where, kind)
        elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
            yield Import(node.module.split(".")[0], where, kind)
        elif isinstance(node, ast.Call) and (name := _dynamic_import(node)):
            yield Import(name.split(".")[0], where, kind)
        yield from walk(node, kind)

    yield from walk(ast.parse(text, filename=path), MODULE)


def third_party_imports(pkg: Package) -> list[Import]:
    own = {pkg.name.replace("-", "_"), canonicalize_name(pkg.name).replace("-", "_")}
    out = []
    for path, text in sorted(pkg.sources.items()):
        for imp in imports_of(path, text):
            if imp.name not in sys.stdlib_module_names and imp.name not in own:
                out.append(imp)
    return out


# -- the checks --------------------------------------------------------------------------------


@functools.cache
def _packages_distributions() -> dict[str, list[str]]:
    return dict(metadata.packages_distributions())


def installed_version(name: str) -> str | None:
    try:
        return metadata.version(name)
    except metadata.PackageNotFoundError:
        return None


def check(pkg: Package, dev_extras: Iterable[str] = DEV_EXTRAS) -> tuple[list[str], list[str]]:
    """(problems, report lines) of ``pkg`` against the running environment. ``dev_extras``
    are for developers only: no import of the package may rely on them."""
    dev = set(dev_extras)
    problems: list[str] = []
    report: list[str] = []
    env = _environment()
    if pkg.requires_python and env["python_full_version"] not in SpecifierSet(pkg.requires_python):
        problems.append(
            f"Python {env['python_full_version']} is outside Requires-Python {pkg.requires_python}"
        )
    core: dict[str, Requirement] = {}
    extras: dict[str, dict[str, Requirement]] = {}
    for d in pkg.requires:
        key = str(canonicalize_name(d.req.name))
        if d.extra is None:
            core[key] = d.req
        else:
            extras.setdefault(key, {})[d.extra] = d.req

    # Every declared requirement installed here satisfies its specifier.
    for d in pkg.requires:
        version = installed_version(d.req.name)
        if version is None:
            if d.extra is None and (d.req.marker is None or d.req.marker.evaluate()):
                problems.append(
                    f"{d.req}: a core requirement, not installed here so its pin is unchecked "
                    "(make env installs it)"
                )
            continue
        if not d.req.specifier.contains(version, prereleases=True):
            where = "core" if d.extra is None else f"extra {d.extra!r}"
            problems.append(
                f"{d.req} ({where}): the installed {d.req.name} {version}, which the package "
                f"is developed and tested with, does not satisfy {d.req.specifier}"
            )

    # Every third-party import belongs to a declared requirement.
    dists_of = _packages_distributions()
    by_module: dict[str, list[Import]] = {}
    for imp in third_party_imports(pkg):
        by_module.setdefault(imp.name, []).append(imp)
    for name, imps in sorted(by_module.items()):
        dists = [str(canonicalize_name(d)) for d in dists_of.get(name, [])]
        dists = dists or [str(canonicalize_name(name))]  # not installed: a requirement of that name
        in_core = [d for d in dists if d in core]
        in_dev = sorted({e for d in dists for e in extras.get(d, {}) if e in dev})
        in_extras = sorted({e for d in dists for e in extras.get(d, {}) if e not in dev})
        at_module = [i for i in imps if i.kind == MODULE]
        first = (at_module or imps)[0]
        user = [d for d in dists if set(extras.get(d, {})) - dev]
        dist = (in_core or user or [d for d in dists if d in extras] or dists)[0]
        if not in_core and not in_extras and in_dev:
            problems.append(
                f"{first.where}: imports {name!r} ({first.kind}), but {dist} is only in the "
                f"developers' extra(s) {', '.join(in_dev)}, which users do not install: "
                "declare it in [project].dependencies or in a user-facing extra"
            )
            continue
        if not in_core and not in_extras:
            problems.append(
                f"{first.where}: imports {name!r} (distribution {dist}, {first.kind}) but no "
                "requirement declares it: add it to [project].dependencies (or to an extra "
                "when only an optional feature needs it)"
            )
            continue
        if not in_core and at_module:
            problems.append(
                f"{at_module[0].where}: imports {name!r} at module level, but {dist} is only "
                f"in the extra(s) {', '.join(in_extras)}: without them that module cannot be "
                "imported; declare it in [project].dependencies or import it where it is used"
            )
            continue
        req = core.get(dist) or next(r for e, r in extras[dist].items() if e not in dev)
        how = "core" if in_core else f"extra {', '.join(in_extras)}"
        kinds = sorted({i.kind for i in imps})
        report.append(
            f"  {name:<10} {req.name + str(req.specifier):<34} "
            f"{installed_version(dist) or '-':<14} {how}: "
            f"{len(imps)} import(s), {'; '.join(kinds)}"
        )
    imported = {str(canonicalize_name(d)) for n in by_module for d in dists_of.get(n, [n])}
    imported |= set(by_module)
    for name, req in core.items():
        if name not in imported:
            report.append(f"  (note) core requirement {req} is never imported by the package")
    return problems, report


# -- the linked venv ---------------------------------------------------------------------------


def closure(reqs: Iterable[Requirement]) -> dict[str, metadata.Distribution]:
    """The installed distributions ``reqs`` need, transitively (markers and extras evaluated
    for the running interpreter). Raises SystemExit naming a missing or wrongly pinned one."""
    env = _environment()
    todo = [(r, frozenset[str]()) for r in reqs]
    done: dict[str, metadata.Distribution] = {}
    seen: set[tuple[str, frozenset[str]]] = set()
    while todo:
        req, parent_extras = todo.pop()
        if req.marker is not None and not any(
            req.marker.evaluate({**env, "extra": e}) for e in (parent_extras or {""})
        ):
            continue
        key = canonicalize_name(req.name)
        extras = frozenset(req.extras)
        if (key, extras) in seen:
            continue
        seen.add((key, extras))
        try:
            dist = metadata.distribution(req.name)
        except metadata.PackageNotFoundError:
            raise SystemExit(f"{req}: needed, not installed in {sys.prefix}") from None
        if not req.specifier.contains(dist.version, prereleases=True):
            raise SystemExit(f"{req}: needed, installed {dist.version}")
        done[key] = dist
        todo += [(Requirement(r), extras) for r in dist.requires or []]
    return done


def top_level_entries(dist: metadata.Distribution) -> set[str]:
    """The names a distribution installs directly in site-packages (packages, modules, its
    .dist-info, .libs folders, .pth files); not its scripts (``../../bin/x``)."""
    tops = set()
    for f in dist.files or []:
        parts = Path(str(f)).parts
        if parts and parts[0] not in ("..", "__pycache__") and not Path(str(f)).is_absolute():
            tops.add(parts[0])
    return tops


def link_into(site: Path, pkg: Package) -> list[str]:
    """Link the core requirements' closure into ``site``; the report lines."""
    site.mkdir(parents=True, exist_ok=True)
    own = canonicalize_name(pkg.name)
    needed = {k: d for k, d in closure(d.req for d in pkg.requires if d.extra is None).items()}
    needed.pop(own, None)
    owners: dict[str, set[str]] = {}  # top-level entry -> every installed distribution using it
    for dist in metadata.distributions():
        for top in top_level_entries(dist):
            owners.setdefault(top, set()).add(canonicalize_name(dist.metadata["Name"]))
    linked, shared = 0, set()
    for key, dist in sorted(needed.items()):
        for top in sorted(top_level_entries(dist)):
            target = Path(str(dist.locate_file(top)))
            dest = site / top
            if dest.is_symlink() or dest.exists() or not target.exists():
                continue
            dest.symlink_to(target, target_is_directory=target.is_dir())
            linked += 1
            others = owners.get(top, set()) - set(needed) - {key}
            if others:
                shared.add(f"{top} (also {', '.join(sorted(others))})")
    lines = [
        f"linked {len(needed)} distributions ({linked} entries) into {site}: "
        + ", ".join(f"{d.metadata['Name']} {d.version}" for _, d in sorted(needed.items()))
    ]
    if shared:
        lines.append("  shared with undeclared distributions: " + "; ".join(sorted(shared)))
    return lines


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("path", type=Path, help="a .whl, or a pyproject.toml")
    parser.add_argument(
        "--source", type=Path, help="with a pyproject.toml: the package's source folder"
    )
    parser.add_argument(
        "--link-into",
        type=Path,
        metavar="SITE_PACKAGES",
        help="then link the core requirements' closure into this site-packages folder",
    )
    args = parser.parse_args(argv)
    if args.path.suffix == ".whl":
        pkg = read_wheel(args.path)
    else:
        pkg = read_pyproject(args.path, args.source)
    problems, report = check(pkg)
    print(
        f"{args.path.name}: {len(pkg.sources)} Python files, {len(pkg.requires)} declared "
        f"requirements; third-party imports:"
    )
    print("\n".join(report))
    if problems:
        print(f"{len(problems)} problem(s) with the declared dependencies:", file=sys.stderr)
        for p in problems:
            print(f"  {p}", file=sys.stderr)
        return 1
    if args.link_into is not None:
        print("\n".join(link_into(args.link_into, pkg)))
    return 0


if __name__ == "__main__":
    sys.exit(main())
