"""ToF + stereo rig calibration as JSON (intrinsics, distortion, extrinsics), the format
``rgbd synth`` writes and ``rgbd fuse`` reads (``examples/calibration.json`` is the synthetic rig).

Layout (units: pixels and metres; cameras in OpenCV's frame: x right, y down, z forward)::

    {
      "stereo": {"left": CAM, "right": CAM, "baseline": 0.12},
      "tof": CAM,
      "tof_to_reference": {"rotation": [[1, 0, 0], [0, 1, 0], [0, 0, 1]],
                           "translation": [0.0, 0.04, 0.0]},
      "reference": "right"
    }

    CAM = {"fx": 727.27, "fy": 727.27, "cx": 479.5, "cy": 269.5, "width": 960, "height": 540,
           "distortion": [k1, k2, p1, p2, k3, k4, k5, k6]}

- ``stereo``: the *rectified* pair (equal size and fx); the right camera sits ``baseline``
  metres along +x of the left one, so disparity ``d = u_left - u_right = baseline * fx / z``.
- ``tof``: the ToF camera; its depth and amplitude maps are ``height x width``.
- ``tof_to_reference``: the pose taking points from the ToF camera's frame into the reference
  camera's frame (``p_ref = rotation @ p_tof + translation``).
- ``reference``: ``"right"`` (the thesis' output camera, the default when absent) or ``"left"``.
- ``distortion``: OpenCV order, 4, 5 or 8 coefficients; optional (no distortion).

Unknown keys are refused, naming them (a misspelt ``"refrence"`` would otherwise leave the
default in force without a word); keys starting with ``_`` are free for notes.
"""

from __future__ import annotations

import contextlib
from collections.abc import Iterator
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


def _rig_to_dict(rig: ToFStereoRig) -> dict[str, Any]:
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
    return write_json(path, _rig_to_dict(rig))


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


def _matrix(where: str, value: object, shape: tuple[int, ...]) -> np.ndarray:
    """A list of numbers (``(n,)``) or of rows of numbers (``(rows, n)``) of exactly ``shape``."""
    _numbers(where, value)
    rows = value if len(shape) == 2 else [value]
    want = f"{shape[0]} x {shape[1]} list of" if len(shape) == 2 else f"list of {shape[0]}"
    assert isinstance(rows, list)
    if len(rows) != (shape[0] if len(shape) == 2 else 1) or any(
        not isinstance(r, list) or len(r) != shape[-1] or any(isinstance(v, list) for v in r)
        for r in rows
    ):
        raise ValueError(f"{where} is {value!r}, expected a {want} numbers")
    return np.asarray(value, float)


#: The keys every camera object of the layout needs (``distortion`` is optional).
CAMERA_KEYS = ("fx", "fy", "cx", "cy", "width", "height")


class _MissingKey(Exception):
    """A key of the layout is absent (reported with the file's name by :func:`load_rig`)."""


def _require(
    where: str, obj: dict[str, Any], keys: tuple[str, ...], optional: tuple[str, ...] = ()
) -> None:
    """Every key of ``keys`` is present and no other than those and ``optional`` (keys that
    start with ``_`` are free for notes): a misspelt optional key (``"refrence"``) would
    otherwise be ignored and its default used without a word."""
    for key in keys:
        if key not in obj:
            raise _MissingKey(f"{where} has no key {key!r}")
    for key in obj:
        if key not in keys and key not in optional and not str(key).startswith("_"):
            raise _MissingKey(
                f"{where} has an unknown key {key!r}, expected only {list(keys + optional)} "
                "(keys starting with '_' are free for notes)"
            )


def _camera(where: str, value: object) -> PinholeCamera:
    c = _object(f"camera {where!r}", value)
    _require(f"camera {where!r}", c, CAMERA_KEYS, ("distortion",))
    try:
        return PinholeCamera(
            _number(f"{where}.fx", c["fx"]),
            _number(f"{where}.fy", c["fy"]),
            _number(f"{where}.cx", c["cx"]),
            _number(f"{where}.cy", c["cy"]),
            _integer(f"{where}.width", c["width"]),
            _integer(f"{where}.height", c["height"]),
            Distortion.from_opencv(_numbers(f"{where}.distortion", c.get("distortion", [0.0] * 5))),
        )
    except RgbdError as exc:  # the camera's own checks (fx > 0, ...) say which camera
        raise ValueError(f"camera {where!r}: {exc}") from None


