"""``rgbd demo``: the library on synthetic and real data."""

from __future__ import annotations

import argparse
from pathlib import Path

from rgbd_rs.cli._args import Commands, folder, integer


def register(commands: Commands) -> None:
    demo = commands.command(
        "demo",
        run,
        help="run the demo on synthetic and real data",
        description="Camera geometry on an analytic scene and on the real Azure "
        "Kinect frame, ToF-stereo fusion of a rendered SYNTH3-style scene, segmentation and "
        "semantic labeling of a real NYUv2 frame, and shape classification of real ModelNet "
        "shapes; prints measurements and writes PNGs.",
    )
    demo.add_argument(
        "--out", type=folder, default=Path("out/demo"), help="folder for the pictures (out/demo)"
    )
    demo.add_argument("--no-pictures", action="store_true", help="print only")
    demo.add_argument(
        "--seed", type=integer(0, 2**32 - 1), default=0, help="random seed (default 0)"
    )


def run(args: argparse.Namespace) -> int:
    from rgbd_rs import demo

    return demo.main(None if args.no_pictures else args.out, seed=args.seed)
