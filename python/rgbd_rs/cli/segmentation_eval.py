"""``rgbd eval segmentation``: the side-by-side segmentation table on the NYUv2 frames."""

from __future__ import annotations

import argparse
import importlib.util
import math
import time
from pathlib import Path

from rgbd_rs.cli._args import Commands, folder, integer
from rgbd_rs.errors import RgbdError

DESCRIPTION = (
    "Segments the NYUv2 frames of the shared data with scikit-image's felzenszwalb and slic (on "
    "RGB and on RGB + depth), our normalized-cuts over-segmentation and the fit-only merging, "
    "each at the parameters with the lowest Variation of Information on the train frames "
    "(NNNN <= 43), and prints VoI, Rand index, boundary recall, under-segmentation error, "
    "segments and seconds per frame on the chosen frames, plus boundary recall of ours vs SLIC "
    "at ~300 segments. Ground truth: connected regions of the 40-class labels (semantic regions, "
    "not instances). Writes OUT/table.md and one figure per frame, OUT/NNNN.png."
)


def register(commands: Commands) -> None:
    p = commands.group_command(
        "eval",
        "segmentation",
        run,
        help="VoI / RI / boundary recall of ours vs scikit-image on NYUv2 (Table 4.1)",
        description=DESCRIPTION,
    )
    p.add_argument(
        "--frames",
        choices=("test", "train", "all"),
        default="test",
        help="frames the table is measured on (default test: NNNN >= 46); the parameters are "
        "always tuned on the train frames",
    )
    p.add_argument(
        "--tuning-frames",
        type=integer(1, 25),
        metavar="N",
        help="tune on the first N train frames only (default all 25)",
    )
    p.add_argument(
        "--labeler",
        default="auto",
        metavar="auto|FILE",
        help="semantic ConvNet of the full-method row: the shipped weights (auto) or a "
        "`rgbd train semantic` checkpoint",
    )
    p.add_argument(
        "--out",
        type=folder,
        default=Path("out/eval_segmentation"),
        help="output folder (out/eval_segmentation)",
    )
    p.add_argument("--quiet", action="store_true", help="no progress bar")


def run(args: argparse.Namespace) -> int:
    if importlib.util.find_spec("skimage") is None:
        raise RgbdError(
            "scikit-image: not installed, expected it for the peer methods "
            "(pip install 'rgbd_rs[eval]')"
        )
    from rgbd_rs.data.nyuv2 import nyuv2_frames
    from rgbd_rs.segmentation.evaluate import default_methods, evaluate

    tuning = nyuv2_frames("train")
    if args.tuning_frames is not None:
        tuning = tuning[: args.tuning_frames]
    t0 = time.perf_counter()
    if args.labeler != "auto" and not Path(args.labeler).is_file():
        raise RgbdError(f"--labeler: {args.labeler}: no such checkpoint file (or auto)")
    report = evaluate(
        args.frames,
        tuning_frames=tuning,
        methods=default_methods(labeler=args.labeler),
        out=args.out,
        quiet=args.quiet,
    )
    semantic: list[str] = []
    if report.semantic is not None:
        semantic = [
            "",
            f"Semantic labels of the full method over NYUv2's 13 classes ({report.semantic.frames} "
            f"{args.frames} frames; unlabeled pixels left out; thesis Table 4.2 on the full "
            "654-frame test set: pixel 64.4 -> 67.2 %, class 51.7 -> 54.4 %):",
            "",
            report.semantic.table(),
            "",
            "Per class (thesis Table 4.3):",
            "",
            report.semantic.per_class_table(),
        ]
    minutes = (time.perf_counter() - t0) / 60
    chosen = [
        f"- {s.name}: "
        + (", ".join(f"{k}={v:g}" for k, v in s.params.items()) or "defaults")
        + (f" (tuning VoI {s.tuning_voi:.2f})" if not math.isnan(s.tuning_voi) else " (not tuned)")
        for s in report.scores
    ]
    text = "\n".join(
        [
            f"Parameters chosen by mean VoI on {len(report.tuning_frames)} train frames:",
            *chosen,
            "",
            f"NYUv2 {args.frames} frames ({len(report.frames)}), region ground truth = "
            "connected components of the 40-class labels:",
            "",
            report.table(),
            "",
            report.count_line(),
            *semantic,
            "",
            f"({minutes:.1f} min in all)",
        ]
    )
    print(text)
    (args.out / "table.md").parent.mkdir(parents=True, exist_ok=True)
    (args.out / "table.md").write_text(text + "\n")
    print(f"table and figures in {args.out}/")
    return 0
