"""tools/check_wheel_deps.py: the imports-vs-Requires-Dist check `make wheel` runs, on the real
pyproject and on fake packages with an undeclared, a wrongly pinned or an extra-only import."""

from __future__ import annotations

import importlib.util
import sys
import textwrap
import zipfile
from importlib import metadata
from pathlib import Path
from types import ModuleType

import pytest

ROOT = Path(__file__).resolve().parents[1]


def _load() -> ModuleType:
    spec = importlib.util.spec_from_file_location(
        "check_wheel_deps", ROOT / "tools" / "check_wheel_deps.py"
    )
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module  # dataclasses look their module up
    spec.loader.exec_module(module)
    return module


cwd = _load()


def fake(
    tmp_path: Path,
    files: dict[str, str],
    deps: list[str],
    extras: dict[str, list[str]] | None = None,
    requires_python: str = ">=3.10",
) -> list[str]:
    """The problems check() finds in a maturin-style package ``fakepkg`` under tmp_path."""
    lines = [
        "[project]",
        'name = "fakepkg"',
        f'requires-python = "{requires_python}"',
        f"dependencies = {deps!r}",
        "[project.optional-dependencies]",
        *(f"{k} = {v!r}" for k, v in (extras or {}).items()),
        "[tool.maturin]",
        'python-source = "python"',
        'module-name = "fakepkg._native"',
    ]
    tmp_path.mkdir(parents=True, exist_ok=True)
    (tmp_path / "pyproject.toml").write_text("\n".join(lines).replace("'", '"') + "\n")
    pkg = tmp_path / "python" / "fakepkg"
    pkg.mkdir(parents=True)
    (pkg / "__init__.py").write_text("from fakepkg import sub\nfrom . import sub as _s\n")
    for name, text in files.items():
        (pkg / name).write_text(textwrap.dedent(text))
    problems, _ = cwd.check(cwd.read_pyproject(tmp_path / "pyproject.toml", None))
    return list(problems)


def test_the_real_pyproject_passes() -> None:
    problems, report = cwd.check(cwd.read_pyproject(ROOT / "pyproject.toml", None))
    assert problems == []
    modules = {line.split()[0] for line in report}
    assert {"numpy", "torch", "cv2", "scipy", "trimesh", "tqdm"} <= modules


def test_an_undeclared_import_is_flagged(tmp_path: Path) -> None:
    problems = fake(tmp_path, {"sub.py": "import numpy\nfrom scipy import sparse\n"}, ["numpy>=2"])
    assert len(problems) == 1
    assert "sub.py:2: imports 'scipy'" in problems[0] and "no requirement declares" in problems[0]


def test_an_undeclared_import_in_a_function_or_by_name_is_flagged(tmp_path: Path) -> None:
    src = """
    import importlib

    def f():
        import scipy.io

    def g():
        return importlib.import_module("trimesh")
    """
    problems = fake(tmp_path, {"sub.py": src}, [])
    assert len(problems) == 2
    assert "imports 'scipy'" in problems[0] and "in a function" in problems[0]
    assert "sub.py:8: imports 'trimesh'" in problems[1]


def test_a_wrong_pin_is_flagged(tmp_path: Path) -> None:
    assert int(metadata.version("numpy").split(".")[0]) >= 2
    problems = fake(tmp_path, {"sub.py": "import numpy\n"}, ["numpy<1"])
    assert len(problems) == 1
    assert problems[0].startswith("numpy<1 (core): the installed numpy 2.")
    problems = fake(tmp_path / "b", {"sub.py": "x = 1\n"}, [], {"eval": ["scipy<1"]})
    assert len(problems) == 1 and "scipy<1 (extra 'eval')" in problems[0]


