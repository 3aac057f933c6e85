"""``rgbd fuse`` and ``rgbd eval fusion``: the fusion pipeline's commands."""

from __future__ import annotations

import argparse
import sys
import textwrap
import time
from itertools import islice
from pathlib import Path

import numpy as np
import numpy.typing as npt

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
from rgbd_rs.cli._maps import depth_mm_png16, disparity_png16, disparity_png_note
from rgbd_rs.errors import InvalidArgumentError, ShapeMismatchError

#: Width of each panel of `rgbd fuse`'s preview.png (pixels).
PREVIEW_WIDTH = 400
#: Names and colours (RGB) of the values of ``FusionResult.source`` (0-5) in the preview.
SOURCE_NAMES = (
    "none",
    "LC",
    "ToF (LC empty)",
    "stereo (LC empty)",
    "ToF carried to the border",
    "LC, neither measured",
)
SOURCE_COLOURS = ((0, 0, 0), (44, 160, 44), (31, 119, 180), (255, 127, 14), (148, 103, 189),
                  (214, 39, 40))  # fmt: skip
#: The largest depth depth_mm.png holds (65535 mm).
DEPTH_PNG_MAX_M = 65.535

#: fuse()'s parameters -> the flags that gave them (errors name the flag).
FUSE_FLAGS = {
    "left/right": "--left/--right",
    "tof_depth/rig": "--tof-depth/--calib",
    "left": "--left",
    "right": "--right",
    "tof_depth": "--tof-depth",
    "tof_amplitude": "--tof-amplitude",
    "rig": "--calib",
    "confidence[0]": "--tof-confidence",
    "confidence[1]": "--stereo-confidence",
    "confidence": "--tof-confidence/--stereo-confidence",
    "max_disparity": "--max-disparity",
    "reference": "--reference",
}
#: Largest LC window half-size (crates/rgbd-fusion).
MAX_RADIUS: int = _rgbd_rs.MAX_RADIUS

FUSE_DESCRIPTION = (
    "Reproject + upsample the ToF depth onto the reference camera, run SGM on the pair, weight "
    "both with confidences and fuse them with the locally consistent (LC) method. Writes "
    "OUT/fused.npz (float32 maps), OUT/disparity.png (16-bit, disparity x 256), OUT/depth_mm.png "
    "(16-bit millimetres) and OUT/preview.png, and prints the SGM search range and the share of "
    "valid pixels of each input and of the result. Maps: .npy/.npz in metres, or 16-bit PNG in "
    "millimetres (depth; --depth-scale for other units). The amplitude may be in any unit."
)

#: The calibration JSON layout (rgbd_rs.data.calibration), shown by `rgbd fuse --help`.
CALIBRATION_HELP = """\
calibration JSON (--calib); examples/calibration.json is the synthetic rig:
  {"stereo": {"left": CAM, "right": CAM, "baseline": 0.12},
   "tof": CAM,
   "tof_to_reference": {"rotation": [[1, 0, 0], [0, 1, 0], [0, 0, 1]],
                        "translation": [0.0, 0.04, 0.0]},
   "reference": "right"}
  CAM = {"fx": 727.27, "fy": 727.27, "cx": 479.5, "cy": 269.5,
         "width": 960, "height": 540,
         "distortion": [k1, k2, p1, p2, k3, k4, k5, k6]}
units: pixels and metres; camera frames x right, y down, z forward (OpenCV)
  stereo      the rectified pair (equal size and fx); the right camera sits
              baseline metres along +x of the left one, so
              disparity = u_left - u_right = baseline * fx / z
  tof         the ToF camera; --tof-depth/--tof-amplitude are height x width
  tof_to_reference
              takes ToF-frame points into the frame of the camera named by
              "reference": p_ref = rotation @ p_tof + translation
  reference   "right" (the default when absent) or "left"; --reference picks
              the output camera (the pose is carried across the baseline)
  distortion  OpenCV order, 4, 5 or 8 values; optional (none)
"""


