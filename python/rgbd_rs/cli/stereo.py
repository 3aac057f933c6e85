"""``rgbd stereo`` (our census SGM, or OpenCV's, on one rectified pair) and ``rgbd eval stereo``
(both on the real Middlebury scenes of the shared data)."""

from __future__ import annotations

import argparse
import math
import sys
from pathlib import Path
from typing import Any

from rgbd_rs.cli._args import (
    Commands,
    flagged,
    folder,
    input_paths,
    integer,
    named,
    output_folder,
    real,
)
from rgbd_rs.cli._maps import disparity_png16, disparity_png_note
from rgbd_rs.errors import InvalidArgumentError

#: ``--min-depth`` when ``--calib`` gives the range: the nearest depth searched (metres).
DEFAULT_MIN_DEPTH = 0.5
#: What ``rgbd stereo`` writes (cleared from --out first).
STEREO_OUTPUTS = ("disparity.npz", "disparity.png", "preview.png")
#: OpenCV block sizes ``rgbd eval stereo`` compares against.
OPENCV_BLOCKS = (3, 5, 7, 9)


def register(commands: Commands) -> None:
    st = commands.command(
        "stereo",
        run_stereo,
        help="disparity of a rectified stereo pair (census SGM, or OpenCV's)",
        description="Semi-global matching on a rectified pair: our census matcher (default) or "
        "OpenCV's SGBM. Writes OUT/disparity.npz (float32 px, NaN = none), disparity.png "
        "(16-bit, px x 256, 0 = none) and preview.png (colour, with a scale bar).",
    )
    st.add_argument("--left", type=Path, required=True, help="left image (PNG)")
    st.add_argument("--right", type=Path, required=True, help="right image (PNG)")
    rng = st.add_mutually_exclusive_group(required=True)
    rng.add_argument(
        "--max-disparity",
        type=integer(1),
        help="search range in px (inclusive; OpenCV searches whole 16-px steps from 0, so its top "
        "is the next multiple of 16 minus 1)",
    )
    rng.add_argument(
        "--calib",
        type=Path,
        help="calibration JSON of these images (its 'stereo' section is enough: left, right, "
        "baseline): the search range covers depths down to --min-depth",
    )
    st.add_argument(
        "--min-depth",
        type=real(0.0, 1e6),
        default=None,
        help=f"with --calib: nearest depth searched, metres (default {DEFAULT_MIN_DEPTH})",
    )
    st.add_argument("--reference", choices=("left", "right"), default="left", help="default left")
    st.add_argument(
        "--method", choices=("census", "opencv"), default="census", help="default census (ours)"
    )
    st.add_argument(
        "--vertical-tolerance",
        type=int,
        choices=(0, 1, 2),
        default=None,
        help="census: target rows searched above and below each row (default 1, for a rig "
        "rectified to within about a pixel; 0 for a pair rectified to a fraction of one)",
    )
    st.add_argument(
        "--lr-tolerance",
        type=integer(0, 255),
        default=None,
        help="census: left-right check tolerance in px, NaN where the two views' matches "
        "disagree by more (default: no check, every pixel gets a value, as rgbd eval stereo "
        "scores the matcher; rgbd fuse runs it with 1)",
    )
    st.add_argument(
        "--no-align-rows",
        action="store_true",
        help="census: match the pair as given (by default the rows' misalignment is measured "
        "after a first match and, where it reaches 0.5 px, the other image's rows are "
        "resampled and the pair matched again, with a warning)",
    )
    st.add_argument("--out", type=folder, required=True, help="output folder")

    ev = commands.group_command(
        "eval",
        "stereo",
        run_eval_stereo,
        help="census SGM vs OpenCV SGBM on the real Middlebury scenes",
        description="Scores our census matcher and OpenCV's SGBM (HH and 3WAY, block sizes "
        f"{', '.join(map(str, OPENCV_BLOCKS))}) on the Middlebury scenes of the shared data "
        "(stereo/scenes.csv): bad-1, bad-2 (a missing output counts as bad), RMS, coverage and "
        "bad-1 in the 2 px band around depth edges, on the non-occluded pixels of the left "
        "view. Writes OUT/<split>.md.",
    )
    ev.add_argument(
        "--split", choices=("train", "val", "test", "all"), default="test", help="default test"
    )
    ev.add_argument(
        "--out", type=folder, default=Path("out/eval_stereo"), help="(default out/eval_stereo)"
    )
    ev.add_argument("--quiet", action="store_true", help="no progress")


