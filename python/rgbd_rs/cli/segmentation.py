"""``rgbd segment``: segment an RGB-D frame (thesis ch. 4)."""

from __future__ import annotations

import argparse
import re
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from rgbd_rs import _rgbd_rs
from rgbd_rs.cli._args import (
    Commands,
    fail,
    flagged,
    folder,
    input_paths,
    integer,
    named,
    output_folder,
    real,
    refuse_overwriting,
)
from rgbd_rs.cli.fusion import DEPTH_SCALE_HELP, DEPTH_SCALE_RANGE
from rgbd_rs.holes import DEFAULT_FILL_RADIUS

DESCRIPTION = (
    "Segment an RGB-D frame: 9-D colour/position/normal features (eq. 4.1), normalized-cuts "
    "over-segmentation with the Nystrom approximation (§4.4), spline fits of every segment and "
    "the semantic ConvNet's class PDFs (§4.6) and region merging (Algorithm 1, §4.7); every final "
    "segment gets one class (--pooling: the argmax of its mean PDF, or its majority). The "
    "ConvNet is the one shipped in the package (--labeler "
    "auto, NYUv2's 13 classes), a checkpoint of `rgbd train semantic` (--labeler FILE), or none "
    "(--labeler none: the fit-only baseline, couples merged in order of fit improvement while "
    "eq. 4.8 holds); --pdfs (per-pixel class probabilities, H x W x C .npy) replaces the ConvNet. "
    "Writes OUT/labels.png (16-bit, the final segments numbered 1..N, 0 = no depth), "
    "OUT/labels.npy (the merge's segment ids, -1 = no depth), OUT/over.npy, "
    "OUT/overlay.png (boundaries on the colour image), OUT/segments.png (labels.png in colour); "
    "with classes OUT/semantic.npy, OUT/semantic.png (refined classes), OUT/network.png (the "
    "ConvNet's per-pixel classes), both with a class legend, and OUT/classes.json (id, name, "
    "colour of each class, and id -1 for the pictures' no-data grey); with --frames N every "
    "N-th merge step as OUT/merge/NNNN.png (Fig. 4.5)."
)


#: Everything ``rgbd segment`` may write (cleared first, so no file of an earlier run stays).
SEGMENT_OUTPUTS = (
    "labels.png",
    "labels.npy",
    "over.npy",
    "overlay.png",
    "segments.png",
    "semantic.npy",
    "semantic.png",
    "network.png",
    "classes.json",
    "merge/[0-9][0-9][0-9][0-9].png",
)

#: The most clusters ``--segments`` asks for: a tenth of the pixels the over-segmentation fits
#: its centres on (it needs at least one per cluster). An NYUv2 frame (640x480, fit-only
#: merging) takes 0.7 s at the default 230, 6.7 s at 5000 on the 2-core build machine; 50000
#: had not finished after 100 s.
MAX_SEGMENTS = _rgbd_rs.OVERSEG_DEFAULT_FIT_POINTS // 10

#: segment()'s parameters -> the flags that gave them (errors name the flag).
SEGMENT_FLAGS = {
    "rgb": "--rgb",
    "depth": "--depth",
    "camera": "--calib",
    "pdfs": "--pdfs",
    "n_segments": "--segments",
    "fill_radius": "--fill-radius",
    "cues": "--rgb/--depth",  # the labeling network's input, made from both
}


#: How ``rgbd segment`` names the merge's mode.
_MODE_WORDS = {
    "similarity": "ordered by the ConvNet's class similarity, checked by the spline fits",
    "fit": "fit-only: by the spline fits alone, no class similarity",
}