#: What ``rgbd fuse`` writes in ``--out``.
FUSE_OUTPUTS = ("fused.npz", "disparity.png", "depth_mm.png", "preview.png")


def register(commands: Commands) -> None:
    fz = commands.command(
        "fuse",
        run_fuse,
        help="fuse a ToF frame with a stereo pair (thesis ch. 3)",
        description=textwrap.fill(FUSE_DESCRIPTION, 80),
    )
    # The layout's indentation matters: the description is pre-wrapped above.
    fz.formatter_class = argparse.RawDescriptionHelpFormatter
    fz.epilog = CALIBRATION_HELP
    fz.add_argument("--left", type=Path, required=True, help="left colour image (PNG)")
    fz.add_argument("--right", type=Path, required=True, help="right colour image (PNG)")
    fz.add_argument(
        "--tof-depth", type=Path, required=True, help="ToF depth (.npy/.npz m, .png mm)"
    )
    fz.add_argument(
        "--tof-amplitude", type=Path, required=True, help="ToF amplitude (.npy/.npz/.png)"
    )
    fz.add_argument(
        "--depth-scale",
        type=real(*DEPTH_SCALE_RANGE, low_open=False),
        metavar="M",
        help=DEPTH_SCALE_HELP,
    )
    fz.add_argument("--calib", type=Path, required=True, help="rig calibration JSON")
    fz.add_argument("--out", type=folder, required=True, help="output folder")
    fz.add_argument(
        "--reference",
        choices=("left", "right"),
        help='camera the output lies on (default: the calibration\'s "reference", right when '
        "absent, as in the thesis)",
    )
    fz.add_argument(
        "--confidence",
        choices=("convnet", "uniform", "heuristic"),
        default=None,
        help="confidence weights (default convnet: the shipped confidence ConvNet); see also "
        "--weights and --tof-confidence",
    )
    fz.add_argument(
        "--weights",
        type=Path,
        help="a checkpoint of `rgbd train confidence` to use instead of the shipped weights",
    )
    fz.add_argument(
        "--precision",
        choices=("auto", "float32", "bfloat16"),
        default=None,
        help="the ConvNet's arithmetic (default auto: bfloat16 where the CPU has native "
        "bfloat16, about 2x faster; float32 for the same result on every machine)",
    )
    fz.add_argument(
        "--tof-confidence",
        type=Path,
        help="ToF confidence map (.npy, [0, 1]) on the output camera's grid (its width x "
        "height); give --stereo-confidence with it",
    )
    fz.add_argument(
        "--stereo-confidence",
        type=Path,
        help="stereo confidence map (.npy, [0, 1]) on the output camera's grid; give "
        "--tof-confidence with it",
    )
    fz.add_argument(
        "--max-disparity",
        type=integer(1),
        help="SGM search range in px (default: from the ToF's disparities, robust to flying "
        "pixels, at most a third of the width)",
    )
    fz.add_argument(
        "--radius",
        type=integer(1, MAX_RADIUS),
        help=f"LC window half-size, 1..{MAX_RADIUS} (default: grows with the image width: 10 at "
        "960 px, 19 at 1920 px, the thesis' 39x39 window)",
    )
    fz.add_argument(
        "--stride",
        type=integer(1),
        default=2,
        help="LC window sampling step, at most --radius (default 2; with the default radius, "
        "capped at it)",
    )
    fz.add_argument(
        "--cross-check", action="store_true", help="keep only pixels both views agree on (eq. 2.18)"
    )
    fz.add_argument(
        "--keep-pose",
        action="store_true",
        help="fuse the ToF pose and depths as given: by default a ToF orientation that fits "
        "the stereo map clearly better turned by 0.1 to about 6 degrees is refined, and depths "
        "1-6 %% off the pair's scale are rescaled (each with a warning; the pose and factor "
        "used go to fused.npz as tof_pose and tof_scale)",
    )

    ef = commands.group_command(
        "eval",
        "fusion",
        run_eval,
        help="RMS disparity error of ToF, SGM and LC fusion (Table 3.2) + Fig. 3.4",
        description="Reproduces the thesis Table 3.2 protocol on the synthetic test set and on "
        "the Middlebury pairs (ToF simulated). Writes OUT/<dataset>/table.md and figure.png for "
        "each dataset.",
    )
    ef.add_argument("--synth", type=Path, help="synthetic dataset folder (from `rgbd synth`)")
    ef.add_argument("--split", choices=("test", "train"), default="test", help="default test")
    ef.add_argument(
        "--middlebury", action="store_true", help="also the Middlebury pairs of the shared data"
    )
    ef.add_argument(
        "--real",
        choices=("train", "val", "test"),
        help="the real Middlebury split of ../shared/data/stereo with simulated ToF laws: the "
        "default fusion scored per case (fused / better input, fused / good input, coverage)",
    )
    ef.add_argument(
        "--laws", type=integer(1, 64), default=2, help="fixed ToF laws per real scene (2)"
    )
    ef.add_argument(
        "--dense",
        action="store_true",
        help="with --real: the dense protocol instead of the --laws laws (a 512x424 ToF of the "
        "default sensor, finer than the colour images and far more precise than the stereo map; "
        "written to OUT/real_SPLIT_dense/)",
    )
    ef.add_argument(
        "--view",
        choices=("left", "right"),
        default="left",
        help="with --real: the camera fused on and scored (default left, beside the simulated "
        "ToF; right: the far camera, the scenes with right-view ground truth; written to "
        "OUT/real_SPLIT_right/)",
    )
    ef.add_argument("--limit", type=integer(1), help="first N synthetic scenes / real cases only")
    ef.add_argument(
        "--scenes",
        metavar="NAME[,NAME]",
        help="with --real: only these scenes of the split (e.g. Cones,Teddy), in its order",
    )
    ef.add_argument(
        "--stride",
        type=integer(1),
        default=2,
        help="LC window sampling step, at most the radius (default 2)",
    )
    ef.add_argument("--cross-check", action="store_true", help="LC with the two-view cross-check")
    ef.add_argument(
        "--weights",
        type=Path,
        help="confidence ConvNet checkpoint for the 'LC ConvNet' row (default: the shipped one "
        "fuse() picks, the far-camera network with --view right)",
    )
    ef.add_argument("--no-convnet", action="store_true", help="leave out the 'LC ConvNet' row")
    ef.add_argument(
        "--out",
        type=folder,
        default=Path("out/eval_fusion"),
        help="output folder (out/eval_fusion)",
    )
    ef.add_argument("--quiet", action="store_true", help="no progress bar")


