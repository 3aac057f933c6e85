"""A fifth fuzz of the public surface (special files, fork, names in messages): each case below
replaced a device file, hung, raised a foreign exception, returned a wrong mesh or named the
wrong argument before its fix; each must now raise the RgbdError subclass named, in our words,
or give the right result."""

from __future__ import annotations

import os
import stat
from pathlib import Path

import numpy as np
import pytest

from bad_input import Case, check, params
from forked import NEEDS_FORK, in_forked_child
from rgbd_rs import PinholeCamera, RgbdError
from rgbd_rs.errors import InvalidArgumentError, ShapeMismatchError

ARG, FILE, SHAPE = InvalidArgumentError, RgbdError, ShapeMismatchError
CAM = PinholeCamera(fx=40.0, fy=40.0, cx=15.5, cy=11.5, width=32, height=24)
IMG = np.zeros((24, 32, 3), np.uint8)


def _fifo(tmp: Path) -> Path:
    path = tmp / "pipe"
    os.mkfifo(path)
    return path


def _fusion(name: str) -> object:
    import importlib

    return getattr(importlib.import_module("rgbd_rs.fusion"), name)


def _fuse_subnormal_tof() -> object:
    from rgbd_rs.data.synth import synth3_rig

    rig = synth3_rig(0.0625)
    h, w = rig.stereo.left.height, rig.stereo.left.width
    th, tw = rig.tof.height, rig.tof.width
    img = np.zeros((h, w, 3), np.uint8)
    tof = np.full((th, tw), 1e-40, np.float32)
    return _fusion("fuse")(img, img, tof, np.ones((th, tw), np.float32), rig)


def _fit_grid(lam: float) -> object:
    from rgbd_rs.surface import fit_grid

    v, u = np.mgrid[0:24, 0:32].astype(np.float32) / 100
    return fit_grid(np.stack([u, v, 1 + u * u], axis=-1), spacing=8, lam=lam)


def _segment_fits_j() -> object:
    from rgbd_rs.surface import SegmentFits

    v, u = np.mgrid[0:24, 0:32].astype(np.float32) / 100
    labels = (np.arange(32)[None, :] >= 16).astype(np.int32).repeat(24, axis=0)
    return SegmentFits(np.stack([u, v, 1 + u * u], axis=-1), labels).should_merge(0, 10**6)


def _mesh(name: str) -> object:
    import importlib

    return getattr(importlib.import_module("rgbd_rs.meshes"), name)


def _labeler_small() -> object:
    from rgbd_rs.segmentation import SemanticLabeler

    depth = np.full((24, 32), 2.0, np.float32)
    return SemanticLabeler.load().labels(IMG, depth, CAM)


def _checkpoint_arch(tmp: Path) -> object:
    from rgbd_rs.nn import load_checkpoint
    from rgbd_rs.nn.confidence import WEIGHTS

    return load_checkpoint(WEIGHTS, arch=np.zeros((2, 2)))  # type: ignore[arg-type]


def _classify_both() -> object:
    from rgbd_rs.shapes import classify

    pts = np.random.default_rng(0).normal(size=(64, 3)).astype(np.float32)
    return classify(pts, checkpoint="x.pt", dataset="modelnet10")


def _views_background() -> object:
    from rgbd_rs.shapes import depth_views

    return depth_views(_mesh("sphere")(1.0), 32, background=1e308)


def _texture() -> object:
    from rgbd_rs.render import Texture

    return Texture("bogus")  # type: ignore[arg-type]


def _kinect(tmp: Path) -> object:
    from rgbd_rs.data import load_azure_kinect_frame

    path = tmp / "x.npy"
    np.save(path, np.zeros(3))
    return load_azure_kinect_frame(path)


def _write(name: str) -> object:
    import importlib

    return getattr(importlib.import_module("rgbd_rs.io"), name)


