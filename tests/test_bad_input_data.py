"""Bad input to :mod:`rgbd_rs.data`, :mod:`rgbd_rs.io`, :mod:`rgbd_rs.viz` and
:mod:`rgbd_rs.metrics` (see tests/test_bad_input.py for the contract and the meta-test).

A file whose *content* is bad raises :class:`~rgbd_rs.RgbdError` itself, naming the file; a bad
argument (a path of the wrong type, an unknown mode) raises InvalidArgumentError naming it."""

from __future__ import annotations

import json
import tempfile
import warnings
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from bad_input import Case, check, params
from rgbd_rs import InvalidArgumentError, RgbdError, ShapeMismatchError
from rgbd_rs.data import (
    AzureKinectFrame,
    Synth3Dataset,
    SynthDataset,
    data_root,
    load_azure_kinect_calibration,
    load_azure_kinect_frame,
    load_camera,
    load_middlebury,
    load_rig,
    load_stereo_rig,
    reproject_to_color,
    save_camera,
    save_rig,
    synth3_rig,
    write_dataset,
)
from rgbd_rs.data.calibration import _rig_to_dict
from rgbd_rs.io import (
    read_json,
    read_npy,
    read_npz,
    read_png,
    sha256,
    write_json,
    write_npz,
    write_png,
)
from rgbd_rs.metrics import bad_pixel_rate, depth_edges, edge_alignment, edge_band, rms_error
from rgbd_rs.viz import as_bgr, colorize, outline_segments, paint_segments, save_png, tile

SHAPE = ShapeMismatchError
ARG = InvalidArgumentError
FILE = RgbdError

_TMP = tempfile.TemporaryDirectory(prefix="rgbd_bad_input_")
TMP = Path(_TMP.name)
D = np.ones((6, 8), np.float32)
U8 = np.zeros((6, 8, 3), np.uint8)


def _file(name: str, data: bytes | str) -> Path:
    p = TMP / name
    p.parent.mkdir(parents=True, exist_ok=True)
    if isinstance(data, str):
        p.write_text(data)
    else:
        p.write_bytes(data)
    return p


def _pickled(name: str) -> Path:
    """An .npz or .npy holding an object array (numpy pickles it)."""
    p = TMP / name
    p.parent.mkdir(parents=True, exist_ok=True)
    objects = np.array([{"depth": 1}], dtype=object)
    if name.endswith(".npz"):
        np.savez(p, depth=objects)
    else:
        np.save(p, objects)
    return p


def _kinect_calibration(tmp: Path, **override: object) -> Path:
    """A minimal Azure Kinect calibration JSON; ``override`` replaces D0 intrinsics fields."""
    params = [0.5, 0.5, 0.5, 0.5, *([0.0] * 10)]
    d0 = {
        "Location": "CALIBRATION_CameraLocationD0",
        "Intrinsics": {"ModelParameters": params},
        "MetricRadius": 1.7,
    }
    pv0 = {
        "Location": "CALIBRATION_CameraLocationPV0",
        "Intrinsics": {"ModelParameters": params},
        "SensorWidth": 4096,
        "SensorHeight": 3072,
        "Rt": {"Rotation": [1, 0, 0, 0, 1, 0, 0, 0, 1], "Translation": [0.03, 0, 0]},
    }
    d0["Intrinsics"] = {**d0["Intrinsics"], **override}
    doc = {"CalibrationInformation": {"Cameras": [d0, pv0]}}
    return _file(tmp.name + "/kinect.json", json.dumps(doc))


def _kinect_strings() -> object:
    path = _kinect_calibration(TMP / "strings", ModelParameters=["0.5"] * 14)
    return load_azure_kinect_calibration(path)


def _rig_with_strings() -> object:
    doc = _rig_to_dict(synth3_rig(0.125))
    doc["tof"]["fx"] = "365.9"
    return load_rig(_file("rig_strings.json", json.dumps(doc)))


def _rig_edited(name: str, edit: Callable[[dict[str, Any]], object]) -> Callable[[], object]:
    def call() -> object:
        doc = _rig_to_dict(synth3_rig(0.125))
        edit(doc)
        return load_rig(_file(name, json.dumps(doc)))

    return call


_STEREO = _rig_to_dict(synth3_rig(0.125))["stereo"]