def register(commands: Commands) -> None:
    """Add ``rgbd segment``."""
    p = commands.command(
        "segment",
        run_segment,
        help="segment an RGB-D frame (thesis ch. 4)",
        description=DESCRIPTION,
    )
    p.add_argument("--rgb", type=Path, required=True, help="colour image (PNG)")
    p.add_argument(
        "--depth",
        type=Path,
        required=True,
        help="depth registered to the colour image (.npy/.npz metres, 16-bit .png millimetres "
        "or --depth-scale)",
    )
    p.add_argument(
        "--depth-scale",
        type=real(*DEPTH_SCALE_RANGE, low_open=False),
        metavar="M",
        help=DEPTH_SCALE_HELP,
    )
    p.add_argument(
        "--calib",
        type=Path,
        required=True,
        help="camera JSON {fx, fy, cx, cy, width, height} (examples/nyu_camera.json), or a "
        "`rgbd fuse` rig file (its reference camera)",
    )
    p.add_argument("--out", type=folder, required=True, help="output folder")
    p.add_argument("--pdfs", type=Path, help="per-pixel class probabilities (.npy, H x W x C)")
    p.add_argument(
        "--labeler",
        default=None,
        metavar="auto|none|FILE",
        help="semantic ConvNet: the shipped weights (auto, the default), none (fit-only "
        "merging) or a checkpoint file; not with --pdfs",
    )
    p.add_argument(
        "--segments",
        type=integer(2, MAX_SEGMENTS),
        default=None,
        help="normalized-cuts clusters of the over-segmentation (default "
        f"{_rgbd_rs.OVERSEG_DEFAULT_SEGMENTS}, at most {MAX_SEGMENTS}; "
        "fewer, e.g. 30, give fewer and larger final segments)",
    )
    p.add_argument(
        "--touching",
        action="store_true",
        help="every touching couple is adjacent (skip the boundary tests of eq. 4.3-4.5)",
    )
    p.add_argument(
        "--pooling",
        choices=("mean", "majority"),
        default="mean",
        help="class of each final segment: argmax of its mean PDF (mean, default) or its most "
        "common per-pixel class (majority)",
    )
    p.add_argument(
        "--fill-radius",
        type=real(0, 1000, low_open=False),
        default=DEFAULT_FILL_RADIUS,
        help="depth holes within this many pixels of a measured pixel take its depth first "
        f"(default {DEFAULT_FILL_RADIUS}: scattered holes, sparse ToF depth; 0 keeps every hole)",
    )
    p.add_argument("--frames", type=integer(1), help="write every N-th merge step as a PNG")
    p.add_argument(
        "--seed",
        type=integer(0, 2**32 - 1),
        default=0,
        help="seed of the over-segmentation's pixel sample and k-means (0; the same seed gives "
        "the same segments)",
    )
    p.add_argument("--quiet", action="store_true", help="no progress output")


def class_names(pdfs: np.ndarray | None) -> list[str]:
    """The class names of the labeler's PDFs: NYUv2's 13 (+ unlabeled) for the shipped
    network's 14 channels, else ``class 0`` ... ``class C-1``."""
    from rgbd_rs.data.nyuv2 import LABEL13_NAMES

    count = len(LABEL13_NAMES) if pdfs is None else int(pdfs.shape[-1])
    if count == len(LABEL13_NAMES):
        return list(LABEL13_NAMES)
    return [f"class {i}" for i in range(count)]


def _preview_width(rgb: np.ndarray) -> int:
    """The pictures' width: the frame's, within what a panel can take (a frame narrower than a
    panel's title is drawn wider; its label maps keep its size)."""
    from rgbd_rs.viz import MAX_TILE_WIDTH, MIN_PANEL_WIDTH

    return min(max(int(rgb.shape[1]), MIN_PANEL_WIDTH), MAX_TILE_WIDTH)


