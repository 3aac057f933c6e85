"""``rgbd demo``: what the library does today, on synthetic and real data.

1. Synthetic: an analytic scene (tilted wall + sphere) is ray-cast through a distorted camera A;
   its depth map is reprojected into a second distorted camera B and compared with B's own
   analytic depth; random scene points go through project -> undistort -> back-project.
2. Real: the Azure Kinect ToF frame is reprojected onto its colour camera (if the shared data is
   present), with coverage, depth range and edge alignment printed.
3. Fusion: a SYNTH3-style room is rendered (stereo pair + simulated ToF) and fused (ch. 3); the
   RMS disparity error of ToF, SGM and the LC variants is printed and pictured (fusion.png).
Pictures go to ``--out``.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
import numpy.typing as npt

from rgbd_rs.camera import Distortion, PinholeCamera, Pose
from rgbd_rs.data import (
    data_root,
    load_azure_kinect_calibration,
    load_azure_kinect_frame,
    reproject_to_color,
)
from rgbd_rs.geometry import Reprojection, reproject_depth
from rgbd_rs.metrics import edge_alignment
from rgbd_rs.viz import as_bgr, class_picture, colorize, grid, image_panel, map_panel, save_png

F64 = npt.NDArray[np.float64]

SPHERE_CENTER = np.array([0.1, 0.05, 2.0])
SPHERE_RADIUS = 0.45
WALL_NORMAL = np.array([0.2, 0.0, -1.0]) / np.linalg.norm([0.2, 0.0, -1.0])
WALL_OFFSET = -3.2  # n · X = WALL_OFFSET


def _cast(origin: F64, dirs: F64) -> F64:
    """Ray parameter of the first hit of rays ``origin + s * dirs`` with the analytic scene."""
    oc = origin - SPHERE_CENTER
    b = dirs @ oc
    a = np.einsum("ij,ij->i", dirs, dirs)
    disc = b * b - a * (oc @ oc - SPHERE_RADIUS**2)
    with np.errstate(invalid="ignore"):
        s_sphere = np.where(disc >= 0, (-b - np.sqrt(disc)) / a, np.inf)
        s_wall = (WALL_OFFSET - WALL_NORMAL @ origin) / (dirs @ WALL_NORMAL)
    s_wall = np.where(s_wall > 0, s_wall, np.inf)
    s = np.minimum(np.where(s_sphere > 0, s_sphere, np.inf), s_wall)
    return np.where(np.isfinite(s), s, np.nan)


def _analytic_depth(cam: PinholeCamera, world_to_cam: Pose) -> npt.NDArray[np.float32]:
    """Ground-truth depth (z in ``cam``) of the analytic scene, scene frame = camera A's."""
    u, v = np.meshgrid(
        np.arange(cam.width, dtype=np.float64), np.arange(cam.height, dtype=np.float64)
    )
    xy = cam.undistort_points(np.column_stack([u.ravel(), v.ravel()]), normalized=True)
    d_cam = np.column_stack([xy, np.ones(len(xy))])
    inv = world_to_cam.inverse()
    s = _cast(inv.translation, d_cam @ inv.rotation.T)
    return (s * d_cam[:, 2]).reshape(cam.height, cam.width).astype(np.float32)


@dataclass(frozen=True)
class SyntheticResult:
    point_round_trip_m: float
    reprojection_median_abs_m: float
    reprojection_coverage: float
    compared_pixels: int


