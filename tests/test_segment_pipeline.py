"""The segmentation pipeline end to end on a real NYUv2 frame, and `rgbd segment`."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from rgbd_rs.cli import main
from rgbd_rs.data import NYUV2_CAMERA, data_root, load_nyuv2_frame
from rgbd_rs.metrics import variation_of_information
from rgbd_rs.segmentation.pipeline import segment

pytestmark = pytest.mark.skipif(data_root() is None, reason="shared data not found")


@pytest.fixture(scope="module")
def frame():  # type: ignore[no-untyped-def]
    return load_nyuv2_frame(1)


@pytest.fixture(scope="module")
def result(frame):  # type: ignore[no-untyped-def]
    return segment(frame.rgb, frame.depth, NYUV2_CAMERA, n_segments=150, labeler=None)


def test_stages_and_shapes(frame, result) -> None:  # type: ignore[no-untyped-def]
    assert result.over.shape == result.labels.shape == frame.depth.shape
    assert list(result.seconds) == ["features", "oversegment", "fits", "merge"]
    n_over = np.unique(result.over[result.over >= 0]).size
    assert n_over >= 100
    assert 2 <= result.merge.n_segments < n_over, "the merging joins segments"
    assert result.merge.mode == "fit" and result.semantic is None
    # Final segments are unions of over-segments.
    pairs = np.unique(np.stack([result.over.ravel(), result.labels.ravel()]), axis=1)
    assert np.unique(pairs[0]).size == pairs.shape[1]
    np.testing.assert_array_equal(result.fits.labels(), result.labels)


def test_the_result_pickles_whole(result) -> None:  # type: ignore[no-untyped-def]
    """A process pool's worker hands a segment() result back: its fits too."""
    import pickle

    back = pickle.loads(pickle.dumps(result))
    assert back == result
    np.testing.assert_array_equal(back.fits.labels(), result.labels)
    live = np.unique(result.labels[result.labels >= 0])[:5]
    assert [back.fits.fit_error(i) for i in live] == [result.fits.fit_error(i) for i in live]


def test_merging_moves_toward_the_ground_truth(frame, result) -> None:  # type: ignore[no-untyped-def]
    from rgbd_rs.data import region_ground_truth

    gt = region_ground_truth(frame.label40)
    over = variation_of_information(result.over, gt)
    merged = variation_of_information(result.labels, gt)
    assert merged < over, (over, merged)


def test_deterministic(frame, result) -> None:  # type: ignore[no-untyped-def]
    again = segment(frame.rgb, frame.depth, NYUV2_CAMERA, n_segments=150, labeler=None)
    np.testing.assert_array_equal(again.labels, result.labels)


def test_depth_in_a_wrong_unit_warns(frame) -> None:  # type: ignore[no-untyped-def]
    """0.1 mm (or TUM's 1/5000 m) read as millimetres: ten (five) times too far, which the
    features accept, so segment() warns naming the unit."""
    with pytest.warns(RuntimeWarning, match=r"^depth: median .* check the depth unit"):
        segment(frame.rgb, frame.depth * 10, NYUV2_CAMERA, n_segments=20, labeler=None)
    from rgbd_rs.segmentation.pipeline import _depth_unit_warning

    assert _depth_unit_warning(NYUV2_CAMERA.depth_to_points(frame.depth)) is None
    # ... and 1000x too near (kilometres, or metres scaled twice) as well.
    too_near = _depth_unit_warning(NYUV2_CAMERA.depth_to_points(frame.depth / 1000))
    assert too_near is not None and too_near.startswith("depth: median 0.00")
    assert "below the ~0.05 m" in too_near


def test_cli_writes_labels_overlay_and_frames(tmp_path: Path) -> None:
    root = data_root()
    assert root is not None
    f = root / "nyuv2" / "frames"
    calib = Path(__file__).parents[1] / "examples" / "nyu_camera.json"
    out = tmp_path / "seg"
    argv = ["segment", "--rgb", str(f / "0001_rgb.png"), "--depth", str(f / "0001_depth.png")]
    argv += ["--calib", str(calib), "--out", str(out), "--segments", "60", "--frames", "10"]
    argv += ["--labeler", "none"]
    assert main([*argv, "--quiet"]) == 0
    labels = np.load(out / "labels.npy")
    assert labels.shape == (480, 640)
    for name in ("labels.png", "overlay.png", "segments.png", "over.npy", "merge/0000.png"):
        assert (out / name).exists(), name