def run_segment(args: argparse.Namespace) -> int:
    from rgbd_rs.cli.fusion import depth_png_scale, load_map
    from rgbd_rs.data.calibration import load_camera
    from rgbd_rs.errors import InvalidArgumentError, ShapeMismatchError
    from rgbd_rs.io import read_npy, read_png, write_png
    from rgbd_rs.segmentation.oversegment import DEFAULT_N_SEGMENTS
    from rgbd_rs.segmentation.pipeline import segment
    from rgbd_rs.viz import (
        NO_DATA_RGB,
        class_legend,
        image_panel,
        outline_segments,
        paint_segments,
        save_png,
    )

    refuse_overwriting(args.out, SEGMENT_OUTPUTS, "--out", input_paths(args))  # before the work
    if args.labeler == "":
        return fail("--labeler: got an empty value, expected auto, none or a checkpoint file")
    rgb = named("--rgb", lambda: read_png(args.rgb))
    grey = rgb.ndim == 2 or rgb.shape[2] < 3 or _png_colour_type(args.rgb) in (0, 4)
    if grey:  # OpenCV reads a grey + alpha PNG as colour: its header says what it is
        raise ShapeMismatchError(
            f"--rgb: {args.rgb}: got a grey image, expected a colour (RGB) image: the features "
            "and the ConvNet read colour"
        )
    if rgb.dtype != np.uint8:
        raise InvalidArgumentError(
            f"--rgb: {args.rgb}: got a {8 * rgb.itemsize}-bit image, expected an 8-bit colour image"
        )
    scale = depth_png_scale("--depth", args.depth, args.depth_scale)
    depth = load_map("--depth", args.depth, png_scale=scale, depth=True)
    camera = named("--calib", lambda: load_camera(args.calib))
    size = (camera.height, camera.width)
    for flag, path, arr in (("--rgb", args.rgb, rgb), ("--depth", args.depth, depth)):
        if arr.shape[:2] != size:
            hint = ""
            if flag == "--depth" and rgb.shape[:2] == size:
                hint = (
                    " (depth on its own sensor's lattice? register it to the colour camera "
                    "first: rgbd reproject)"
                )
            raise ShapeMismatchError(
                f"{flag}: {path}: got {arr.shape[1]}x{arr.shape[0]} pixels, expected the --calib "
                f"camera's {camera.width}x{camera.height}{hint}"
            )
    pdfs = None if args.pdfs is None else named("--pdfs", lambda: read_npy(args.pdfs))
    n = DEFAULT_N_SEGMENTS if args.segments is None else args.segments
    if pdfs is not None and args.labeler is not None:
        return fail(f"--labeler: got {args.labeler} with --pdfs, which replaces the ConvNet")
    labeler: Any = None if args.labeler == "none" else (args.labeler or "auto")
    if labeler not in (None, "auto"):
        if not Path(labeler).is_file():
            return fail(f"--labeler: {labeler}: no such checkpoint file (or auto, none)")
        from rgbd_rs.segmentation import SemanticLabeler

        path = labeler  # loaded now: a bad checkpoint fails before the minutes of work
        labeler = named("--labeler", lambda: SemanticLabeler.load(path))
    result = flagged(
        SEGMENT_FLAGS,
        lambda: segment(
            rgb,
            depth,
            camera,
            pdfs=pdfs,
            labeler=labeler,
            n_segments=n,
            touching=args.touching,
            pooling=args.pooling,
            fill_radius=args.fill_radius,
            seed=args.seed,
            quiet=args.quiet,
        ),
        amend=_naming_the_depth_scale(args.depth, depth, scale),
    )
    out = output_folder(args.out, SEGMENT_OUTPUTS)  # inputs checked before the work
    np.save(out / "labels.npy", result.labels)
    np.save(out / "over.npy", result.over)
    ids = np.unique(result.labels[result.labels >= 0], return_inverse=True)[1]
    png = np.zeros(result.labels.shape, np.uint16)
    png[result.labels >= 0] = (ids + 1).astype(np.uint16)
    write_png(out / "labels.png", png, rgb=False)
    save_png(out / "overlay.png", outline_segments(rgb, result.labels))
    n_found = int(ids.max()) + 1 if ids.size else 0
    seg_panel = image_panel(
        paint_segments(result.labels),
        f"{n_found} segments (labels.png in colour; white: boundaries)",
        width=_preview_width(rgb),
    )
    legend = class_legend(
        ["no depth: not segmented (labels.png 0)"], [NO_DATA_RGB], seg_panel.shape[1]
    )
    save_png(out / "segments.png", np.vstack([seg_panel, legend]))
    written = "labels.png, labels.npy, over.npy, overlay.png, segments.png"
    if result.semantic is not None:
        from rgbd_rs.data.nyuv2 import LABEL13_NAMES
        from rgbd_rs.data.synth_indoor import LABEL13_COLORS
        from rgbd_rs.io import write_json
        from rgbd_rs.viz import class_picture

        names = class_names(result.pdfs)
        if tuple(names) == LABEL13_NAMES:
            colors = list(LABEL13_COLORS)
        else:  # another labeler's classes: the segment pictures' colour of each id (BGR -> RGB)
            swatches = paint_segments(np.arange(len(names))[None, :], boundaries=False)[0]
            colors = [(int(b[2]), int(b[1]), int(b[0])) for b in swatches]
        np.save(out / "semantic.npy", result.semantic)
        write_json(
            out / "classes.json",
            [
                {"id": i, "name": n, "rgb": list(c)}
                for i, (n, c) in enumerate(zip(names, colors, strict=True))
            ]
            + [{"id": -1, "name": "no data", "rgb": list(NO_DATA_RGB)}],
        )
        width = _preview_width(rgb)
        save_png(
            out / "semantic.png",
            class_picture(result.semantic, names, colors, "classes after the segment refinement",
                          width=width),
        )  # fmt: skip
        written += ", semantic.npy, semantic.png, classes.json"
        if result.network_labels is not None:
            net = np.where(result.labels >= 0, result.network_labels, -1)
            save_png(
                out / "network.png",
                class_picture(net, names, colors, "the ConvNet's per-pixel classes", width=width),
            )
            written += ", network.png"
    if args.frames:
        steps = len(result.merge.history)
        for k in range(0, steps + 1, args.frames):
            save_png(out / "merge" / f"{k:04d}.png", paint_segments(result.merge.labels_after(k)))
        written += f", merge/ ({steps // args.frames + 1} frames)"
    if not args.quiet:
        stages = ", ".join(f"{k} {v * 1e3:.0f} ms" for k, v in result.seconds.items())
        n_over = int(np.unique(result.over[result.over >= 0]).size)
        print(
            f"{n_over} segments -> {result.merge.n_segments} after {len(result.merge.history)} "
            f"merges ({_MODE_WORDS.get(result.merge.mode, result.merge.mode)}); {stages}"
        )
        print(f"wrote in {out}/: {written}")
    return 0


