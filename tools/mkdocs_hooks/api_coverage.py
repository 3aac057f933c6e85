"""mkdocs hook: the API reference leaves out no public name.

After the build, every name in the ``__all__`` of each documented package must have its anchor
on that package's page (``id="rgbd_rs.fusion.lc_fuse"``, or under a parent package that
re-exports it: ``rgbd_rs.data.generate_indoor`` for ``rgbd_rs.data.synth_indoor``; a function
that shares its name with its own submodule, such as ``rgbd_rs.fusion.fuse``, is documented
from the submodule: ``rgbd_rs.fusion.fuse.fuse``). A missing one fails the build, so a new
public function cannot ship without a reference entry.
"""

from __future__ import annotations

import importlib
from pathlib import Path
from typing import Any

#: API page (under site/) -> the packages whose ``__all__`` it documents.
PAGES = {
    "api/core/index.html": ("rgbd_rs",),
    "api/fusion/index.html": ("rgbd_rs.fusion",),
    "api/segmentation/index.html": ("rgbd_rs.segmentation",),
    "api/shapes/index.html": ("rgbd_rs.shapes", "rgbd_rs.shapes.curvature"),
    "api/nn/index.html": ("rgbd_rs.nn",),
    "api/data/index.html": (
        "rgbd_rs.data",
        "rgbd_rs.data.nyuv2",
        "rgbd_rs.data.nyuv2_mat",
        "rgbd_rs.data.synth_indoor",
    ),
    "api/tools/index.html": (
        "rgbd_rs.surface",
        "rgbd_rs.render",
        "rgbd_rs.meshes",
        "rgbd_rs.metrics",
        "rgbd_rs.io",
        "rgbd_rs.viz",
    ),
}


def missing(site: Path) -> list[str]:
    """The public names without an anchor on their page, as ``page: package.name``."""
    out = []
    for page, packages in PAGES.items():
        html = (site / page).read_text()
        for package in packages:
            for name in importlib.import_module(package).__all__:
                if name.startswith("__"):
                    continue
                # documented under the package or where a parent package re-exports it
                parts = package.split(".")
                owners = [".".join(parts[:k]) for k in range(len(parts), 0, -1)]
                ids = [f'id="{o}.{name}"' for o in owners] + [f'id="{package}.{name}.{name}"']
                if not any(i in html for i in ids):
                    out.append(f"{page}: {package}.{name}")
    return out


def on_post_build(config: Any, **_: Any) -> None:
    """Fail the build when a public name has no entry."""
    gaps = missing(Path(config["site_dir"]))
    if gaps:
        raise SystemExit("API reference misses public names:\n  " + "\n  ".join(gaps))
