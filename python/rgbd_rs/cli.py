"""The ``rgbd`` command line. ``rgbd --help`` lists the commands; each has its own ``--help``."""

from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence
from pathlib import Path

from rgbd_rs import __version__, cli_fusion
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
        "Kinect frame, then ToF-stereo fusion of a rendered SYNTH3-style scene; prints "
        "measurements and writes PNGs.",
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
    syn = sub.add_parser(
        "synth",
        help="generate a SYNTH3-style synthetic ToF + stereo dataset",
        description="Render procedural rooms with the SYNTH3 rig (thesis Table 3.1): stereo "
        "pair, ToF depth + amplitude with mixed pixels, multipath, noise and dropout, and ground "
        "truth. Resumable and bit-reproducible for a given seed. With --preview, only writes "
        "OUT/preview.png (one test scene with per-effect ToF error maps).",
    )
    syn.add_argument("--out", type=Path, required=True, help="dataset folder")
    syn.add_argument("--train", type=int, default=40, help="training scenes (default 40)")
    syn.add_argument("--test", type=int, default=15, help="test scenes (default 15)")
    syn.add_argument("--seed", type=int, default=0, help="random seed (default 0)")
    syn.add_argument(
        "--scale", type=float, default=0.5, help="stereo size relative to 1920x1080 (default 0.5)"
    )
    syn.add_argument("--preview", action="store_true", help="write OUT/preview.png only")
    syn.add_argument("--quiet", action="store_true", help="no progress bar")
    cli_fusion.add_parsers(sub)
    return p


def _synth(args: argparse.Namespace) -> int:
    if args.preview:
        from rgbd_rs.data.synth_preview import write_preview

        rms = write_preview(args.out / "preview.png", seed=args.seed, scale=args.scale)
        parts = ", ".join(
            f"{k} {100 * v:.2f} cm" for k, v in rms.items() if k != "dropout_fraction"
        )
        print(f"ToF rms error by source: {parts}; invalid {100 * rms['dropout_fraction']:.1f} %")
        print(f"wrote {args.out / 'preview.png'}")
        return 0
    from rgbd_rs.data.synth import write_dataset

    path = write_dataset(
        args.out,
        train=args.train,
        test=args.test,
        seed=args.seed,
        scale=args.scale,
        quiet=args.quiet,
    )
    print(f"wrote {args.train} + {args.test} scenes; manifest {path}")
    return 0


def _reproject(args: argparse.Namespace) -> int:
    import numpy as np

    from rgbd_rs.data import (
        load_azure_kinect_calibration,
        load_azure_kinect_frame,
        reproject_to_color,
    )
    from rgbd_rs.data.files import write_npz
    from rgbd_rs.viz import as_bgr, colorize, save_png, tile

    cal = load_azure_kinect_calibration(args.calib)
    frame = load_azure_kinect_frame(args.frame)
    rep = reproject_to_color(frame, cal, splat_radius=args.splat_radius)
    args.out.mkdir(parents=True, exist_ok=True)
    assert rep.channels is not None  # amplitude was passed as a channel
    write_npz(args.out / "depth.npz", {"depth": rep.depth, "amplitude": rep.channels})
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
        if args.command == "synth":
            return _synth(args)
        if args.command == "fuse":
            return cli_fusion.run_fuse(args)
        if args.command == "eval":
            return cli_fusion.run_eval(args)
        _parser().print_help()
        return 2
    except RgbdError as exc:
        print(f"rgbd: error: {exc}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
