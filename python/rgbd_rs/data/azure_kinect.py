"""The real Azure Kinect ToF frame and its factory calibration (``../shared/data/tof``).

The calibration JSON stores, per camera, 14 ``ModelParameters`` (cx, cy, fx, fy, k1..k6, codx,
cody, p2, p1) with cx, cy, fx, fy normalised by the full sensor size and (0, 0) at the corner of
the top-left pixel, plus ``Rt`` relative to the depth camera (metres). A capture mode is a
binning + crop of the sensor; this module applies the same mode tables as the Azure Kinect SDK
(``transformation_get_mode_specific_camera_calibration``) and shifts to pixel-centred
coordinates (-0.5), giving OpenCV-convention cameras.

``Rt`` of the colour camera maps depth-camera points into the colour frame (checked on the real
frame: with it, depth edges land on colour edges; with its inverse they do not; see
tests/test_azure_kinect.py).
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import numpy.typing as npt

from rgbd_rs import _validate
from rgbd_rs._array_eq import array_eq
from rgbd_rs._reasons import reason
from rgbd_rs.camera import Distortion, PinholeCamera, Pose
from rgbd_rs.errors import InvalidArgumentError, RgbdError
from rgbd_rs.geometry import Reprojection, reproject_depth
from rgbd_rs.io import _no_constant, read_npz

# mode -> (binned resolution, crop offset, output resolution), from the SDK's mode tables.
DEPTH_MODES: dict[str, tuple[tuple[int, int], tuple[int, int], tuple[int, int]]] = {
    "NFOV_2X2BINNED": ((512, 512), (96, 90), (320, 288)),
    "NFOV_UNBINNED": ((1024, 1024), (192, 180), (640, 576)),
    "WFOV_2X2BINNED": ((512, 512), (0, 0), (512, 512)),
    "WFOV_UNBINNED": ((1024, 1024), (0, 0), (1024, 1024)),
}
COLOR_MODES: dict[str, tuple[tuple[int, int], tuple[int, int], tuple[int, int]]] = {
    "720P": ((1280, 960), (0, 120), (1280, 720)),
    "1080P": ((1920, 1440), (0, 180), (1920, 1080)),
    "1440P": ((2560, 1920), (0, 240), (2560, 1440)),
    "1536P": ((2048, 1536), (0, 0), (2048, 1536)),
    "2160P": ((3840, 2880), (0, 360), (3840, 2160)),
    "3072P": ((4096, 3072), (0, 0), (4096, 3072)),
}


@dataclass(frozen=True)
class AzureKinectCalibration:
    """Mode-specific depth and colour cameras and the depth -> colour pose."""

    depth: PinholeCamera
    color: PinholeCamera
    depth_to_color: Pose
    depth_metric_radius: float


@array_eq
@dataclass(frozen=True)
class AzureKinectFrame:
    """One capture: depth (metres, NaN invalid), IR amplitude, and the colour image (RGB)."""

    depth: npt.NDArray[np.float32]
    amplitude: npt.NDArray[np.float32]
    color: npt.NDArray[np.uint8]

    def __post_init__(self) -> None:
        depth = _validate.array("depth", self.depth, shape=(None, None))
        amplitude = _validate.array("amplitude", self.amplitude, shape=depth.shape)
        color = _validate.asarray("color", self.color)
        if color.dtype != np.uint8 or color.ndim != 3 or color.shape[2] != 3:
            raise InvalidArgumentError(
                f"color: got {color.dtype} of shape {color.shape}, expected H x W x 3 uint8 RGB"
            )
        object.__setattr__(self, "depth", depth)
        object.__setattr__(self, "amplitude", amplitude)


def _mode_camera(
    params: list[float], mode: tuple[tuple[int, int], tuple[int, int], tuple[int, int]]
) -> PinholeCamera:
    (bw, bh), (ox, oy), (w, h) = mode
    cx, cy, fx, fy, k1, k2, k3, k4, k5, k6, _codx, _cody, p2, p1 = params
    return PinholeCamera(
        fx=fx * bw,
        fy=fy * bh,
        cx=cx * bw - ox - 0.5,
        cy=cy * bh - oy - 0.5,
        width=w,
        height=h,
        distortion=Distortion(k1=k1, k2=k2, p1=p1, p2=p2, k3=k3, k4=k4, k5=k5, k6=k6),
    )


def load_azure_kinect_calibration(
    path: str | Path, depth_mode: str = "NFOV_UNBINNED", color_resolution: str = "720P"
) -> AzureKinectCalibration:
    """Read an Azure Kinect factory calibration JSON for one depth mode and colour resolution."""
    if not isinstance(depth_mode, str) or depth_mode not in DEPTH_MODES:
        raise InvalidArgumentError(
            f"depth_mode: got {depth_mode!r}, expected one of {list(DEPTH_MODES)}"
        )
    if not isinstance(color_resolution, str) or color_resolution not in COLOR_MODES:
        raise InvalidArgumentError(
            f"color_resolution: got {color_resolution!r}, expected one of {list(COLOR_MODES)}"
        )
    if not isinstance(path, (str, Path)) or not str(path):
        raise InvalidArgumentError(f"path: got {path!r}, expected a calibration JSON path")
    path = Path(path)
    try:
        # NaN and Infinity are not JSON numbers: refused, as read_json refuses them.
        cams = json.loads(path.read_text(), parse_constant=_no_constant)
        cams = cams["CalibrationInformation"]["Cameras"]
        by_loc = {c["Location"]: c for c in cams}
        d, c = by_loc["CALIBRATION_CameraLocationD0"], by_loc["CALIBRATION_CameraLocationPV0"]
        dp = _numbers("D0 ModelParameters", d["Intrinsics"]["ModelParameters"], 14)
        cp = _numbers("PV0 ModelParameters", c["Intrinsics"]["ModelParameters"], 14)
        sw, sh = _numbers("PV0 SensorWidth/SensorHeight", [c["SensorWidth"], c["SensorHeight"]], 2)
        if sw * 3 != sh * 4:
            raise ValueError("only 4:3 colour calibrations are supported")
        rt = c["Rt"]
        rotation = _numbers("PV0 Rt.Rotation", rt["Rotation"], 9)
        translation = _numbers("PV0 Rt.Translation", rt["Translation"], 3)
        pose = Pose(np.reshape(rotation, (3, 3)), np.asarray(translation))
        radius = _numbers("D0 MetricRadius", [d.get("MetricRadius", 0.0)], 1)[0]
        depth_cam = _mode_camera(dp, DEPTH_MODES[depth_mode])
        color_cam = _mode_camera(cp, COLOR_MODES[color_resolution])
    except (OSError, KeyError, TypeError, ValueError, OverflowError, AttributeError) as exc:
        # json.JSONDecodeError and the cameras' own InvalidArgumentError are ValueErrors.
        raise InvalidArgumentError(
            f"path: could not read an Azure Kinect calibration from {path} ({reason(exc)}), "
            "expected the "
            "device's calibration JSON with D0 and PV0 cameras"
        ) from None
    return AzureKinectCalibration(depth_cam, color_cam, pose, radius)


def _numbers(what: str, values: object, count: int) -> list[float]:
    """``count`` JSON numbers (strings are refused, not parsed)."""
    if not isinstance(values, list) or len(values) != count:
        raise ValueError(f"{what}: expected a list of {count} numbers")
    for v in values:
        if isinstance(v, bool) or not isinstance(v, (int, float)):
            raise ValueError(f"{what}: got {v!r}, expected numbers")
        if not math.isfinite(float(v)):
            raise ValueError(f"{what}: got {v!r}, expected finite numbers")
    return [float(v) for v in values]


def reproject_to_color(
    frame: AzureKinectFrame,
    calibration: AzureKinectCalibration,
    *,
    splat_radius: int = 1,
    pose: Pose | None = None,
) -> Reprojection:
    """Reproject a frame's ToF depth (carrying its amplitude) onto the colour camera.

    ``pose`` overrides the calibrated depth -> colour transform (e.g. to test a registration).
    """
    if not isinstance(frame, AzureKinectFrame):
        raise InvalidArgumentError(
            f"frame: got {type(frame).__name__}, expected an AzureKinectFrame"
        )
    if not isinstance(calibration, AzureKinectCalibration):
        raise InvalidArgumentError(
            f"calibration: got {type(calibration).__name__}, expected an AzureKinectCalibration"
        )
    return reproject_depth(
        frame.depth,
        calibration.depth,
        calibration.color,
        calibration.depth_to_color if pose is None else pose,
        channels=frame.amplitude,
        splat_radius=splat_radius,
    )


def load_azure_kinect_frame(path: str | Path) -> AzureKinectFrame:
    """Read ``azure_kinect_frame.npz`` (``depth_mm``, ``ir``, ``color``); 0 mm becomes NaN."""
    if not isinstance(path, (str, Path)) or not str(path):
        raise InvalidArgumentError(f"path: got {path!r}, expected an npz file path")
    path = Path(path)
    try:
        arrays = read_npz(path, ["depth_mm", "ir", "color"])
    except RgbdError as exc:
        raise InvalidArgumentError(
            f"path: could not read an Azure Kinect frame ({exc}), expected an npz with "
            "depth_mm, ir and color"
        ) from None
    depth_mm, ir, color = arrays["depth_mm"], arrays["ir"], arrays["color"]
    if depth_mm.dtype.kind not in "ui" or depth_mm.dtype.itemsize < 2:
        raise InvalidArgumentError(
            f"path: {path} holds depth_mm as {depth_mm.dtype}, expected integer millimetres "
            "(uint16, as the device writes them; metres stored as floats would be 1000x too near)"
        )
    kinds = (depth_mm.dtype.kind, ir.dtype.kind, color.dtype.kind)
    if any(k not in "uif" for k in kinds) or color.dtype != np.uint8:
        raise InvalidArgumentError(
            f"path: {path} holds depth {depth_mm.dtype}, ir {ir.dtype}, color {color.dtype}, "
            "expected numeric depth_mm and ir and a uint8 colour image"
        )
    if (
        depth_mm.shape != ir.shape
        or depth_mm.ndim != 2
        or color.ndim != 3
        or color.shape[2] < 3
        or depth_mm.size == 0
    ):
        raise InvalidArgumentError(
            f"path: {path} holds depth {depth_mm.shape}, ir {ir.shape}, color {color.shape}, "
            "expected equal 2-D depth/ir and an H x W x 3 colour image"
        )
    if depth_mm.dtype.kind == "i" and (depth_mm < 0).any():
        raise InvalidArgumentError(
            f"path: {path} holds {int((depth_mm < 0).sum())} negative depth_mm values (down to "
            f"{int(depth_mm.min())}), expected millimetres >= 0 (0 = no return; the device "
            "writes uint16)"
        )
    depth = depth_mm.astype(np.float32) / 1000.0
    depth[depth_mm == 0] = np.nan
    return AzureKinectFrame(depth, ir.astype(np.float32), np.ascontiguousarray(color[:, :, :3]))