def test_cli_errors_name_the_flag(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    import cv2

    root = data_root()
    assert root is not None
    f = root / "nyuv2" / "frames"
    calib = Path(__file__).parents[1] / "examples" / "nyu_camera.json"
    small = tmp_path / "small.png"
    cv2.imwrite(str(small), np.full((240, 320), 1500, np.uint16))
    d8 = tmp_path / "d8.png"
    cv2.imwrite(str(d8), np.full((480, 640), 150, np.uint8))
    foreign = tmp_path / "foreign.json"
    foreign.write_text('{"CalibrationInformation": {}}')
    base = {"--rgb": f / "0001_rgb.png", "--depth": f / "0001_depth.png", "--calib": calib}
    for change, needles in (
        ({"--depth": small}, ("--depth: ", "320x240 pixels", "--calib camera's 640x480")),
        ({"--depth": d8}, ("--depth: ", "8-bit PNG")),
        ({"--calib": foreign}, ("--calib: ", "CalibrationInformation", "expected a camera")),
    ):
        args = {**base, **change}
        argv = ["segment", *[x for k, v in args.items() for x in (k, str(v))]]
        assert main([*argv, "--out", str(tmp_path / "o"), "--labeler", "none"]) == 2
        err = capsys.readouterr().err.strip()
        assert err.startswith("rgbd: error: ") and len(err.splitlines()) == 1, err
        for n in needles:
            assert n in err, (n, err)


def test_cli_a_frame_too_small_for_the_labeler_names_the_inputs(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    import json

    import cv2

    cv2.imwrite(str(tmp_path / "rgb.png"), np.full((48, 64, 3), 90, np.uint8))
    np.save(tmp_path / "depth.npy", np.full((48, 64), 2.0, np.float32))
    cam = {"fx": 60.0, "fy": 60.0, "cx": 31.5, "cy": 23.5, "width": 64, "height": 48}
    (tmp_path / "cam.json").write_text(json.dumps(cam))
    argv = ["segment", "--rgb", str(tmp_path / "rgb.png"), "--depth", str(tmp_path / "depth.npy")]
    argv += ["--calib", str(tmp_path / "cam.json"), "--out", str(tmp_path / "o"), "--quiet"]
    assert main([*argv, "--segments", "10"]) == 2
    err = capsys.readouterr().err
    assert err.startswith("rgbd: error: --rgb: got a 64x48 frame, smaller than the "), err
    assert "--labeler none" in err
    # A grey image for --rgb, and a depth on its own (smaller) lattice, each named with a way out.
    cv2.imwrite(str(tmp_path / "grey.png"), np.full((48, 64), 90, np.uint8))
    grey = [*argv]
    grey[2] = str(tmp_path / "grey.png")
    assert main(grey) == 2
    err = capsys.readouterr().err
    assert err.startswith(f"rgbd: error: --rgb: {tmp_path / 'grey.png'}: got a grey image"), err
    import struct
    import zlib

    def chunk(kind: bytes, data: bytes) -> bytes:
        return (
            struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data))
        )

    rows = b"".join(b"\0" + bytes([90, 255]) * 64 for _ in range(48))  # grey 90, opaque
    la = chunk(b"IHDR", struct.pack(">IIBBBBB", 64, 48, 8, 4, 0, 0, 0))  # colour type 4
    (tmp_path / "la.png").write_bytes(
        b"\x89PNG\r\n\x1a\n" + la + chunk(b"IDAT", zlib.compress(rows)) + chunk(b"IEND", b"")
    )
    grey[2] = str(tmp_path / "la.png")
    assert main(grey) == 2  # OpenCV reads it as colour; its header says grey + alpha
    err = capsys.readouterr().err
    assert err.startswith(f"rgbd: error: --rgb: {tmp_path / 'la.png'}: got a grey image"), err
    cv2.imwrite(str(tmp_path / "deep.png"), np.full((48, 64, 3), 900, np.uint16))
    grey[2] = str(tmp_path / "deep.png")
    assert main(grey) == 2
    err = capsys.readouterr().err
    assert err.startswith(f"rgbd: error: --rgb: {tmp_path / 'deep.png'}: got a 16-bit image"), err
    np.save(tmp_path / "small.npy", np.full((24, 32), 2.0, np.float32))
    small = [*argv]
    small[4] = str(tmp_path / "small.npy")
    assert main(small) == 2
    err = capsys.readouterr().err
    assert "got 32x24 pixels, expected the --calib camera's 64x48 (depth on its own" in err, err


def _tiny_labeler():  # type: ignore[no-untyped-def]
    import torch

    from rgbd_rs.data.nyuv2 import LABEL13_NAMES
    from rgbd_rs.nn.semantic import SemanticNet
    from rgbd_rs.segmentation.labeling import SemanticLabeler

    torch.manual_seed(0)
    return SemanticLabeler(SemanticNet(14, width=8, lcn_window=5), (80, 60), LABEL13_NAMES)