CASES = [
    Case(
        "default_channel_weights",
        lambda: __import__(
            "rgbd_rs.segmentation", fromlist=["default_channel_weights"]
        ).default_channel_weights(2**31 - 1),
        ARG,
        r"^n_channels: got 2147483647, expected an integer >= 1 and <= 1024",
    ),
    Case("fuse", _fuse_subnormal_tof, ARG, r"^tof_depth: got depths down to 1e-40 m"),
    Case(
        "lc_refine",
        lambda: _fusion("lc_refine")(np.full((24, 32), 3e38, np.float32), IMG, IMG),
        ARG,
        r"^disparity: got \d+ value\(s\) as large as 3e\+38 px",
    ),
    Case(
        "sgm",
        lambda: _fusion("sgm")(IMG, IMG, max_disparity=8, min_disparity=2**31 - 1),
        ARG,
        r"^min_disparity: got 2147483647, expected an integer >= 0 and <= 30",
    ),
    Case("fit_grid", lambda: _fit_grid(1e30), ARG, r"^lam: got 1e\+30, expected a smoothing"),
    Case(
        "fit_mask",
        lambda: __import__("rgbd_rs.surface", fromlist=["fit_mask"]).fit_mask(
            np.full((24, 32, 3), np.nan, np.float32), None
        ),
        ARG,
        r"^points: got no valid pixel \(none with three finite coordinates",
    ),
    Case("SegmentFits.should_merge", _segment_fits_j, ARG, r"^j: got 1000000"),
    Case("sphere", lambda: _mesh("sphere")(1e-308), ARG, r"^radius: got 1e-308, expected a length"),
    Case("cylinder", lambda: _mesh("cylinder")(1.0, 1e308), ARG, r"^height: got 1e\+308"),
    Case("box", lambda: _mesh("box")((1.0, 1.0, 1e-35)), ARG, r"^size\[2\]: got 1e-35"),
    Case(
        "Mesh.normalized",
        lambda: _mesh("sphere")(1.0).normalized(1e308),
        ARG,
        r"^size: got 1e\+308, expected a length",
    ),
    Case("concat", lambda: _mesh("concat")([]), ARG, r"^meshes: got an empty list"),
    Case(
        "Mesh.transformed",
        lambda: _mesh("box")((1, 1, 1)).transformed(np.diag([-1.0, 1.0, 1.0])),
        ARG,
        r"^rotation: got a matrix .* det = -1\.0000, expected a rotation",
        "mirror",
    ),
    Case(
        "Mesh.transformed",
        lambda: _mesh("box")((1, 1, 1)).transformed(np.zeros((3, 3))),
        ARG,
        r"^rotation: got a matrix",
        "singular",
    ),
    Case("Texture", _texture, ARG, r"^kind: got 'bogus'"),
    Case("depth_views", _views_background, ARG, r"^background: got 1e\+308"),
    Case("SemanticLabeler.labels", _labeler_small, SHAPE, r"^rgb: got a 32x24 frame, smaller"),
    Case("classify", _classify_both, ARG, r"^checkpoint: got 'x\.pt' together with dataset"),
    Case(
        "depth_to_disparity",
        lambda: __import__("rgbd_rs").depth_to_disparity([[1, 2], [3]], 0.1, 40.0),
        ARG,
        r"^depth: got list with rows of different lengths \(ragged\).* expected a rectangular",
    ),
    Case(
        "PinholeCamera",
        lambda: PinholeCamera(fx=40.0, fy=40.0, cx=1e308, cy=11.5, width=32, height=24),
        ARG,
        r"^cx: got 1e\+308 px, expected a principal point",
    ),
    Case(
        "Distortion",
        lambda: __import__("rgbd_rs").Distortion(k1=1e30),
        ARG,
        r"^distortion\.k1: got 1e\+30, expected a coefficient",
    ),
]


@pytest.mark.parametrize("case", params(CASES))
def test_case(case: Case) -> None:
    check(case)


@pytest.mark.parametrize(
    "call",
    [_checkpoint_arch, _kinect],
    ids=["load_checkpoint arch", "load_azure_kinect_frame npy"],
)
def test_file_cases(call: object, tmp_path: Path) -> None:
    with pytest.raises(InvalidArgumentError) as info:
        call(tmp_path)  # type: ignore[operator]
    msg = str(info.value)
    assert msg.startswith(("arch: got ndarray", "path: could not read")), msg
    assert "context manager" not in msg and "truth value" not in msg


