"""ToF + stereo rig calibration as JSON (intrinsics, distortion, extrinsics), the format
``rgbd synth`` writes and ``rgbd fuse`` reads.

Layout: ``{"stereo": {"left": CAM, "right": CAM, "baseline": m}, "tof": CAM,
"tof_to_reference": {"rotation": 3x3, "translation": [x, y, z]}, "reference": "right"}`` with
``CAM = {"fx", "fy", "cx", "cy", "width", "height", "distortion": [k1, k2, p1, p2, k3, k4, k5,
k6]}`` (OpenCV order). Units: pixels and metres.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from rgbd_rs.camera import Distortion, PinholeCamera, Pose, StereoRig, ToFStereoRig
from rgbd_rs.data.files import read_json, write_json
from rgbd_rs.errors import RgbdError


def _cam(c: PinholeCamera) -> dict[str, Any]:
    return {
        "fx": c.fx,
        "fy": c.fy,
        "cx": c.cx,
        "cy": c.cy,
        "width": c.width,
        "height": c.height,
        "distortion": [float(v) for v in c.distortion.to_opencv()],
    }


def rig_to_dict(rig: ToFStereoRig) -> dict[str, Any]:
    """The JSON-ready description of ``rig``."""
    return {
        "stereo": {
            "left": _cam(rig.stereo.left),
            "right": _cam(rig.stereo.right),
            "baseline": rig.stereo.baseline,
        },
        "tof": _cam(rig.tof),
        "tof_to_reference": {
            "rotation": np.asarray(rig.tof_to_reference.rotation).tolist(),
            "translation": np.asarray(rig.tof_to_reference.translation).tolist(),
        },
        "reference": rig.reference,
    }


def save_rig(path: str | Path, rig: ToFStereoRig) -> Path:
    """Write ``rig`` as calibration JSON (atomically)."""
    return write_json(path, rig_to_dict(rig))


def load_rig(path: str | Path) -> ToFStereoRig:
    """Read a calibration JSON; missing keys or bad values raise RgbdError naming the file."""
    d = read_json(path)

    def cam(c: dict[str, Any]) -> PinholeCamera:
        return PinholeCamera(
            float(c["fx"]),
            float(c["fy"]),
            float(c["cx"]),
            float(c["cy"]),
            int(c["width"]),
            int(c["height"]),
            Distortion.from_opencv(c.get("distortion", [0.0] * 5)),
        )

    try:
        st = d["stereo"]
        t = d["tof_to_reference"]
        return ToFStereoRig(
            tof=cam(d["tof"]),
            stereo=StereoRig(cam(st["left"]), cam(st["right"]), float(st["baseline"])),
            tof_to_reference=Pose(
                np.asarray(t["rotation"], float), np.asarray(t["translation"], float)
            ),
            reference=d.get("reference", "right"),
        )
    except KeyError as exc:
        raise RgbdError(f"{path}: calibration lacks the key {exc}") from exc
    except (TypeError, ValueError) as exc:
        raise RgbdError(f"{path}: invalid calibration ({exc})") from exc