def run_synthetic(out: Path | None, seed: int = 0) -> SyntheticResult:
    """The synthetic part of the demo; returns its measurements."""
    rng = np.random.default_rng(seed)
    cam_a = PinholeCamera(
        420.0, 420.0, 319.5, 239.5, 640, 480, Distortion(k1=-0.25, k2=0.08, p1=1e-3, p2=-5e-4)
    )
    cam_b = PinholeCamera(
        600.0, 600.0, 479.5, 269.5, 960, 540, Distortion(k1=0.1, k2=-0.02, k3=0.005)
    )
    a_to_b = Pose(_rot_y(np.deg2rad(3.0)), np.array([-0.12, 0.01, 0.0]))

    # Points: project -> undistort -> back-project with their true depth.
    pts = rng.uniform([-1.0, -0.7, 1.0], [1.0, 0.7, 4.0], size=(100_000, 3))
    px = cam_a.project(pts)
    back = cam_a.backproject(px, pts[:, 2])
    round_trip = float(np.nanmax(np.linalg.norm(back - pts, axis=1)))

    depth_a = _analytic_depth(cam_a, Pose.identity())
    depth_b = _analytic_depth(cam_b, a_to_b)
    rep = reproject_depth(depth_a, cam_a, cam_b, a_to_b, splat_radius=1)
    both = np.isfinite(rep.depth) & np.isfinite(depth_b)
    err = np.abs(rep.depth - depth_b)
    med = float(np.median(err[both]))
    if out is not None:
        save_png(
            out / "synthetic_reprojection.png",
            reprojection_figure(depth_a, rep.depth, depth_b, _coverage(cam_a, cam_b, a_to_b, rep)),
        )
    return SyntheticResult(round_trip, med, rep.coverage, int(both.sum()))


#: Classes of the reprojection's coverage panel (RGB colours).
COVERAGE = (
    ("reprojected", (60, 170, 60)),
    ("hidden from camera A (occlusion)", (230, 150, 30)),
    ("outside camera A's view", (120, 180, 255)),
)


def _coverage(
    cam_a: PinholeCamera, cam_b: PinholeCamera, a_to_b: Pose, rep: Reprojection
) -> npt.NDArray[np.int64]:
    """Per pixel of B: 0 reprojected, 1 a hole although camera A sees the direction (occlusion,
    or a splat gap), 2 outside camera A's image, -1 no scene at all."""
    truth = _analytic_depth(cam_b, a_to_b)
    pts = cam_b.depth_to_points(truth).reshape(-1, 3)
    in_a = a_to_b.inverse().apply(pts)
    px = cam_a.project(in_a)
    inside = (
        (px[:, 0] >= -0.5)
        & (px[:, 0] <= cam_a.width - 0.5)
        & (px[:, 1] >= -0.5)
        & (px[:, 1] <= cam_a.height - 0.5)
    ).reshape(truth.shape)
    cls = np.where(np.isfinite(rep.depth), 0, np.where(inside, 1, 2))
    return np.where(np.isfinite(truth), cls, -1)


def reprojection_figure(
    depth_a: npt.NDArray[np.float32],
    reprojected: npt.NDArray[np.float32],
    depth_b: npt.NDArray[np.float32],
    coverage: npt.NDArray[np.int64],
) -> npt.NDArray[np.uint8]:
    """The synthetic reprojection's panels: both depths and the reprojection on one depth
    scale (m), the |error| scaled to its 99th percentile (mm), and where B got no value."""
    lo, hi = float(np.nanmin(depth_b)), float(np.nanmax(depth_b))
    err_mm = np.abs(reprojected - depth_b) * 1e3
    top = float(np.nanpercentile(err_mm, 99)) if np.isfinite(err_mm).any() else 1.0
    names = [name for name, _ in COVERAGE]
    colors = [color for _, color in COVERAGE]
    return grid(
        [
            map_panel(depth_a, "depth, camera A (distorted, 640x480)", unit="m", vmin=lo, vmax=hi),
            map_panel(reprojected, "A reprojected into camera B", unit="m", vmin=lo, vmax=hi),
            map_panel(depth_b, "analytic depth, camera B (960x540)", unit="m", vmin=lo, vmax=hi),
            map_panel(err_mm, "|reprojected - analytic|", unit="mm", vmin=0.0, vmax=top),
            class_picture(coverage, names, colors, "camera B: where a value came from"),
        ],
        columns=3,
    )


def _rot_y(a: float) -> F64:
    c, s = np.cos(a), np.sin(a)
    return np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])