@pytest.fixture(scope="module")
def labeled(frame):  # type: ignore[no-untyped-def]
    return segment(frame.rgb, frame.depth, NYUV2_CAMERA, n_segments=150, labeler=_tiny_labeler())


def test_convnet_drives_the_merging_and_labels_segments(frame, labeled) -> None:  # type: ignore[no-untyped-def]
    assert list(labeled.seconds) == ["features", "oversegment", "fits", "semantic", "merge"]
    assert labeled.merge.mode == "similarity"
    pdfs = labeled.pdfs
    assert pdfs is not None and pdfs.shape == (480, 640, 14)
    np.testing.assert_allclose(pdfs.sum(axis=-1), 1, atol=1e-4)
    net = labeled.network_labels
    assert net is not None and net.min() >= 1, "never the unlabeled class"
    sem = labeled.semantic
    assert sem is not None
    # Each final segment has one class: the argmax of its pixels' mean PDF (§4.7, mean pooling).
    assert labeled.pooling == "mean"
    for s in np.unique(labeled.labels[labeled.labels >= 0])[:20]:
        inside = labeled.labels == s
        assert np.unique(sem[inside]).size == 1
        assert sem[inside][0] == pdfs[inside].astype(np.float64).sum(axis=0).argmax()


def test_labeler_none_is_fit_only_and_bad_labelers(frame) -> None:  # type: ignore[no-untyped-def]
    from rgbd_rs.errors import InvalidArgumentError, RgbdError

    with pytest.raises(InvalidArgumentError, match=r"^labeler: got 3"):
        segment(frame.rgb, frame.depth, NYUV2_CAMERA, labeler=3)  # type: ignore[arg-type]
    with pytest.raises(RgbdError, match="no such checkpoint"):
        segment(frame.rgb, frame.depth, NYUV2_CAMERA, labeler="/nonexistent/semantic.pt")