def _search_range(args: argparse.Namespace, width: int, height: int) -> int:
    if args.max_disparity is not None:
        if args.min_depth is not None:
            raise InvalidArgumentError(
                "--min-depth: got it with --max-disparity, expected --calib (the range comes "
                "from the calibration and the nearest depth, or is given)"
            )
        dmax = int(args.max_disparity)
    else:
        from rgbd_rs.data.calibration import load_stereo_rig

        rig = named("--calib", lambda: load_stereo_rig(args.calib))
        size = (rig.left.width, rig.left.height)
        if size != (width, height):
            raise InvalidArgumentError(
                f"--calib: {args.calib} is for {size[0]} x {size[1]} images, the pair is "
                f"{width} x {height}; expected the calibration of these images"
            )
        min_depth = DEFAULT_MIN_DEPTH if args.min_depth is None else args.min_depth
        reach = rig.baseline * rig.focal / min_depth
        if not math.isfinite(reach) or reach >= width:
            how = f"--calib's baseline {rig.baseline:g} x focal {rig.focal:.1f} px / " + (
                f"--min-depth {min_depth:g}"
                if args.min_depth is not None
                else f"the default --min-depth {min_depth:g} m (is the baseline in metres? "
                "else give --min-depth in its unit, or --max-disparity)"
            )
            raise InvalidArgumentError(
                f"--min-depth: a search range of {reach:.4g} px ({how}), expected less than "
                f"the image width {width}"
            )
        dmax = math.ceil(reach)
    if dmax >= width:
        given = args.max_disparity is not None
        flag = "--max-disparity" if given else "--min-depth"
        shown = f"{dmax}" if given else f"{dmax:.4g}"  # as typed, or 4 digits of a computed one
        raise InvalidArgumentError(
            f"{flag}: a search range of {shown} px, expected less than the image width {width}"
        )
    return dmax


def run_stereo(args: argparse.Namespace) -> int:
    import numpy as np

    from rgbd_rs.fusion.census import CensusParams
    from rgbd_rs.fusion.stereo import BLOCK_SIZE, DISPARITY_STEP, _max_search, _sgm
    from rgbd_rs.io import read_png, write_npz, write_png
    from rgbd_rs.viz import colorize_with_bar, save_png

    left = named("--left", lambda: read_png(args.left))
    right = named("--right", lambda: read_png(args.right))
    dmax = _search_range(args, left.shape[1], left.shape[0])
    params = None
    census_flags = {
        "--vertical-tolerance": args.vertical_tolerance is not None,
        "--lr-tolerance": args.lr_tolerance is not None,
        "--no-align-rows": args.no_align_rows,
    }
    for flag, given in census_flags.items():
        if given and args.method == "opencv":
            raise InvalidArgumentError(
                f"{flag}: got it with --method opencv, expected --method census (OpenCV's "
                "SGBM has its own left-right check and searches the rectified row only)"
            )
    if any(census_flags.values()):
        given = {"vertical_tolerance": args.vertical_tolerance, "lr_tolerance": args.lr_tolerance}
        changes = {k: v for k, v in given.items() if v is not None}
        params = CensusParams().replace(**changes, align_rows=not args.no_align_rows)
    if args.method == "opencv":
        if _max_search(left.shape[1]) < 1:
            raise InvalidArgumentError(
                f"--left: images {left.shape[1]} px wide, expected at least "
                f"{DISPARITY_STEP + BLOCK_SIZE // 2 + 1} px for OpenCV's SGBM (its 7x7 block and "
                f"{DISPARITY_STEP}-px search steps); --method census takes narrower images"
            )
        dmax = min(dmax, _max_search(left.shape[1]))
    out = output_folder(args.out, STEREO_OUTPUTS, inputs=input_paths(args))
    disp = flagged(
        {
            "left": "--left",
            "right": "--right",
            "max_disparity": "--max-disparity",
            "lr_tolerance": "--lr-tolerance",
        },
        lambda: _sgm(
            left,
            right,
            reference=args.reference,
            max_disparity=dmax,
            method=args.method,
            params=params,
        ),
    )
    write_npz(out / "disparity.npz", {"disparity": disp})
    write_png(out / "disparity.png", disparity_png16(disp), rgb=False)
    clipped = disparity_png_note(disp, "disparity.npz")
    if clipped is not None:
        print(clipped, file=sys.stderr)
    name = "census SGM (rgbd_rs)" if args.method == "census" else "OpenCV SGBM-HH 7x7"
    title = f"{name}: disparity on the {args.reference} view"
    found = disp[np.isfinite(disp)]  # the colours span the map's values, not the search range
    lo, hi = (
        (float(np.percentile(found, 1)), float(np.percentile(found, 99)))
        if found.size
        else (0.0, float(dmax))
    )
    save_png(out / "preview.png", colorize_with_bar(disp, lo, max(hi, lo + 1.0), "px", title=title))
    _warn_if_swapped(left, right, args.reference, dmax, args.method, disp)
    _warn_if_cut(args, disp, dmax)
    _warn_if_blank(args.method, left, right)
    cover = float(np.isfinite(disp).mean())
    checked = args.method == "opencv" or args.lr_tolerance is not None
    note = (
        ""
        if checked
        else " (no left-right check: --lr-tolerance 1 leaves NaN where the views disagree)"
    )
    from rgbd_rs.fusion.stereo import _searched_top

    top = _searched_top(args.method, 0, dmax)  # OpenCV: whole 16-px steps, so 0..63 for 64
    print(f"{args.method} SGM on the {args.reference} view, 0..{top} px: {cover:.1%} matched{note}")
    print(f"wrote {out}/disparity.npz, disparity.png, preview.png")
    return 0