def run_kinect(out: Path | None) -> dict[str, float] | None:
    """Reproject the real Azure Kinect frame onto its colour camera (None without the data)."""
    root = data_root()
    if root is None or not (root / "tof" / "azure_kinect_frame.npz").exists():
        return None
    cal = load_azure_kinect_calibration(root / "tof" / "azure_kinect_calibration.json")
    frame = load_azure_kinect_frame(root / "tof" / "azure_kinect_frame.npz")
    rep = reproject_to_color(frame, cal)
    wrong = reproject_to_color(frame, cal, pose=cal.depth_to_color.inverse())
    stats = {
        "coverage": rep.coverage,
        "source_valid": float(np.isfinite(frame.depth).mean()),
        "depth_p50_source": float(np.nanmedian(frame.depth)),
        "depth_p50_target": float(np.nanmedian(rep.depth)),
        "edge_alignment": edge_alignment(rep.depth, frame.color),
        "edge_alignment_inverse_pose": edge_alignment(wrong.depth, frame.color),
    }
    if out is not None:
        color = as_bgr(frame.color)
        assert rep.channels is not None
        lo, hi = (float(v) for v in np.nanpercentile(frame.depth, [1, 99]))
        # Depth over colour where the ToF landed, the plain colour image elsewhere.
        tinted = (0.5 * color + 0.5 * colorize(rep.depth, lo, hi)).astype(np.uint8)
        over = np.where(np.isfinite(rep.depth)[..., None], tinted, color)
        amp = np.log10(np.where(frame.amplitude > 0, frame.amplitude, np.nan))
        alo, ahi = (float(v) for v in np.nanpercentile(amp, [1, 99]))
        rep_amp = np.log10(np.where(rep.channels > 0, rep.channels, np.nan))
        ch, cw = frame.color.shape[:2]
        dh, dw = frame.depth.shape
        # One row per camera lattice, so no row is padded to the other's aspect ratio.
        on_color = [
            image_panel(color, f"colour camera {cw}x{ch}"),
            map_panel(rep.depth, "ToF depth on the colour camera", unit="m", vmin=lo, vmax=hi),
            image_panel(over, "colour + ToF depth (its colours as beside)"),
        ]
        on_tof = [
            map_panel(frame.depth, f"ToF depth, ToF camera {dw}x{dh}", unit="m", vmin=lo,
                      vmax=hi),
            map_panel(amp, "ToF amplitude, ToF camera", unit="log10 DN", vmin=alo, vmax=ahi),
            map_panel(rep_amp, "ToF amplitude on the colour camera", unit="log10 DN", vmin=alo,
                      vmax=ahi),
        ]  # fmt: skip
        # Equal widths: three panels of the default width in each row.
        rows = [grid(on_color, columns=3), grid(on_tof, columns=3)]
        save_png(out / "kinect_depth_to_color.png", np.vstack(rows))
    return stats


def main(out: Path | None, seed: int = 0) -> int:
    """Run every part and print its results; with ``out``, the figures and ``out/index.html``
    (every figure and the printed measurements on one page)."""
    from rgbd_rs.demo_page import capture, write_index

    with capture() as printed:
        _run(out, seed)
    if out is not None:
        page = write_index(out, printed.getvalue())
        print(f"Pictures in {out}/ (all on one page: {page})")
    return 0


def _run(out: Path | None, seed: int) -> None:
    syn = run_synthetic(out, seed)
    print("Synthetic scene (tilted wall + sphere), two distorted cameras")
    print(
        "  project -> undistort -> back-project, 100k points: "
        f"max error {syn.point_round_trip_m:.2e} m"
    )
    print(
        "  depth A -> B reprojection: median |z - z_true| = "
        f"{syn.reprojection_median_abs_m * 1e3:.3f} mm "
        f"over {syn.compared_pixels} px (coverage {syn.reprojection_coverage:.1%})"
    )
    ak = run_kinect(out)
    if ak is None:
        print("Azure Kinect frame: shared data not found (set RGBD_DATA) - skipped")
    else:
        print("Azure Kinect ToF frame -> colour camera (real data)")
        print(
            f"  coverage of the colour lattice {ak['coverage']:.1%} "
            f"(source valid {ak['source_valid']:.1%}); "
            f"median depth {ak['depth_p50_source']:.3f} m -> {ak['depth_p50_target']:.3f} m"
        )
        print(
            f"  depth edges on colour edges (<= 2 px): {ak['edge_alignment']:.1%} "
            f"(inverse pose, a wrong registration: {ak['edge_alignment_inverse_pose']:.1%})"
        )
    from rgbd_rs.demo_fusion import report, run_fusion

    report(run_fusion(out, seed))
    from rgbd_rs import demo_scene

    demo_scene.report(demo_scene.run_segmentation(out), demo_scene.run_shapes(out))