def _png_colour_type(path: Path) -> int | None:
    """The colour type a PNG's header declares (0 grey, 2 RGB, 3 palette, 4 grey + alpha,
    6 RGBA), None for another file."""
    with open(path, "rb") as fh:
        head = fh.read(26)
    return head[25] if len(head) == 26 and head[12:16] == b"IHDR" else None


def _naming_the_depth_scale(path: Path, depth: np.ndarray, scale: float) -> Callable[[str], str]:
    """A message rewriter: the depth-unit warning or error ends with the --depth-scale value
    that makes the PNG's median depth plausible (a .npy/.npz holds metres: no flag fixes it)."""
    from rgbd_rs.segmentation.pipeline import _suggested_depth_scale

    def amend(text: str) -> str:
        about_median = text.startswith("depth:") and "median" in text
        if not (about_median and path.suffix.lower() == ".png"):
            return text
        valid = depth[np.isfinite(depth) & (depth > 0)]
        med = float(np.median(valid)) if valid.size else 0.0
        fix = _suggested_depth_scale(med, scale)
        if fix is None:
            return text
        # The library's "divide by N" is for an array; for a PNG the flag is the fix.
        text = re.sub(
            r": depth looks like \w+; divide by [0-9.e+]+",
            f" m (read with --depth-scale {scale:g})",
            text,
        )
        return text + f"; --depth-scale {fix:g} brings it to {med / scale * fix:.3g} m"

    return amend