#: Metres per unit of a 16-bit depth PNG unless ``--depth-scale`` says otherwise (millimetres,
#: as NYUv2, Kinect and Azure Kinect store them).
DEPTH_PNG_SCALE = 1e-3
DEPTH_SCALE_HELP = (
    f"metres per unit of a 16-bit depth PNG (default {DEPTH_PNG_SCALE:g}: millimetres; 0.0002 "
    "for TUM's 5000 per metre, 0.0001 for 0.1 mm); only for PNG: .npy/.npz depth is metres"
)
#: Bounds of --depth-scale (metres per PNG unit): 1 um to 1 km.
DEPTH_SCALE_RANGE = (1e-6, 1e3)


def depth_png_scale(flag: str, path: Path, scale: float | None) -> float:
    """``--depth-scale`` (None: not given) for the depth file ``path`` of ``flag``: refused
    with a .npy/.npz, which holds metres."""
    if scale is None:
        return DEPTH_PNG_SCALE
    if path.suffix.lower() != ".png":
        raise InvalidArgumentError(
            f"--depth-scale: given with {flag} {path}, expected it only with a 16-bit PNG "
            "(.npy/.npz depth is metres)"
        )
    return scale


def load_map(
    flag: str,
    path: Path,
    *,
    png_scale: float = 1.0,
    depth: bool = False,
    names: tuple[str, ...] = (),
) -> npt.NDArray[np.float32]:
    """The ``H x W`` map of ``flag``'s file: .npy, a .npz with one array (or, of several, the
    first one named in ``names``; for a ``depth`` map also one named ``depth``, as
    `rgbd reproject` writes), or a PNG (values x ``png_scale``, 0 = invalid; a ``depth`` PNG
    must have 16 bits). Bad files raise an RgbdError naming ``flag`` and the file."""
    from rgbd_rs.io import read_npy, read_npz, read_png

    suffix = path.suffix.lower()
    if suffix == ".png":
        raw = named(flag, lambda: read_png(path))
        if raw.ndim != 2:
            raise ShapeMismatchError(
                f"{flag}: {path}: got a PNG of shape {raw.shape}, expected a single channel"
            )
        if depth and raw.dtype != np.uint16:
            raise InvalidArgumentError(
                f"{flag}: {path}: got an 8-bit PNG, expected a 16-bit depth PNG (8 bits cannot "
                "hold depth; save 16-bit millimetres, or .npy in metres)"
            )
        return np.where(raw > 0, raw * png_scale, np.nan).astype(np.float32)
    if suffix == ".npy":
        arr = named(flag, lambda: read_npy(path))
    elif suffix == ".npz":
        arrays = named(flag, lambda: read_npz(path))
        wanted = (*names, "depth") if depth else names
        picked = next((n for n in wanted if n in arrays), None)
        if len(arrays) > 1 and picked is not None:
            arrays = {picked: arrays[picked]}
        if len(arrays) != 1:
            expected = ("exactly one array" if not wanted else "one array") + "".join(
                f", or one named {n!r}" for n in wanted
            )
            raise InvalidArgumentError(
                f"{flag}: {path}: got arrays {sorted(arrays)}, expected {expected}"
            )
        (arr,) = arrays.values()
    else:
        raise InvalidArgumentError(
            f"{flag}: {path}: got suffix {suffix!r}, expected .npy, .npz or .png"
        )
    if arr.dtype.kind not in "biuf":
        raise InvalidArgumentError(f"{flag}: {path}: got dtype {arr.dtype}, expected a numeric map")
    if depth and arr.dtype.kind in "biu":
        raise InvalidArgumentError(
            f"{flag}: {path}: got dtype {arr.dtype}, expected float depth in metres (a 16-bit "
            "map of millimetres: save it as a 16-bit PNG, or divide by 1000)"
        )
    if arr.ndim != 2 or arr.size == 0:
        raise ShapeMismatchError(
            f"{flag}: {path}: got shape {arr.shape}, expected a non-empty H x W map"
        )
    return np.asarray(arr, np.float32)