def _frame_npz(name: str, depth_mm: np.ndarray, ir: object = True) -> Path:
    arrays = {"depth_mm": depth_mm, "color": np.zeros((*depth_mm.shape, 3), np.uint8)}
    if ir is not None:
        arrays["ir"] = np.ones(depth_mm.shape, np.uint16)
    path = TMP / name
    np.savez(path, **arrays)
    return path


def _middlebury_16bit() -> object:
    """The 2003 layout (disparity = PNG / 4) with 16-bit ground truth: refused, not divided."""
    folder = TMP / "mb16"
    write_png(folder / "im2.png", np.zeros((10, 40, 3), np.uint8))
    write_png(folder / "im6.png", np.zeros((10, 40, 3), np.uint8))
    write_png(folder / "disp2.png", np.full((10, 40), 256 * 20, np.uint16))
    write_png(folder / "disp6.png", np.full((10, 40), 256 * 20, np.uint16))
    return load_middlebury(folder)


def _synth3_string_variable() -> object:
    from scipy.io import savemat

    from rgbd_rs.data.synth3 import LAYOUT

    root = TMP / "synth3"
    for kind, (folder, suffix, var) in LAYOUT.items():
        value: object = np.ones((4, 6))
        if kind == "amplitude":
            value = "not a map"
        p = root / "train" / folder / f"scene_0000_{suffix}"
        p.parent.mkdir(parents=True, exist_ok=True)
        savemat(p, {var: value})
    return Synth3Dataset(root, "train")[0]


def _synth3_bad_kind() -> object:
    from scipy.io import savemat

    from rgbd_rs.data.synth3 import LAYOUT

    root = TMP / "synth3_ok"
    for folder, suffix, var in LAYOUT.values():
        p = root / "test" / folder / f"test_scene_0000_{suffix}"
        p.parent.mkdir(parents=True, exist_ok=True)
        savemat(p, {var: np.ones((4, 6))})
    return Synth3Dataset(root, "test").path(0, "depth")


def _manifest_list() -> object:
    root = TMP / "manifest_list"
    _file("manifest_list/manifest.json", "[]")
    save_rig(root / "calibration.json", synth3_rig(0.125))
    return SynthDataset(root)


