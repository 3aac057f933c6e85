"""``rgbd synth-indoor``: synthetic labeled indoor RGB-D frames (pre-training data of the
semantic-labeling ConvNet)."""

from __future__ import annotations

import argparse
from pathlib import Path

from rgbd_rs.cli._args import Commands, flagged, folder, integer, shard

#: Frames the preview shows.
PREVIEW_FRAMES = 4


def register(commands: Commands) -> None:
    p = commands.command(
        "synth-indoor",
        run_synth_indoor,
        help="generate synthetic labeled indoor RGB-D frames (13 NYUv2 classes)",
        description="Render furnished rooms with a Kinect-v1-like camera: OUT/NNNNNN_rgb.png, "
        "NNNNNN_depth.png (uint16 mm, 0 = hole), NNNNNN_label13.png and camera_NNNNNN.json, the "
        "layout of the real NYUv2 frames. Frame k of a seed is the same whatever the shard; "
        "complete frames are skipped (resume). --preview writes OUT/preview.png only; --stats "
        "prints the class pixel frequencies of OUT's frames beside the real NYUv2 frames'.",
    )
    p.add_argument("--out", type=folder, required=True, help="output folder")
    p.add_argument(
        "--count", type=integer(1, 1_000_000), required=True, help="frames 0..N-1 of the seed"
    )
    p.add_argument("--seed", type=integer(0, 2**63 - 1), default=0, help="random seed (default 0)")
    p.add_argument("--shard", type=shard, default=(0, 1), help="write frames i, i+n, ... (i/n)")
    p.add_argument("--width", type=integer(16, 4096), default=640, help="width (default 640)")
    p.add_argument("--height", type=integer(16, 4096), default=480, help="height (default 480)")
    p.add_argument("--preview", action="store_true", help="write OUT/preview.png only")
    p.add_argument("--stats", action="store_true", help="print class frequencies vs NYUv2")
    p.add_argument("--quiet", action="store_true", help="no progress bar")


def run_synth_indoor(args: argparse.Namespace) -> int:
    from rgbd_rs.data.synth_indoor import (
        generate_indoor,
        render_indoor_frame,
        write_indoor_preview,
    )

    if args.preview:
        frames = [
            render_indoor_frame(args.seed, k, width=args.width, height=args.height)
            for k in range(PREVIEW_FRAMES)
        ]
        path = write_indoor_preview(args.out / "preview.png", frames)
        print(f"wrote {path}")
        return 0
    mine = flagged(
        {"out": "--out", "shard": "--shard", "count": "--count", "width": "--width",
         "height": "--height", "seed": "--seed"},
        lambda: generate_indoor(
            args.out,
            args.count,
            seed=args.seed,
            shard=args.shard,
            width=args.width,
            height=args.height,
            quiet=args.quiet,
        ),
        warnings_too=False,
    )  # fmt: skip
    print(f"{len(mine)} frames of shard {args.shard[0]}/{args.shard[1]} in {args.out}")
    if args.stats:
        _print_stats(args.out)
    return 0


def _print_stats(out: Path) -> None:
    from rgbd_rs.data.nyuv2 import LABEL13_NAMES, load_nyuv2_frame, nyuv2_frames
    from rgbd_rs.data.paths import data_root
    from rgbd_rs.data.synth_indoor import IndoorFrames, class_frequencies

    frames = IndoorFrames(out)
    synth = class_frequencies(frames[k].label13 for k in range(len(frames)))
    real = None
    if data_root() is not None:
        ids = nyuv2_frames()
        real = class_frequencies(load_nyuv2_frame(i).label13 for i in ids)
    head = f"{'class':<11}{f'synthetic ({len(frames)})':>17}"
    print(head + (f"{f'NYUv2 ({len(ids)})':>13}" if real is not None else ""))
    for c, name in enumerate(LABEL13_NAMES):
        row = f"{name:<11}{100 * synth[c]:>16.1f}%"
        print(row + (f"{100 * real[c]:>12.1f}%" if real is not None else ""))