def test_cli_with_a_checkpoint_writes_classes(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    from rgbd_rs.nn.checkpoint import Checkpoint, save_checkpoint
    from rgbd_rs.nn.semantic import ARCH

    lab = _tiny_labeler()
    ckpt = tmp_path / "semantic.pt"
    norm = {"input_size": [80, 60], "classes": list(lab.classes), "ignore_index": 0}
    state = lab.net.state_dict()
    save_checkpoint(Checkpoint(ckpt, ARCH, lab.net.arch_config(), norm, state), ckpt)
    root = data_root()
    assert root is not None
    f = root / "nyuv2" / "frames"
    calib = Path(__file__).parents[1] / "examples" / "nyu_camera.json"
    out = tmp_path / "seg"
    argv = ["segment", "--rgb", str(f / "0001_rgb.png"), "--depth", str(f / "0001_depth.png")]
    argv += ["--calib", str(calib), "--out", str(out), "--segments", "60", "--labeler", str(ckpt)]
    assert main([*argv, "--quiet"]) == 0
    for name in ("semantic.npy", "semantic.png", "network.png", "overlay.png", "classes.json"):
        assert (out / name).exists(), name
    # Issue 30: the class pictures carry a legend; classes.json maps id -> name -> colour.
    classes = json.loads((out / "classes.json").read_text())
    assert [c["id"] for c in classes] == [*range(len(classes) - 1), -1]
    assert classes[1]["name"] == "bed" and len(classes[1]["rgb"]) == 3
    # The pictures' "no data" grey is named too; segments.png shows it with a legend.
    from rgbd_rs.viz import NO_DATA_RGB

    assert classes[-1] == {"id": -1, "name": "no data", "rgb": list(NO_DATA_RGB)}
    from rgbd_rs.io import read_png

    for name in ("semantic.png", "network.png", "segments.png"):
        pic = read_png(out / name)
        assert pic.shape[1] == 640 and pic.shape[0] > 480 + 40, (name, pic.shape)  # + legend
    assert main([*argv[:-2], "--labeler", str(tmp_path / "nope.pt"), "--quiet"]) == 2
    # A file that is no checkpoint fails before the features are computed, naming the flag.
    (tmp_path / "text.pt").write_text("not a checkpoint")
    capsys.readouterr()
    assert main([*argv[:-2], "--labeler", str(tmp_path / "text.pt"), "--quiet"]) == 2
    assert capsys.readouterr().err.startswith("rgbd: error: --labeler: ")
    # --pdfs replaces the ConvNet: a --labeler beside it is refused, not silently ignored.
    np.save(tmp_path / "pdfs.npy", np.full((480, 640, 14), 1 / 14, np.float32))
    assert main([*argv, "--pdfs", str(tmp_path / "pdfs.npy"), "--quiet"]) == 2
    assert "--labeler: got " in capsys.readouterr().err


def test_cli_warns_on_a_wrong_depth_unit_naming_the_flag(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """The shared HHA frame's raw depth is in 0.1 mm: read as millimetres it is ten times too
    far, which the CLI reports as one warning line naming --depth (and --depth-scale fixes)."""
    import warnings

    root = data_root()
    assert root is not None
    raw = root / "hha" / "depth_raw.png"
    calib = Path(__file__).parents[1] / "examples" / "nyu_camera.json"
    argv = [
        "segment",
        "--rgb",
        str(root / "nyuv2" / "frames" / "0001_rgb.png"),
        "--depth",
        str(raw),
    ]
    argv += ["--calib", str(calib), "--labeler", "none", "--segments", "20", "--quiet"]
    with warnings.catch_warnings():
        warnings.simplefilter("always")
        assert main([*argv, "--out", str(tmp_path / "a")]) == 0
        lines = capsys.readouterr().err.strip().splitlines()
        assert len(lines) == 1 and lines[0].startswith("rgbd: warning: --depth: median 3"), lines
        # It names the value that fixes it (this file's unit is 0.1 mm).
        assert lines[0].endswith("; --depth-scale 0.0001 brings it to 3.04 m"), lines
        assert main([*argv, "--out", str(tmp_path / "b"), "--depth-scale", "0.0001"]) == 0
        assert capsys.readouterr().err == ""
        # Read as metres (a scale of 1) the depth is refused outright, naming the fix too.
        assert main([*argv, "--out", str(tmp_path / "c"), "--depth-scale", "1"]) == 2
        err = capsys.readouterr().err.strip()
        assert err.startswith("rgbd: error: --depth: got a median valid depth of"), err
        assert err.endswith("; --depth-scale 0.0001 brings it to 3.04 m"), err
        # The library's "divide by" (for an array) gives way to the flag that was given.
        assert "m (read with --depth-scale 1)," in err and "divide by" not in err, err


@pytest.mark.parametrize(
    ("median_m", "scale", "fix"),
    [
        (31.0, 1e-3, 1e-4),  # 0.1 mm counts read as millimetres
        (12.5, 1e-3, 2e-4),  # TUM's 1/5000 m counts read as millimetres, a far scene
        (0.025, 1e-3, 1e-1 * 1e-1),  # centimetres read as millimetres
        (2.0, 1e-3, None),  # plausible already
        (1e6, 1e-3, None),  # no common unit makes it plausible
        (float("nan"), 1e-3, None),
    ],
)
def test_suggested_depth_scale(median_m: float, scale: float, fix: float | None) -> None:
    from rgbd_rs.segmentation.pipeline import _suggested_depth_scale

    got = _suggested_depth_scale(median_m, scale)
    assert got == fix if fix is None else got == pytest.approx(fix)


@pytest.mark.parametrize(
    ("rows", "cols"), [(slice(0, 480), slice(300, 307)), (slice(200, 208), slice(300, 308))]
)
def test_cli_segments_a_frame_narrower_than_a_panel(
    rows: slice, cols: slice, tmp_path: Path
) -> None:
    """A 7-px-wide strip and an 8x8 crop: the pictures are drawn at a panel's least width and
    no internal window radius reaches the user (both used to fail after or before the work)."""
    import json

    import cv2

    root = data_root()
    assert root is not None
    f = root / "nyuv2" / "frames"
    rgb = cv2.imread(str(f / "0046_rgb.png"))[rows, cols]
    depth = cv2.imread(str(f / "0046_depth.png"), cv2.IMREAD_UNCHANGED)[rows, cols]
    cv2.imwrite(str(tmp_path / "rgb.png"), rgb)
    cv2.imwrite(str(tmp_path / "d.png"), depth)
    cam = json.loads((Path(__file__).parents[1] / "examples" / "nyu_camera.json").read_text())
    cam |= {"cx": cam["cx"] - cols.start, "cy": cam["cy"] - rows.start}
    cam |= {"width": cols.stop - cols.start, "height": rows.stop - rows.start}
    (tmp_path / "cam.json").write_text(json.dumps(cam))
    argv = ["segment", "--rgb", str(tmp_path / "rgb.png"), "--depth", str(tmp_path / "d.png")]
    argv += ["--calib", str(tmp_path / "cam.json"), "--out", str(tmp_path / "seg")]
    assert main([*argv, "--labeler", "none", "--segments", "4", "--quiet"]) == 0
    labels = np.load(tmp_path / "seg" / "labels.npy")
    assert labels.shape == depth.shape and (labels >= 0).any()
    assert cv2.imread(str(tmp_path / "seg" / "segments.png")).shape[1] >= 16