CASES: list[Case] = [
    # -- data -----------------------------------------------------------------------------------
    Case("data_root", lambda: data_root(required="yes"), ARG, r"^required: got 'yes'"),
    Case(
        "load_azure_kinect_calibration",
        _kinect_strings,
        ARG,
        r"^path: .*strings/kinect\.json.*ModelParameters",
        "strings",
    ),
    Case(
        "load_azure_kinect_calibration",
        lambda: load_azure_kinect_calibration(
            _kinect_calibration(TMP / "nan", ModelParameters=[float("nan")] * 14)
        ),
        ARG,
        r"^path: .*nan/kinect\.json \(NaN is not a JSON number\)",
        "NaN",
    ),
    Case(
        "load_azure_kinect_calibration",
        lambda: load_azure_kinect_calibration(TMP / "none.json", depth_mode="HFOV"),
        ARG,
        r"^depth_mode: got 'HFOV'",
        "mode",
    ),
    Case(
        "load_azure_kinect_calibration",
        lambda: load_azure_kinect_calibration(TMP / "none.json", color_resolution=["720P"]),
        ARG,
        r"^color_resolution: got \['720P'\]",
        "unhashable mode",
    ),
    Case(
        "load_azure_kinect_frame",
        lambda: load_azure_kinect_frame(_file("frame.npz", b"")),
        ARG,
        r"^path: .*frame\.npz",
    ),
    Case(
        "load_azure_kinect_frame",
        lambda: load_azure_kinect_frame(_frame_npz("metres.npz", np.full((4, 4), 1.5, np.float32))),
        ARG,
        r"^path: .*metres\.npz holds depth_mm as float32, expected integer millimetres",
        "float depth",
    ),
    Case(
        "load_azure_kinect_frame",
        lambda: load_azure_kinect_frame(_frame_npz("neg.npz", -np.ones((4, 4), np.int16))),
        ARG,
        r"^path: .*neg\.npz holds 16 negative depth_mm values \(down to -1\), expected millimetres",
        "negative depth",
    ),
    Case(
        "load_azure_kinect_frame",
        lambda: load_azure_kinect_frame(
            _frame_npz("no_ir.npz", np.ones((4, 4), np.uint16), ir=None)
        ),
        ARG,
        r"^path: could not read .*no_ir\.npz: missing arrays \['ir'\]",
        "missing array",
    ),
    Case(
        "load_azure_kinect_frame",
        lambda: load_azure_kinect_frame(None),
        ARG,
        r"^path: got None",
        "None",
    ),
    Case(
        "AzureKinectFrame",
        lambda: reproject_to_color(
            AzureKinectFrame(D[:3], D, U8),
            load_azure_kinect_calibration(_kinect_calibration(TMP / "ok")),
        ),
        SHAPE,
        r"^amplitude: got shape \(6, 8\), expected \(3, 8\)",
    ),
    Case(
        "reproject_to_color",
        lambda: reproject_to_color(AzureKinectFrame(D, D, U8), "calibration"),
        ARG,
        r"^calibration: got str",
    ),
    Case("load_middlebury", _middlebury_16bit, FILE, r"disp2\.png: got a uint16 disparity PNG"),
    Case("load_middlebury", lambda: load_middlebury(TMP), FILE, r"Middlebury", "not a scene"),
    Case("load_middlebury", lambda: load_middlebury(7), ARG, r"^folder: got 7", "int"),
    Case("load_rig", _rig_with_strings, FILE, r"rig_strings\.json.*tof\.fx is '365\.9'"),
    Case(
        "load_rig",
        lambda: load_rig(_file("rig_list.json", "[1, 2]")),
        FILE,
        r"rig_list\.json.*JSON object",
        "list",
    ),
    Case(
        "load_rig",
        _rig_edited("rig_typo.json", lambda d: d.update(refrence="left")),
        FILE,
        r"rig_typo\.json.*unknown key 'refrence'",
        "typo",
    ),
    Case(
        "load_rig",
        _rig_edited("rig_rot.json", lambda d: d["tof_to_reference"]["rotation"].__setitem__(0, 5)),
        FILE,
        r"rig_rot\.json.*tof_to_reference\.rotation is \[5, \[0\.0, 1\.0, 0\.0\], .*\], "
        r"expected a 3 x 3 list of numbers",
        "ragged rotation",
    ),
    Case(
        "load_rig",
        _rig_edited("rig_t2.json", lambda d: d["tof_to_reference"]["translation"].pop()),
        FILE,
        r"rig_t2\.json.*tof_to_reference\.translation is \[0\.0, 0\.04\], expected a list of 3",
        "short translation",
    ),
    Case(
        "load_rig",
        _rig_edited("rig_cam_typo.json", lambda d: d["tof"].update(distorsion=[0.1, 0, 0, 0])),
        FILE,
        r"camera 'tof' has an unknown key 'distorsion'",
        "camera typo",
    ),
    Case(
        "load_rig",
        _rig_edited("rig_fx.json", lambda d: d["stereo"]["left"].update(fx=-1.0)),
        FILE,
        r"rig_fx\.json.*camera 'stereo\.left': fx: got -1",
        "which camera",
    ),
    Case(
        "load_rig",
        lambda: load_rig(
            _file(
                "one_cam.json",
                '{"fx": 500, "fy": 500, "cx": 32, "cy": 24, "width": 64, "height": 48}',
            )
        ),
        FILE,
        r"one_cam\.json: holds one camera, expected a ToF \+ stereo rig .*`rgbd reproject`",
        "one camera",
    ),
    Case(
        "load_stereo_rig",
        lambda: load_stereo_rig(_file("st_none.json", '{"tof": {}}')),
        FILE,
        r"st_none\.json: calibration: the file has no key 'stereo'",
        "no stereo",
    ),
    Case(
        "load_stereo_rig",
        lambda: load_stereo_rig(
            _file("st_base.json", json.dumps({"stereo": {**_STEREO, "baseline": "0.1"}}))
        ),
        FILE,
        r"st_base\.json: .*baseline",
        "baseline string",
    ),
    Case(
        "load_stereo_rig",
        lambda: load_stereo_rig(
            _file("st_key.json", json.dumps({"stereo": _STEREO, "tof_pose": 1}))
        ),
        FILE,
        r"st_key\.json: calibration: the file has an unknown key 'tof_pose'",
        "typo",
    ),
    Case("save_rig", lambda: save_rig(TMP / "r.json", "rig"), ARG, r"^rig: got str"),
    Case("synth3_rig", lambda: synth3_rig(1000.0), ARG, r"^scale: got 1000"),
    Case("synth3_rig", lambda: synth3_rig(1e-6), ARG, r"^scale: got 1e-06", "tiny"),
    Case(
        "write_dataset",
        lambda: write_dataset(TMP / "ds", scale=1000.0),
        ARG,
        r"^scale: got 1000",
    ),
    Case("write_dataset", lambda: write_dataset(TMP / "ds", train=-1), ARG, r"^train", "train"),
    Case(
        "write_dataset",
        lambda: write_dataset(_file("plain_file", "x")),
        ARG,
        r"^out: got .*plain_file, a file",
        "out is a file",
    ),
    Case("write_dataset", lambda: write_dataset(TMP / "ds", seed=2**40), ARG, r"^seed", "seed"),
    Case("SynthDataset", lambda: SynthDataset(TMP, "val"), ARG, r"^split: got 'val'"),
    Case("SynthDataset", _manifest_list, FILE, r"manifest\.json: not an rgbd_rs", "manifest []"),
    Case("Synth3Dataset", lambda: Synth3Dataset(TMP, "val"), ARG, r"^split: got 'val'"),
    Case(
        "Synth3Dataset",
        _synth3_string_variable,
        FILE,
        r"amplitude_reprojected.*amplitude_120_rp holds <U",
        ".mat string variable",
    ),
    Case("Synth3Dataset.path", _synth3_bad_kind, ARG, r"^kind: got 'depth'"),
    # -- io -------------------------------------------------------------------------------------
    Case("write_npz", lambda: write_npz(TMP / "a.npz", [D]), ARG, r"^arrays: got list"),
    Case(
        "write_npz",
        lambda: write_npz(TMP / "a.npz", {"a": np.array([object()])}),
        ARG,
        r"^arrays\['a'\]: got dtype object",
        "object",
    ),
    Case("read_npz", lambda: read_npz(TMP / "missing.npz"), FILE, r"missing\.npz: file not found"),
    Case(
        "read_npz",
        lambda: read_npz(_file("trunc.npz", b"PK\x03\x04 truncated")),
        FILE,
        r"trunc\.npz: not a readable npz archive \(it is not a zip archive",
        "truncated",
    ),
    Case(
        "read_npz",
        lambda: read_npz(_pickled("pickled.npz")),
        FILE,
        r"pickled\.npz: not a readable npz archive \(it holds Python objects, not plain numeric",
        "pickled",
    ),
    Case(
        "read_npz",
        lambda: read_npz(_file("text.npz", b"depth,amplitude\n1,2\n")),
        FILE,
        r"text\.npz: not a readable npz archive \(not a zip archive\)$",
        "text",
    ),
    Case("read_npz", lambda: read_npz(TMP / "x.npz", "a"), ARG, r"^keys: got 'a'", "keys"),
    Case("read_npy", lambda: read_npy(_file("empty.npy", b"")), FILE, r"empty\.npy: empty file"),
    Case(
        "read_npy",
        lambda: read_npy(_file("trunc.npy", b"\x93NUMPY\x01\x00v\x00{'descr'")),
        FILE,
        r"trunc\.npy: not a readable \.npy array \(it ends inside an array header: truncated",
        "truncated",
    ),
    Case(
        "read_npy",
        lambda: read_npy(_pickled("pickled.npy")),
        FILE,
        r"pickled\.npy: not a readable \.npy array \(it holds Python objects",
        "pickled",
    ),
    Case(
        "read_npy",
        lambda: read_npy(_file("text.npy", b"1 2 3\n")),
        FILE,
        r"text\.npy: not a readable \.npy array \(no \.npy header\)$",
        "text",
    ),
    Case("read_npy", lambda: read_npy(42), ARG, r"^path: got 42", "int"),
    Case("write_png", lambda: write_png(TMP / "f.png", D), ARG, r"^image: got dtype float32"),
    Case(
        "write_png",
        lambda: write_png(TMP / "f.png", np.zeros((2, 2, 2), np.uint8)),
        SHAPE,
        r"^image: got shape \(2, 2, 2\)",
        "2 channels",
    ),
    Case(
        "write_png",
        lambda: write_png(TMP / "r.png", [[1, 2], [3]]),
        ARG,
        r"^image: got list",
        "ragged",
    ),
    Case(
        "write_png", lambda: write_png(TMP / "r.png", U8, rgb="yes"), ARG, r"^rgb: got 'yes'", "rgb"
    ),
    Case("read_png", lambda: read_png(_file("bad.png", b"\x89PNG")), FILE, r"bad\.png: corrupt"),
    Case("write_json", lambda: write_json(TMP / "o.json", object()), ARG, r"^obj: got"),
    Case("write_json", lambda: write_json(TMP, {}), FILE, r"is a folder, expected a file", "dir"),
    Case(
        "write_png",
        lambda: write_png(_file("plain", "x") / "sub" / "o.png", U8),
        FILE,
        r"o\.png: could not be written \(.*plain is a file, expected a folder to write in\)$",
        "file as folder",
    ),
    Case("read_json", lambda: read_json(_file("bad.json", "{")), FILE, r"bad\.json: malformed"),
    Case(
        "write_json",
        lambda: write_json(TMP / ("a" * 300 + ".json"), {}),
        ARG,
        r"^path: got a name of 305 bytes \('a{20}'\.\.\.\), expected names of at most 255 bytes",
        "long name",
    ),
    Case(
        "read_png",
        lambda: read_png(TMP / "d" / ("b" * 256 + ".png")),
        ARG,
        r"^path: got a name of 260 bytes",
        "long name",
    ),
    Case("sha256", lambda: sha256(TMP / "nothing"), FILE, r"nothing: file not found"),
    # -- viz ------------------------------------------------------------------------------------
    Case(
        "load_camera",
        lambda: load_camera(_file("cam_missing.json", '{"fx": 500, "fy": 500, "cx": 1}')),
        FILE,
        r"cam_missing\.json.*has no key 'cy'",
    ),
    Case(
        "load_camera",
        lambda: load_camera(
            _file("cam_str.json", '{"fx": "5", "fy": 5, "cx": 1, "cy": 1, "width": 4, "height": 4}')
        ),
        FILE,
        r"cam_str\.json.*fx",
        "string",
    ),
    Case(
        "load_camera",
        lambda: load_camera(
            _file(
                "cam_skew.json",
                '{"fx": 5, "fy": 5, "cx": 1, "cy": 1, "width": 4, "height": 4, "skew": 0.1}',
            )
        ),
        FILE,
        r"cam_skew\.json.*unknown key 'skew'",
        "unknown key",
    ),
    Case("save_camera", lambda: save_camera(TMP / "c.json", "cam"), ARG, r"^camera: got str"),
    Case("colorize", lambda: colorize(np.zeros((2, 2, 2))), SHAPE, r"^values: got shape"),
    Case("colorize", lambda: colorize(D, vmin="lo"), ARG, r"^vmin: got 'lo'", "vmin"),
    Case("colorize", lambda: colorize(D, colormap=99), ARG, r"^colormap: got 99", "colormap"),
    Case("as_bgr", lambda: as_bgr(np.float32(0)), ARG, r"^image: got dtype float32"),
    Case("as_bgr", lambda: as_bgr(np.uint8(0)), SHAPE, r"^image: got shape \(\)", "0-d"),
    Case("as_bgr", lambda: as_bgr([[1, 2], [3]]), ARG, r"^image: got list", "ragged"),
    Case("tile", lambda: tile([], []), ARG, r"^images: got list"),
    Case("tile", lambda: tile([U8], ["a", "b"]), ARG, r"^labels: got", "labels"),
    Case("tile", lambda: tile([D], ["a"]), ARG, r"^images\[0\]: got dtype float32", "float"),
    Case("tile", lambda: tile([U8], ["a"], width=0), ARG, r"^width: got 0", "width"),
    Case(
        "outline_segments",
        lambda: outline_segments(U8, np.zeros((2, 2), np.int32)),
        SHAPE,
        r"^labels: got shape",
    ),
    Case(
        "outline_segments",
        lambda: outline_segments(U8, np.zeros(U8.shape[:2], np.float32)),
        ARG,
        r"^labels: got dtype float32",
        "dtype",
    ),
    Case(
        "outline_segments",
        lambda: outline_segments(U8, np.zeros(U8.shape[:2], np.int32), color=(0, 0, 300)),
        ARG,
        r"^color: got",
        "color",
    ),
    Case("paint_segments", lambda: paint_segments(np.zeros(3, np.int32)), SHAPE, r"^labels"),
    Case(
        "paint_segments",
        lambda: paint_segments(np.zeros((2, 2), np.int32), boundaries=1),  # type: ignore[arg-type]
        ARG,
        r"^boundaries: got 1",
        "flag",
    ),
    Case("save_png", lambda: save_png(TMP / "v.png", D), ARG, r"^image: got dtype float32"),
    Case("save_png", lambda: save_png(3.5, U8), ARG, r"^path: got 3.5", "path"),
    # -- metrics --------------------------------------------------------------------------------
    Case("depth_edges", lambda: depth_edges(np.ones(3)), SHAPE, r"^depth: got shape \(3,\)"),
    Case("depth_edges", lambda: depth_edges(D, rel_step=0.0), ARG, r"^rel_step: got 0", "step"),
    Case(
        "edge_alignment",
        lambda: edge_alignment(D, U8[:5]),
        SHAPE,
        r"^image: got shape \(5, 8, 3\)",
    ),
    Case(
        "edge_alignment",
        lambda: edge_alignment(D, U8, max_distance="far"),
        ARG,
        r"^max_distance: got 'far'",
        "distance",
    ),
    Case("rms_error", lambda: rms_error(D, D[:3]), SHAPE, r"^truth: got shape \(3, 8\)"),
    Case(
        "rms_error",
        lambda: rms_error(D, np.full_like(D, np.nan)),
        ARG,
        r"^estimate: got no pixel where it and truth are both finite",
        "nothing to compare",
    ),
    Case(
        "rms_error",
        lambda: rms_error(D, D, np.zeros(D.shape, bool)),
        ARG,
        r"^mask: got no pixel",
        "empty mask",
    ),
    Case(
        "rms_error",
        lambda: rms_error(D, D, mask=np.ones((6, 8))),
        ARG,
        r"^mask: got dtype float64",
        "float mask",
    ),
    Case(
        "rms_error", lambda: rms_error(D, D, mask=[[1, 2], [3]]), ARG, r"^mask: got list", "ragged"
    ),
    Case("bad_pixel_rate", lambda: bad_pixel_rate(D, D, -1.0), ARG, r"^threshold: got -1"),
    Case(
        "bad_pixel_rate",
        lambda: bad_pixel_rate(D, D[:3], 1.0),
        SHAPE,
        r"^truth: got shape \(3, 8\)",
        "shape",
    ),
    Case(
        "bad_pixel_rate",
        lambda: bad_pixel_rate(D, D, 1.0, mask=np.ones((6, 8))),
        SHAPE,
        r"^mask: got float64",
        "float mask",
    ),
    Case("edge_band", lambda: edge_band(D, width=-1), ARG, r"^width: got -1"),
    Case("edge_band", lambda: edge_band(np.ones(3)), SHAPE, r"^depth: got shape \(3,\)", "1-D"),
]