@pytest.mark.parametrize(
    "writer, arg",
    [
        ("write_text", "x"),
        ("write_json", {"a": 1}),
        ("write_npz", {"a": np.zeros(2)}),
        ("write_png", np.zeros((2, 2), np.uint8)),
    ],
)
def test_writers_refuse_special_files_and_leave_them_alone(
    writer: str, arg: object, tmp_path: Path
) -> None:
    # The atomic rename used to replace whatever was there: as root, /dev/null became a
    # regular file. A FIFO stands in for the device here.
    fifo = _fifo(tmp_path)
    with pytest.raises(RgbdError, match=r"pipe: is a pipe, expected a regular file path"):
        _write(writer)(fifo, arg)
    assert stat.S_ISFIFO(fifo.stat().st_mode)


@pytest.mark.parametrize("reader", ["read_json", "read_npy", "read_npz", "read_png", "sha256"])
def test_readers_refuse_special_files(reader: str, tmp_path: Path) -> None:
    with pytest.raises(RgbdError, match=r"pipe: is a pipe, expected a regular file"):
        _write(reader)(_fifo(tmp_path))  # a FIFO read would block forever


def _points_in_child(threads: str | None) -> tuple[object, int, int | None]:
    # Read at the child's first native call, when its own pool is built.
    os.environ.pop("RAYON_NUM_THREADS", None)
    if threads is not None:
        os.environ["RAYON_NUM_THREADS"] = threads
    depth = np.ones((240, 320), np.float32)
    cam = PinholeCamera(fx=300.0, fy=300.0, cx=160.0, cy=120.0, width=320, height=240)
    sgm = _fusion("sgm")
    img = np.random.default_rng(0).integers(0, 255, (60, 80, 3), dtype=np.uint8)
    from rgbd_rs import _rgbd_rs

    tasks = Path("/proc/self/task")
    before = len(list(tasks.iterdir())) if tasks.is_dir() else None
    shapes = (cam.depth_to_points(depth).shape, sgm(img, img, max_disparity=8).shape)
    # The threads the child's own pool started (None where /proc is missing).
    started = None if before is None else len(list(tasks.iterdir())) - before
    return shapes, _rgbd_rs.num_threads(), started


@NEEDS_FORK
@pytest.mark.parametrize("threads", [None, "2"])
def test_native_calls_work_in_a_forked_child(threads: str | None) -> None:
    # rayon's pool is the parent's: a forked child (DataLoader workers, multiprocessing's
    # default on Linux) inherited its bookkeeping without its threads and hung forever.
    depth = np.ones((240, 320), np.float32)
    cam = PinholeCamera(fx=300.0, fy=300.0, cx=160.0, cy=120.0, width=320, height=240)
    cam.depth_to_points(depth)  # the parent's pool now exists
    shapes, said, started = in_forked_child(_points_in_child, threads, timeout=60)
    assert shapes == ((240, 320, 3), (60, 80))
    # One of N workers: one thread, as torch's DataLoader workers get, unless asked otherwise.
    cores = len(os.sched_getaffinity(0))
    expected = 1 if threads is None else min(int(threads), cores)
    assert said == expected
    if started is not None:
        assert started == expected


@pytest.mark.parametrize(
    "text, said",
    [
        (
            "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 9\n",
            "a face refers to a vertex the file does not hold",
        ),
    ],
)
def test_mesh_files_are_refused_in_our_words(text: str, said: str, tmp_path: Path) -> None:
    from rgbd_rs.shapes import load_shape

    path = tmp_path / "bad.obj"
    path.write_text(text)
    with pytest.raises(RgbdError, match=f"bad.obj: .*{said}"):
        load_shape(path)


@pytest.mark.parametrize("value", ["-inf", "-1e-3", "-nan"])
def test_a_negative_number_is_a_flag_value_not_a_flag(
    value: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    # argparse took "-inf" for an option and said "expected one argument"; now the value
    # reaches the flag's own check, which names what it expects.
    from rgbd_rs.cli import main

    argv = ["stereo", "--left", "a.png", "--right", "b.png", "--max-disparity", "8"]
    with pytest.raises(SystemExit):
        main([*argv, "--min-depth", value, "--out", str(tmp_path / "o")])
    err = capsys.readouterr().err
    assert f"argument --min-depth: got {value}" in err and "expected a number" in err