def run_fuse(args: argparse.Namespace) -> int:
    from rgbd_rs.data.calibration import load_rig
    from rgbd_rs.fusion import LcParams, fuse
    from rgbd_rs.io import read_png, write_npz, write_png
    from rgbd_rs.viz import as_bgr, class_picture, grid, image_panel, map_panel, save_png

    if (args.tof_confidence is None) != (args.stereo_confidence is None):
        raise InvalidArgumentError(
            "--tof-confidence/--stereo-confidence: got one, expected both or neither"
        )
    refuse_overwriting(args.out, FUSE_OUTPUTS, "--out", input_paths(args))  # before the work
    if args.radius is not None and args.stride > args.radius:
        return fail(f"--stride: got {args.stride}, expected at most --radius ({args.radius})")
    rig = named("--calib", lambda: load_rig(args.calib))
    left = named("--left", lambda: read_png(args.left))
    right = named("--right", lambda: read_png(args.right))
    scale = depth_png_scale("--tof-depth", args.tof_depth, args.depth_scale)
    # `rgbd synth`'s data.npz holds both maps: --tof-depth/--tof-amplitude may both name it.
    depth = load_map(
        "--tof-depth", args.tof_depth, png_scale=scale, depth=True, names=("tof_depth",)
    )
    amp = load_map("--tof-amplitude", args.tof_amplitude, names=("tof_amplitude", "amplitude"))
    chosen = args.confidence or "convnet"
    conf: object = chosen
    if args.tof_confidence is not None and args.confidence is not None:
        raise InvalidArgumentError(
            f"--confidence {args.confidence}: given with --tof-confidence/--stereo-confidence, "
            "expected one source of confidences (your maps replace the ConvNet)"
        )
    net_flags = [f for f, on in (("--weights", args.weights is not None),
                                 ("--precision", args.precision is not None)) if on]  # fmt: skip
    if net_flags and (chosen != "convnet" or args.tof_confidence):
        given = "--tof-confidence" if args.tof_confidence else f"--confidence {chosen}"
        raise InvalidArgumentError(
            f"{net_flags[0]}: given with {given}, expected it only with --confidence convnet "
            "(the ConvNet it sets)"
        )
    if net_flags:
        from rgbd_rs.fusion._inputs import far_camera_warning, with_reference
        from rgbd_rs.fusion.fuse import shipped_estimator
        from rgbd_rs.nn.confidence import ConfidenceEstimator, Precision

        precision: Precision = args.precision or "auto"
        if args.weights is None:  # --precision alone: the shipped network fuse() would pick
            fused_on = rig if args.reference is None else with_reference(rig, args.reference)
            far = far_camera_warning(fused_on) is not None
            conf = named(
                "--precision", lambda: shipped_estimator(far=far).with_precision(precision)
            )
        else:
            conf = named(
                "--weights", lambda: ConfidenceEstimator.load(args.weights, precision=precision)
            )
    if args.tof_confidence is not None:
        conf = (
            load_map("--tof-confidence", args.tof_confidence),
            load_map("--stereo-confidence", args.stereo_confidence),
        )
    params = LcParams(radius=args.radius, stride=args.stride, cross_check=args.cross_check)
    t0 = time.perf_counter()
    out = flagged(
        FUSE_FLAGS,
        lambda: fuse(
            left,
            right,
            depth,
            amp,
            rig,
            confidence=conf,  # type: ignore[arg-type]
            params=params,
            max_disparity=args.max_disparity,
            reference=args.reference,
            refine_pose=not args.keep_pose,
        ),
    )
    elapsed = time.perf_counter() - t0
    maps: dict[str, np.ndarray] = {
        "disparity": out.disparity,
        "depth": out.depth,
        "plausibility": out.plausibility,
        "tof_disparity": out.tof.disparity,
        "stereo_disparity": out.stereo_disparity,
    }
    if out.source is not None:
        maps["source"] = out.source
    if out.tof_pose is not None:  # 4x4, ToF frame -> the output camera's (metres)
        maps["tof_pose"] = out.tof_pose.as_matrix()
    maps["tof_scale"] = np.array(out.tof_scale, np.float64)
    if out.tof_confidence is not None and out.stereo_confidence is not None:
        maps |= {"tof_confidence": out.tof_confidence, "stereo_confidence": out.stereo_confidence}
    output_folder(args.out, FUSE_OUTPUTS)  # inputs checked before the work
    write_npz(args.out / "fused.npz", maps)
    write_png(args.out / "disparity.png", disparity_png16(out.disparity))
    clipped = disparity_png_note(out.disparity, "fused.npz")
    if clipped is not None:
        print(clipped, file=sys.stderr)
    write_png(args.out / "depth_mm.png", depth_mm_png16(out.depth))
    ref = right if out.reference == "right" else left
    d = out.disparity[np.isfinite(out.disparity)]
    lo, hi = (float(np.percentile(d, 1)), float(np.percentile(d, 99))) if d.size else (0.0, 1.0)
    weights = "confidence-weighted" if out.tof_confidence is not None else "uniform weights"
    panels = [
        image_panel(as_bgr(ref), f"{out.reference} camera (reference)", width=PREVIEW_WIDTH),
        map_panel(out.tof.disparity, "ToF, upsampled: disparity", unit="px", vmin=lo, vmax=hi,
                  width=PREVIEW_WIDTH),
        map_panel(out.stereo_disparity, f"stereo ({out.stereo_matcher} SGM): disparity",
                  unit="px", vmin=lo, vmax=hi, width=PREVIEW_WIDTH),
        map_panel(out.disparity, f"fused (LC, {weights}): disparity", unit="px", vmin=lo,
                  vmax=hi, width=PREVIEW_WIDTH),
        map_panel(out.plausibility, "fused: plausibility", unit="", vmin=0, vmax=1,
                  width=PREVIEW_WIDTH),
        map_panel(out.depth, "fused: depth", unit="m", width=PREVIEW_WIDTH),
    ]  # fmt: skip
    if out.source is not None:  # where each fused pixel comes from (mask 5 for no guesses)
        panels.append(
            class_picture(out.source.astype(np.int64), SOURCE_NAMES, SOURCE_COLOURS,
                          "fused: source of each pixel (fused.npz 'source')",
                          width=PREVIEW_WIDTH)
        )  # fmt: skip
    save_png(args.out / "preview.png", grid(panels, columns=3))
    saturated = np.isfinite(out.depth) & (out.depth > DEPTH_PNG_MAX_M)
    if saturated.mean() > 0.01:
        print(
            f"rgbd: warning: depth_mm.png: {saturated.mean():.0%} of the pixels lie beyond "
            f"{DEPTH_PNG_MAX_M:g} m, the most a 16-bit millimetre PNG holds, and read 65535 "
            "there: check the rig's units (metres); fused.npz holds them exactly",
            file=sys.stderr,
        )
    from rgbd_rs.fusion._inputs import with_reference as on_camera

    as_given = (rig if args.reference is None else on_camera(rig, args.reference)).tof_to_reference
    if out.tof_pose is not None and (
        out.tof_scale != 1.0 or not np.allclose(out.tof_pose.as_matrix(), as_given.as_matrix())
    ):
        print(
            f"fused with the ToF depths divided by {out.tof_scale:.3f} and this pose, ToF frame "
            f"-> {out.reference} camera (metres; fused.npz 'tof_scale', 'tof_pose'):\n"
            + np.array2string(out.tof_pose.as_matrix(), precision=6, suppress_small=True)
        )
    from rgbd_rs.fusion.stereo import MIN_RANGE_COVERAGE, _range_and_coverage

    if args.max_disparity is not None:
        how = "--max-disparity"
    elif not np.isfinite(out.tof.disparity).any():
        how = "no ToF disparity: the largest range the width allows"
    elif _range_and_coverage(out.tof.disparity)[1] < MIN_RANGE_COVERAGE:
        how = "too few ToF disparities: the largest range the width allows"
    else:
        how = "from the ToF disparities"
    from rgbd_rs.fusion.fuse import _fuse_top

    searched = _fuse_top(out.stereo_matcher, out.max_disparity, out.disparity.shape[1])
    steps = (
        ""
        if searched == out.max_disparity
        else f": {out.max_disparity} px, searched in whole 16-px steps"
    )
    print(f"SGM search range: 0-{searched} px ({how}{steps})")

    def valid(m: npt.NDArray[np.float32]) -> str:
        return f"{np.isfinite(m).mean():.1%}"

    union = np.isfinite(out.tof_fused) | np.isfinite(out.stereo_disparity)
    print(
        f"valid pixels on the {out.reference} camera: ToF {valid(out.tof.disparity)}, "
        f"SGM {valid(out.stereo_disparity)} ({out.stereo_matcher}), either {union.mean():.1%}, "
        f"fused {valid(out.disparity)}"
    )
    if out.source is not None:
        from rgbd_rs.fusion import sources as S

        tof_px, st_px = (out.source == S.SOURCE_TOF).mean(), (out.source == S.SOURCE_STEREO).mean()
        carried = (out.source == S.SOURCE_TOF_CARRIED).mean()
        lent = (out.source == S.SOURCE_LC_UNMEASURED).mean()
        print(
            f"fused pixels taken from one input where LC had no value or nothing to check it "
            f"against: ToF {tof_px:.1%}, SGM {st_px:.1%}; the ToF carried to the border the "
            f"other camera cannot see {carried:.1%}; "
            f"LC's answer where neither input measured {lent:.1%}, less sure than its "
            "plausibility says (fused.npz 'source': 2, 3, 4, 5)"
        )
    print(
        f"fused {out.disparity.shape[1]}x{out.disparity.shape[0]} in {elapsed:.2f} s; wrote "
        f"{args.out}/fused.npz, disparity.png, depth_mm.png, preview.png"
    )
    return 0