@pytest.mark.parametrize("case", params(CASES))
def test_bad_input(case: Case) -> None:
    check(case)


def test_metric_limits_beyond_float32_give_the_limiting_answer_without_warnings() -> None:
    """A threshold, edge step or distance beyond float32's range is a limit, not an overflow."""
    truth = np.ones((6, 8), np.float32)
    truth[:, 4:] = 2.0  # one vertical depth edge
    est = truth + np.float32(0.5)
    image = np.zeros((6, 8, 3), np.uint8)
    image[:, 4:] = 200
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # numpy's overflow warnings would raise here
        assert bad_pixel_rate(est, truth, 1e300) == 0.0
        assert bad_pixel_rate(est, truth, 0.25) == 1.0
        far = np.full((2, 2), 3e38, np.float32)
        assert bad_pixel_rate(far, -far, 1e300) == 0.0  # 6e38 apart: no float32 overflow
        assert bad_pixel_rate(far, -far, 1e38) == 1.0
        assert not depth_edges(truth, 1e300).any()
        assert depth_edges(truth, 0.5).any()
        assert not edge_band(truth, 2, 1e300).any()
        assert edge_alignment(truth, image, 1e300) == 1.0
        # Finite values beyond float32 are errors to count, not missing pixels.
        assert bad_pixel_rate(np.array([[1e39, 1.0]]), np.array([[0.0, 1.0]]), 1) == 0.5
    # Holes stored as 0, negative or infinite make no edge, as NaN does.
    for hole in (0.0, -1.0, np.inf, np.nan):
        assert not depth_edges(np.array([[1.0, hole, 1.0]], np.float32)).any(), hole