def _warn_if_cut(args: argparse.Namespace, disp: Any, dmax: int) -> None:
    """Warn when the matches pile up at the top of the search range (it ends before the nearest
    surface; :mod:`rgbd_rs.fusion._range_cut`), naming the flag that set it."""
    import warnings

    from rgbd_rs.fusion._range_cut import range_cut_note

    if args.max_disparity is not None:
        flag, advice = "--max-disparity", "give a larger --max-disparity"
    else:
        depth = DEFAULT_MIN_DEPTH if args.min_depth is None else args.min_depth
        default = " (the default)" if args.min_depth is None else ""
        flag = f"--min-depth {depth:g} m{default}"
        advice = "give a smaller --min-depth (the nearest depth in the scene)"
    from rgbd_rs.fusion.stereo import _searched_top

    note = range_cut_note(disp, _searched_top(args.method, 0, dmax), flag, advice)
    if note is not None:
        warnings.warn(note, RuntimeWarning, 2)


def _warn_if_blank(method: str, left: Any, right: Any) -> None:
    """Warn when most of a view has no texture to match (:mod:`rgbd_rs.fusion._blank`), naming
    its flag."""
    import warnings

    from rgbd_rs.fusion._blank import blank_note
    from rgbd_rs.fusion.stereo import _as_matched

    note = blank_note(*_as_matched(method, left, right))
    if note is not None:
        warnings.warn(f"--{note}", RuntimeWarning, 2)


def _warn_if_swapped(
    left: Any, right: Any, reference: str, dmax: int, method: str, disparity: Any
) -> None:
    """Warn when the pair looks swapped, as ``rgbd fuse`` does without a ToF: the matcher with
    ``fuse``'s left-right check matches far more pixels with the images exchanged (the census
    matcher alone, with no check, matches every pixel of a swapped pair too). OpenCV's map
    (``disparity``) is the one ``fuse`` would compute; the census one is matched again with
    the check."""
    import functools
    import warnings

    import numpy as np

    from rgbd_rs.fusion._fuse_checks import _swap_warning
    from rgbd_rs.fusion.fuse import _match

    match = functools.partial(_match, matcher=method, width=left.shape[1])
    checked = (  # matched as given: the row check is the main match's business
        disparity
        if method == "opencv"
        else match(left, right, reference=reference, max_disparity=dmax, align_rows=False)
    )
    none = np.full(checked.shape, np.nan, np.float32)
    message = _swap_warning(left, right, reference, checked, none, dmax, match)
    if message is not None:  # in the flags' words, as rgbd fuse says it
        warnings.warn(message.replace("left/right:", "--left/--right:", 1), RuntimeWarning, 2)


def run_eval_stereo(args: argparse.Namespace) -> int:
    from rgbd_rs.data.stereo_scenes import load_stereo_scenes
    from rgbd_rs.fusion.evaluate_stereo import census_matcher, evaluate, opencv_matcher
    from rgbd_rs.io import write_text

    split = None if args.split == "all" else args.split
    scenes = load_stereo_scenes(split)
    methods = {"census (ours)": census_matcher()}
    for b in OPENCV_BLOCKS:
        methods[f"OpenCV HH {b}x{b}"] = opencv_matcher(b, "hh")
    for b in OPENCV_BLOCKS:
        methods[f"OpenCV 3WAY {b}x{b}"] = opencv_matcher(b, "3way")

    def progress(msg: str) -> None:
        if not args.quiet and sys.stderr.isatty():
            print(f"\r{msg:<60}", end="", file=sys.stderr, flush=True)

    table = evaluate(scenes, methods, progress)
    if not args.quiet and sys.stderr.isatty():
        print(file=sys.stderr)
    text = table.markdown(f"{args.split} split ({len(scenes)} scenes)")
    out = output_folder(args.out, (f"{args.split}.md",))
    write_text(out / f"{args.split}.md", text)
    print(text)
    print(f"wrote {out}/{args.split}.md")
    return 0
