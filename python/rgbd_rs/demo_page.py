"""``out/demo/index.html``: every figure of ``rgbd demo`` on one page, with what it printed."""

from __future__ import annotations

import html
import io
import sys
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

from rgbd_rs.io import write_text

__all__ = ["FIGURES", "capture", "write_index"]

#: The demo's figures in page order, with their captions.
FIGURES = (
    (
        "synthetic_reprojection.png",
        "Camera geometry: an analytic depth map of distorted camera A reprojected into distorted "
        "camera B, against B's analytic depth; the error scaled to its 99th percentile, and where "
        "B got no value (occlusion or outside A's view).",
    ),
    (
        "kinect_depth_to_color.png",
        "The real Azure Kinect ToF frame reprojected onto its colour camera (depth on one scale "
        "in metres; amplitude in log10 of its own unit).",
    ),
    (
        "fusion.png",
        "ToF-stereo fusion (thesis Fig. 3.4 layout) of a rendered SYNTH3-style scene: the "
        "default fusion (census SGM + the shipped confidence ConvNet + LC) beside its inputs; "
        "errors 0-3 px, excluded pixels grey.",
    ),
    (
        "segmentation.png",
        "RGB-D segmentation and semantic labeling of a real NYUv2 frame with the shipped "
        "semantic ConvNet, against NYUv2's ground truth.",
    ),
    (
        "shapes.png",
        "Shape classification: what the 15-branch network reads for a real ModelNet mesh (six "
        "depth views, six curvature maps, three voxel density profiles, each normalised) and "
        "its answer with the shipped ModelNet40 weights.",
    ),
)


class _Tee(io.TextIOBase):
    """Writes to the real stdout and keeps a copy."""

    def __init__(self, real: io.TextIOBase) -> None:
        self.real, self.copy = real, io.StringIO()

    def write(self, s: str) -> int:
        self.copy.write(s)
        return self.real.write(s)

    def flush(self) -> None:
        self.real.flush()


@contextmanager
def capture() -> Iterator[io.StringIO]:
    """Everything printed inside the block still prints, and is kept in the yielded buffer."""
    tee = _Tee(sys.stdout)  # type: ignore[arg-type]
    old, sys.stdout = sys.stdout, tee
    try:
        yield tee.copy
    finally:
        sys.stdout = old


def write_index(out: Path, printed: str) -> Path:
    """Write ``out/index.html``: the printed measurements, then every figure present in
    ``out`` (relative links, so the folder can be moved or served as is)."""
    parts = [
        "<!doctype html>",
        '<html lang="en"><head><meta charset="utf-8"><title>rgbd_rs demo</title>',
        "<style>body{font-family:sans-serif;max-width:1960px;margin:2em auto;padding:0 1em}"
        "img{max-width:100%;height:auto;border:1px solid #ddd}"
        "pre{background:#f6f6f6;padding:1em;overflow-x:auto}figure{margin:2em 0}</style>",
        "</head><body>",
        "<h1>rgbd_rs demo</h1>",
        "<p>Written by <code>rgbd demo</code> (<code>make demo</code>); every number below was "
        "measured in that run.</p>",
        "<h2>Measurements</h2>",
        f"<pre>{html.escape(printed.strip())}</pre>",
        "<h2>Figures</h2>",
    ]
    for name, caption in FIGURES:
        if (out / name).is_file():
            parts.append(
                f'<figure><a href="{name}"><img src="{name}" alt="{html.escape(name)}"></a>'
                f"<figcaption><code>{name}</code>: {html.escape(caption)}</figcaption></figure>"
            )
    parts.append("</body></html>")
    return write_text(out / "index.html", "\n".join(parts) + "\n")
