"""The ``rgbd`` command line. ``rgbd --help`` lists the commands; each has its own ``--help``."""

from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence
from pathlib import Path

from rgbd_rs import __version__
from rgbd_rs.errors import RgbdError


def _parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(
        prog="rgbd",
        description="rgbd_rs: ToF-stereo fusion, RGB-D segmentation and 3-D shape classification "
        "with a fast Rust core.",
    )
    p.add_argument("--version", action="version", version=f"rgbd_rs {__version__}")
    sub = p.add_subparsers(dest="command", metavar="COMMAND")

    demo = sub.add_parser(
        "demo",
        help="run the demo on synthetic and real data",
        description="Camera geometry on an analytic scene and on the real Azure "
        "Kinect frame; prints measurements and writes PNGs.",
    )
    demo.add_argument("--out", type=Path, default=Path("out/demo"), help="folder for the pictures")
    demo.add_argument("--no-pictures", action="store_true", help="print only")
    demo.add_argument("--seed", type=int, default=0, help="random seed (default 0)")

    rep = sub.add_parser(
        "reproject",
        help="reproject a ToF depth map onto a colour camera",
        description="Reproject an Azure Kinect depth frame (npz with depth_mm, "
        "ir, color) onto its colour camera using the device calibration JSON; "
        "writes depth.npz, a 16-bit PNG (mm) and a preview.",
    )
    rep.add_argument("--frame", type=Path, required=True, help="npz with depth_mm, ir, color")
    rep.add_argument("--calib", type=Path, required=True, help="Azure Kinect calibration JSON")
    rep.add_argument("--out", type=Path, required=True, help="output folder")
    rep.add_argument("--splat-radius", type=int, default=1, help="splat radius in pixels (0..8)")
    return p


def _reproject(args: argparse.Namespace) -> int:
    import numpy as np

    from rgbd_rs.data import (
        load_azure_kinect_calibration,
        load_azure_kinect_frame,
        reproject_to_color,
    )
    from rgbd_rs.viz import as_bgr, colorize, save_png, tile

    cal = load_azure_kinect_calibration(args.calib)
    frame = load_azure_kinect_frame(args.frame)
    rep = reproject_to_color(frame, cal, splat_radius=args.splat_radius)
    args.out.mkdir(parents=True, exist_ok=True)
    tmp = args.out / "depth.npz.tmp.npz"
    assert rep.channels is not None  # amplitude was passed as a channel
    np.savez_compressed(tmp, depth=rep.depth, amplitude=rep.channels)
    tmp.replace(args.out / "depth.npz")
    mm = np.clip(np.nan_to_num(rep.depth * 1000.0, nan=0.0), 0, 65535).astype(np.uint16)
    save_png(args.out / "depth_mm.png", mm)
    save_png(
        args.out / "preview.png",
        tile(
            [as_bgr(frame.color), colorize(rep.depth)], ["colour", "ToF depth on colour"], columns=2
        ),
    )
    print(f"coverage {rep.coverage:.1%}; wrote {args.out}/depth.npz, depth_mm.png, preview.png")
    return 0


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of the ``rgbd`` script."""
    args = _parser().parse_args(argv)
    try:
        if args.command == "demo":
            from rgbd_rs import demo

            return demo.main(None if args.no_pictures else args.out, seed=args.seed)
        if args.command == "reproject":
            return _reproject(args)
        _parser().print_help()
        return 2
    except RgbdError as exc:
        print(f"rgbd: error: {exc}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
