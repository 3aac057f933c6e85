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
from rgbd_rs.errors import InvalidArgumentError, RgbdError
from rgbd_rs.io import read_json, write_json


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
    if not isinstance(rig, ToFStereoRig):
        raise InvalidArgumentError(f"rig: got {type(rig).__name__}, expected a ToFStereoRig")
    return write_json(path, rig_to_dict(rig))


def _number(where: str, value: object) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise ValueError(f"{where} is {value!r}, expected a JSON number")
    try:
        return float(value)
    except OverflowError:
        raise ValueError(f"{where} is an integer beyond the float range") from None


def _integer(where: str, value: object) -> int:
    if isinstance(value, bool) or not isinstance(value, int):
        raise ValueError(f"{where} is {value!r}, expected a JSON integer")
    return value


def _object(where: str, value: object) -> dict[str, Any]:
    if not isinstance(value, dict):
        raise ValueError(f"{where} is {type(value).__name__}, expected a JSON object")
    return value


def _numbers(where: str, value: object) -> list[Any]:
    """A (nested) list of JSON numbers, returned as is."""
    if not isinstance(value, list):
        raise ValueError(f"{where} is {value!r}, expected a list of numbers")
    for i, v in enumerate(value):
        if isinstance(v, list):
            _numbers(f"{where}[{i}]", v)
        else:
            _number(f"{where}[{i}]", v)
    return value


def load_rig(path: str | Path) -> ToFStereoRig:
    """Read a calibration JSON; missing keys or bad values (strings where numbers belong
    included) raise RgbdError naming the file."""
    d = read_json(path)

    def cam(where: str, value: object) -> PinholeCamera:
        c = _object(where, value)
        return PinholeCamera(
            _number(f"{where}.fx", c["fx"]),
            _number(f"{where}.fy", c["fy"]),
            _number(f"{where}.cx", c["cx"]),
            _number(f"{where}.cy", c["cy"]),
            _integer(f"{where}.width", c["width"]),
            _integer(f"{where}.height", c["height"]),
            Distortion.from_opencv(_numbers(f"{where}.distortion", c.get("distortion", [0.0] * 5))),
        )

    try:
        top = _object("the file", d)
        st = _object("stereo", top["stereo"])
        t = _object("tof_to_reference", top["tof_to_reference"])
        return ToFStereoRig(
            tof=cam("tof", top["tof"]),
            stereo=StereoRig(
                cam("stereo.left", st["left"]),
                cam("stereo.right", st["right"]),
                _number("stereo.baseline", st["baseline"]),
            ),
            tof_to_reference=Pose(
                np.asarray(_numbers("tof_to_reference.rotation", t["rotation"]), float),
                np.asarray(_numbers("tof_to_reference.translation", t["translation"]), float),
            ),
            reference=top.get("reference", "right"),
        )
    except KeyError as exc:
        raise RgbdError(f"{path}: calibration lacks the key {exc}") from exc
    except (TypeError, ValueError, OverflowError) as exc:
        raise RgbdError(f"{path}: invalid calibration ({exc})") from exc