def run_eval(args: argparse.Namespace) -> int:
    from rgbd_rs.fusion import LcParams
    from rgbd_rs.fusion.evaluate import evaluate, markdown_table, middlebury_samples, synth_samples

    if args.dense and args.real is None:
        raise InvalidArgumentError("--dense: got it without --real, expected --real SPLIT too")
    if args.view != "left" and args.real is None:
        raise InvalidArgumentError("--view: got it without --real, expected --real SPLIT too")
    if args.scenes is not None and args.real is None:
        raise InvalidArgumentError("--scenes: got it without --real, expected --real SPLIT too")
    if args.view != "left" and args.dense:
        raise InvalidArgumentError("--view: got right with --dense, expected the --laws protocol")
    if args.synth is None and not args.middlebury and args.real is None:
        raise InvalidArgumentError(
            "--synth/--middlebury/--real: got none of them, expected at least one"
        )
    params = LcParams(stride=args.stride, cross_check=args.cross_check)
    estimator = None
    if not args.no_convnet:
        from rgbd_rs.nn.confidence import ConfidenceEstimator

        estimator = ConfidenceEstimator.load(args.weights)
    if args.synth is not None:
        samples = named(
            "--synth", lambda: list(islice(synth_samples(args.synth, args.split), args.limit))
        )
        if not samples:
            raise InvalidArgumentError(
                f"--synth: got {args.synth} with no scene in its {args.split} split, expected "
                "at least one (another --split, or rgbd synth --train/--test N)"
            )
        res = evaluate(
            samples,
            args.out / "synth",
            title=f"synthetic {args.split} set",
            params=params,
            estimator=estimator,
            quiet=args.quiet,
        )
        print(markdown_table(res, f"synthetic {args.split} set ({len(res)} scenes)"))
    if args.real is not None:
        from rgbd_rs.fusion.evaluate_real import evaluate_real, markdown
        from rgbd_rs.fusion.real_scenes import dense_protocol_samples, real_samples

        given = [] if args.scenes is None else args.scenes.split(",")
        scenes = None if args.scenes is None else [n.strip() for n in given if n.strip()]
        if args.dense:
            title = f"real {args.real} split, dense 512x424 ToF"
            real_cases = named("--scenes", lambda: dense_protocol_samples(args.real, scenes=scenes))
            folder = args.out / f"real_{args.real}_dense"
        else:
            per = "1 ToF law" if args.laws == 1 else f"{args.laws} ToF laws"
            title = f"real {args.real} split ({per} per scene)"
            real_cases = named(
                "--scenes",
                lambda: real_samples(args.real, args.laws, view=args.view, scenes=scenes),
            )
            folder = args.out / f"real_{args.real}"
            if args.view == "right":
                title = f"{title}, fused on the right camera (far from the ToF)"
                folder = args.out / f"real_{args.real}_right"
        cases = evaluate_real(
            islice(real_cases, args.limit),
            folder,
            title=title,
            # Without --weights, fuse()'s own choice (the far-camera network on --view right).
            estimator=None if args.weights is None else estimator,
            confidence="heuristic" if args.no_convnet else "convnet",
            params=params,
            quiet=args.quiet,
        )
        print(markdown(cases, title))
    if args.middlebury:
        mb = middlebury_samples()
        res = evaluate(
            mb,
            args.out / "middlebury",
            title="Middlebury (simulated ToF)",
            params=params,
            estimator=estimator,
            quiet=args.quiet,
        )
        print(markdown_table(res, "Middlebury (simulated ToF)"))
    print(f"tables and figures in {args.out}/")
    return 0
