"""``rgbd reproject`` and ``rgbd synth``: the dataset commands."""

from __future__ import annotations

import argparse
from pathlib import Path

from rgbd_rs.cli._args import (
    Commands,
    fail,
    flagged,
    folder,
    input_paths,
    integer,
    output_folder,
    real,
)
from rgbd_rs.cli._maps import depth_mm_png16
from rgbd_rs.geometry import MAX_SPLAT_RADIUS

#: Width of each panel of `rgbd reproject`'s preview.png (pixels).
PREVIEW_WIDTH = 480
#: Everything ``rgbd reproject`` may write (cleared first: a run without ``--undistort`` must
#: not leave an earlier run's undistorted colour image and camera beside its distorted depth).
REPROJECT_OUTPUTS = ("depth.npz", "depth_mm.png", "preview.png", "color.png", "camera.json")


def register(commands: Commands) -> None:
    # The bounds live with the generator; importing it here would load the renderer for every
    # command, so the --scale check reads them when it runs.
    rep = commands.command(
        "reproject",
        run_reproject,
        help="reproject a ToF depth map onto a colour camera",
        description="Reproject an Azure Kinect depth frame (npz with depth_mm, "
        "ir, color) onto its colour camera using the device calibration JSON; "
        "writes depth.npz (depth in metres, amplitude), a 16-bit PNG (mm) and a preview. With "
        "--undistort, also color.png, the depth and amplitude resampled onto the ideal "
        "(distortion-free) colour camera, and camera.json, ready for `rgbd segment --rgb "
        "OUT/color.png --depth OUT/depth.npz --calib OUT/camera.json`.",
    )
    rep.add_argument("--frame", type=Path, required=True, help="npz with depth_mm, ir, color")
    rep.add_argument("--calib", type=Path, required=True, help="Azure Kinect calibration JSON")
    rep.add_argument("--out", type=folder, required=True, help="output folder")
    rep.add_argument(
        "--splat-radius",
        type=integer(0, MAX_SPLAT_RADIUS),
        default=1,
        help="each depth pixel also fills the colour pixels within this radius where it is "
        f"the nearest (0..{MAX_SPLAT_RADIUS}, default 1; 0 leaves the gaps between the "
        "sparser depth samples empty)",
    )
    rep.add_argument(
        "--undistort",
        action="store_true",
        help="resample colour and depth onto the ideal colour camera and write camera.json "
        "(the segmentation needs a pinhole without distortion)",
    )
    syn = commands.command(
        "synth",
        run_synth,
        help="generate a SYNTH3-style synthetic ToF + stereo dataset",
        description="Render procedural rooms with the SYNTH3 rig (thesis Table 3.1): stereo "
        "pair, ToF depth + amplitude with mixed pixels, multipath, noise and dropout, and ground "
        "truth. Resumable and bit-reproducible for a given seed. With --preview, only writes "
        "OUT/preview.png (one test scene with per-effect ToF error maps).",
    )
    syn.add_argument("--out", type=folder, required=True, help="dataset folder")
    syn.add_argument("--train", type=_scenes, default=40, help="training scenes (default 40)")
    syn.add_argument("--test", type=_scenes, default=15, help="test scenes (default 15)")
    syn.add_argument(
        "--seed", type=integer(0, 2**32 - 1), default=0, help="random seed (default 0)"
    )
    syn.add_argument(
        "--scale",
        type=_scale,
        default=0.5,
        help="stereo size relative to 1920x1080 (default 0.5; at most 4, 7680x4320)",
    )
    syn.add_argument(
        "--vary-tof",
        action="store_true",
        help="give every scene its own randomised ToF sensor (frequency, power, noise, multipath,"
        " mixed pixels, amplitude unit, flying pixels): training data of the confidence ConvNet",
    )
    syn.add_argument("--preview", action="store_true", help="write OUT/preview.png only")
    syn.add_argument("--quiet", action="store_true", help="no progress bar")


def _scale(text: str) -> float:
    from rgbd_rs.data.synth import FULL_HEIGHT, MAX_SCALE, MIN_SIDE

    return real(MIN_SIDE / FULL_HEIGHT, MAX_SCALE, low_open=False)(text)


def _scenes(text: str) -> int:
    from rgbd_rs.data.synth import MAX_SCENES

    return integer(0, MAX_SCENES)(text)


def run_synth(args: argparse.Namespace) -> int:
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
        vary_tof=args.vary_tof,
        quiet=args.quiet,
    )
    print(f"wrote {args.train} + {args.test} scenes; manifest {path}")
    return 0


def run_reproject(args: argparse.Namespace) -> int:
    import numpy as np

    from rgbd_rs.data import (
        load_azure_kinect_calibration,
        load_azure_kinect_frame,
        reproject_to_color,
    )
    from rgbd_rs.io import write_npz
    from rgbd_rs.viz import as_bgr, grid, image_panel, map_panel, save_png

    cal = flagged({"path": "--calib"}, lambda: load_azure_kinect_calibration(args.calib))
    frame = flagged({"path": "--frame"}, lambda: load_azure_kinect_frame(args.frame))
    # The frame's maps must fit the calibration's cameras: a mismatch names --frame, before
    # anything in --out is replaced.
    want = (cal.color.height, cal.color.width)
    if frame.color.shape[:2] != want:
        h, w = frame.color.shape[:2]
        return fail(
            f"--frame color: got size {w}x{h}, expected the calibration's colour camera "
            f"{want[1]}x{want[0]} (--calib)"
        )
    from_frame = {"depth": "--frame depth_mm", "frame": "--frame"}
    rep = flagged(
        from_frame, lambda: reproject_to_color(frame, cal, splat_radius=args.splat_radius)
    )
    if not np.isfinite(rep.depth).any():
        return fail(
            "no ToF pixel reaches the colour camera (coverage 0 %): check that --frame's "
            "depth_mm is in millimetres and --calib's colour-camera translation (PV0 Rt) in "
            "metres"
        )
    output_folder(args.out, REPROJECT_OUTPUTS, inputs=input_paths(args))
    assert rep.channels is not None  # amplitude was passed as a channel
    depth, amplitude, color = rep.depth, rep.channels, frame.color
    written = "depth.npz, depth_mm.png, preview.png"
    if args.undistort:
        from rgbd_rs.data.calibration import save_camera
        from rgbd_rs.io import write_png

        cam = cal.color
        depth = cam.undistort_image(depth, interpolation="nearest")
        amplitude = cam.undistort_image(amplitude, interpolation="nearest")
        color = cam.undistort_image(color)
        write_png(args.out / "color.png", color)
        save_camera(args.out / "camera.json", cam.without_distortion())
        written += ", color.png, camera.json (undistorted)"
    write_npz(args.out / "depth.npz", {"depth": depth, "amplitude": amplitude})
    save_png(args.out / "depth_mm.png", depth_mm_png16(depth))
    panels = [
        image_panel(as_bgr(color), "colour camera", width=PREVIEW_WIDTH),
        map_panel(depth, "ToF depth on the colour camera", unit="m", width=PREVIEW_WIDTH),
    ]
    save_png(args.out / "preview.png", grid(panels, columns=2))
    print(f"coverage {rep.coverage:.1%}; wrote {args.out}/{written}")
    return 0