def test_an_extra_only_import_must_be_deferred(tmp_path: Path) -> None:
    """A module-level import of an extra's distribution breaks `import fakepkg.sub` for users
    without the extra; in a function, or guarded by except ImportError, it is optional."""
    problems = fake(tmp_path, {"sub.py": "import scipy\n"}, [], {"eval": ["scipy>=1"]})
    assert len(problems) == 1 and "only in the extra(s) eval" in problems[0]
    src = """
    from typing import TYPE_CHECKING

    if TYPE_CHECKING:
        import torch  # for the type checker only: never run
    try:
        import h5py
    except ImportError:
        h5py = None
    try:
        import embreex  # not installed: matched by the requirement's name
    except (ModuleNotFoundError, OSError):
        embreex = None

    def f():
        import scipy
    """
    extras = {"eval": ["scipy>=1", "h5py>=3"], "bench": ["embreex>=2"]}
    assert fake(tmp_path / "b", {"sub.py": src}, [], extras) == []


def test_an_import_only_the_dev_extra_declares_is_flagged(tmp_path: Path) -> None:
    src = "def f():\n    import pytest\n"
    problems = fake(tmp_path, {"sub.py": src}, [], {"dev": ["pytest>=8"]})
    assert len(problems) == 1 and "developers' extra(s) dev" in problems[0]


def test_requires_python(tmp_path: Path) -> None:
    problems = fake(tmp_path, {"sub.py": ""}, [], requires_python=">=4")
    assert len(problems) == 1 and "outside Requires-Python >=4" in problems[0]


def test_a_wheel_metadata_with_extras_markers(tmp_path: Path) -> None:
    whl = tmp_path / "fakepkg-0.1-py3-none-any.whl"
    meta = [
        "Metadata-Version: 2.4",
        "Name: fakepkg",
        "Version: 0.1",
        "Requires-Dist: numpy>=2",
        'Requires-Dist: pywin32>=1 ; sys_platform == "win32"',
        'Requires-Dist: scipy>=1 ; extra == "eval"',
        "Provides-Extra: eval",
    ]
    with zipfile.ZipFile(whl, "w") as z:
        z.writestr("fakepkg-0.1.dist-info/METADATA", "\n".join(meta) + "\n")
        z.writestr("fakepkg/__init__.py", "import numpy\nimport scipy\n")
    pkg = cwd.read_wheel(whl)
    assert [(str(d.req.name), d.extra) for d in pkg.requires] == [
        ("numpy", None),
        ("pywin32", None),
        ("scipy", "eval"),
    ]
    problems, _ = cwd.check(pkg)  # pywin32: not for this platform, so not missing
    assert len(problems) == 1
    assert "fakepkg/__init__.py:2: imports 'scipy' at module level" in problems[0]


def test_the_cli_on_a_copy_without_scipy(tmp_path: Path, capsys: pytest.CaptureFixture) -> None:
    text = (ROOT / "pyproject.toml").read_text()
    assert '    "scipy>=1.11",\n' in text
    (tmp_path / "pyproject.toml").write_text(text.replace('    "scipy>=1.11",\n', ""))
    args = [str(tmp_path / "pyproject.toml"), "--source", str(ROOT / "python" / "rgbd_rs")]
    assert cwd.main(args) == 1
    err = capsys.readouterr().err
    assert "imports 'scipy'" in err and "no requirement declares it" in err
    assert cwd.main([str(ROOT / "pyproject.toml")]) == 0


def test_link_into_holds_the_closure_only(tmp_path: Path) -> None:
    req = cwd.Requirement
    pkg = cwd.Package(
        "fakepkg",
        [cwd.Declared(req("trimesh>=4"), None), cwd.Declared(req("scipy>=1"), "eval")],
        None,
    )
    site = tmp_path / "site"
    lines = cwd.link_into(site, pkg)
    names = {p.name for p in site.iterdir()}
    # trimesh needs numpy (its extras' requirements are not followed): nothing else.
    assert {"trimesh", "numpy"} <= names and "scipy" not in names and "torch" not in names
    version = metadata.version("trimesh")
    assert f"trimesh-{version}.dist-info" in names and (site / "trimesh").is_symlink()
    assert lines[0].startswith("linked 2 distributions")
    with pytest.raises(SystemExit, match=r"numpy<1: needed, installed 2\."):
        cwd.closure([req("trimesh"), req("numpy<1")])