def save_camera(path: str | Path, camera: PinholeCamera) -> Path:
    """Write one camera as JSON: the ``CAM`` object of the module docstring (the file
    ``rgbd segment --calib`` reads)."""
    if not isinstance(camera, PinholeCamera):
        raise InvalidArgumentError(
            f"camera: got {type(camera).__name__}, expected a rgbd_rs.PinholeCamera"
        )
    return write_json(path, _cam(camera))


def load_camera(path: str | Path) -> PinholeCamera:
    """Read one camera from JSON: a ``CAM`` object (module docstring) at the top level, e.g.
    ``{"fx": 518.86, "fy": 519.47, "cx": 324.58, "cy": 252.74, "width": 640, "height": 480}``
    (``examples/nyu_camera.json``, rounded). A rig file (``rgbd fuse --calib``) is read too: its
    reference stereo camera is returned."""
    d = read_json(path)
    with _reported(path):
        top = _object("the file", d)
        if "stereo" in top and "fx" not in top:
            rig = load_rig(path)
            return rig.stereo.right if rig.reference == "right" else rig.stereo.left
        foreign = not {"fx", "fy", "cx", "cy"} & set(top)
        if not foreign:
            return _camera("camera", top)
    raise RgbdError(
        f"{path}: got a JSON object with keys {sorted(top)[:8]}, expected a camera "
        '({"fx", "fy", "cx", "cy", "width", "height"}, e.g. examples/nyu_camera.json) '
        'or a `rgbd fuse` rig file ({"stereo", "tof", "tof_to_reference"})'
    )


def load_stereo_rig(path: str | Path) -> StereoRig:
    """The rectified stereo pair of a calibration JSON: its ``stereo`` section (``left``,
    ``right``, ``baseline``), from a whole rig file or from one with that section alone (no
    ToF camera needed, as for ``rgbd stereo --calib``). Errors name the file and the key."""
    d = read_json(path)
    with _reported(path):
        top = _object("the file", d)
        _require("the file", top, ("stereo",), ("tof", "tof_to_reference", "reference"))
        st = _object("stereo", top["stereo"])
        _require("'stereo'", st, ("left", "right", "baseline"))
        return _stereo_rig(st)


@contextlib.contextmanager
def _reported(path: str | Path) -> Iterator[None]:
    """A missing key or a bad value inside the block raises RgbdError naming ``path``."""
    try:
        yield
    except _MissingKey as exc:
        raise RgbdError(f"{path}: calibration: {exc}") from exc
    except (TypeError, ValueError, OverflowError) as exc:
        raise RgbdError(f"{path}: invalid calibration ({exc})") from exc


def _stereo_rig(st: dict[str, Any]) -> StereoRig:
    """The pair of a ``stereo`` section whose keys :func:`_require` checked."""
    return StereoRig(
        _camera("stereo.left", st["left"]),
        _camera("stereo.right", st["right"]),
        _number("stereo.baseline", st["baseline"]),
    )


def load_rig(path: str | Path) -> ToFStereoRig:
    """Read a calibration JSON (layout in the module docstring).

    Missing keys raise RgbdError naming the file and where the key is missing (``calibration:
    camera 'tof' has no key 'fx'``); bad values (strings where numbers belong included) name the
    file and the value's place.
    """
    d = read_json(path)
    if isinstance(d, dict) and "stereo" not in d and {"fx", "fy", "cx", "cy"} <= set(d):
        raise RgbdError(
            f"{path}: holds one camera, expected a ToF + stereo rig (stereo.left, "
            "stereo.right, baseline, tof, tof_to_reference): fusion needs a rectified "
            "stereo pair and a ToF camera; to reproject one depth camera onto another "
            "use rgbd_rs.reproject_depth (`rgbd reproject` for an Azure Kinect recording), "
            "to read one camera use load_camera"
        )
    with _reported(path):
        top = _object("the file", d)
        _require("the file", top, ("stereo", "tof", "tof_to_reference"), ("reference",))
        st = _object("stereo", top["stereo"])
        _require("'stereo'", st, ("left", "right", "baseline"))
        t = _object("tof_to_reference", top["tof_to_reference"])
        _require("'tof_to_reference'", t, ("rotation", "translation"))
        return ToFStereoRig(
            tof=_camera("tof", top["tof"]),
            stereo=_stereo_rig(st),
            tof_to_reference=Pose(
                _matrix("tof_to_reference.rotation", t["rotation"], (3, 3)),
                _matrix("tof_to_reference.translation", t["translation"], (3,)),
            ),
            reference=top.get("reference", "right"),
        )
