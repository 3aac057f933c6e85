"""Issue 32's reproducers (reliability round 3), one case each: every one ended in a foreign
exception, a MemoryError after allocating, a misleading message or a silently wrong result
before its fix; each must now raise the RgbdError subclass named, in our words."""

from __future__ import annotations

import struct
import zlib
from pathlib import Path

import numpy as np
import pytest
import torch

from bad_input import Case, check, isolated, params, public_cases
from rgbd_rs import PinholeCamera, RgbdError
from rgbd_rs.errors import InvalidArgumentError, ShapeMismatchError

ARG, SHAPE, FILE = InvalidArgumentError, ShapeMismatchError, RgbdError
CAM = PinholeCamera(fx=50.0, fy=50.0, cx=32.0, cy=24.0, width=64, height=48)


def _lc_stride() -> object:
    from rgbd_rs.fusion.lc import LcParams

    return LcParams(stride=2**64).native(64, 1)


def _depth_views_background() -> object:
    from rgbd_rs.shapes.views import depth_views

    return depth_views(np.random.default_rng(0).random((50, 3)), 16, background=2**1100)


def _confusion(matrix: object) -> object:
    from rgbd_rs.shapes.evaluate import ShapeEvaluation

    return ShapeEvaluation(("a", "b"), matrix, ("views",), "c", "d", "test")  # type: ignore[arg-type]


def _scene_rng(seed: object) -> object:
    from rgbd_rs.data.synth import _scene_rng

    return _scene_rng(seed, "train", 0)  # type: ignore[arg-type]


def _rig_poses() -> object:
    from rgbd_rs.data.synth import _rig_poses

    return _rig_poses(None)  # type: ignore[arg-type]


def _crosscheck() -> object:
    from rgbd_rs.fusion.crosscheck import _consistent

    return _consistent(np.ones((4, 4), np.float32), np.ones((3, 3), np.float32), 1)


def _grouped_conv() -> object:
    from rgbd_rs.nn.semantic import _GroupedConv

    return _GroupedConv(-4, 4, 3, 2)


def _target_confidence() -> object:
    from rgbd_rs.fusion.clues import _target_confidence

    return _target_confidence(np.ones((4, 4, 1)), np.ones((4, 4)), 1.0)


def _load_checkpoint_none() -> object:
    from rgbd_rs.nn.checkpoint import load_checkpoint

    return load_checkpoint(None)  # type: ignore[arg-type]


def _indoor_width_0() -> object:
    from rgbd_rs.data.synth_indoor_scene import _random_indoor_scene

    return _random_indoor_scene(np.random.default_rng(0), 0, 48)


def _train_batch() -> object:
    from rgbd_rs.nn.train import TrainConfig

    return TrainConfig(batch_size=2**63)


def _png_header(tmp: Path, width: int, height: int) -> Path:
    def chunk(kind: bytes, data: bytes) -> bytes:
        crc = zlib.crc32(kind + data) & 0xFFFFFFFF
        return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", crc)

    ihdr = struct.pack(">IIBBBBB", width, height, 8, 0, 0, 0, 0)
    data = b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", ihdr)
    data += chunk(b"IDAT", zlib.compress(b"\0" * 10)) + chunk(b"IEND", b"")
    path = tmp / f"claims_{width}x{height}.png"
    path.write_bytes(data)
    return path


def _read_png_huge(tmp: Path) -> object:
    from rgbd_rs.io import read_png

    return read_png(_png_header(tmp, 200_000, 200_000))


def _pcd(tmp: Path, header_points: int, rows: int, binary: bool) -> Path:
    head = (
        "VERSION .7\nFIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nCOUNT 1 1 1\n"
        f"WIDTH {header_points}\nHEIGHT 1\nPOINTS {header_points}\n"
        f"DATA {'binary' if binary else 'ascii'}\n"
    )
    pts = np.arange(rows * 3, dtype=np.float32).reshape(rows, 3)
    body = pts.tobytes() if binary else "".join(f"{a} {b} {c}\n" for a, b, c in pts).encode()
    path = tmp / f"cloud_{'bin' if binary else 'txt'}.pcd"
    path.write_bytes(head.encode() + body)
    return path


def _load_pcd(tmp: Path, binary: bool) -> object:
    from rgbd_rs.shapes.dataset import load_shape

    return load_shape(_pcd(tmp, 5, 1, binary))


def _pack(tmp: Path, label: object, split: object) -> Path:
    path = tmp / "pack.npz"
    np.savez(
        path,
        points=np.zeros((2, 4, 3), np.float32),
        label=np.asarray(label),
        split=np.asarray(split),
        classes=np.array(["a", "b"]),
        name=np.array(["s0", "s1"]),
    )
    return path


def _point_pack(tmp: Path, label: object, split: object) -> object:
    from rgbd_rs.shapes.dataset import PointCloudSet

    return PointCloudSet(_pack(tmp, label, split))


ALL_CASES = [
    Case("LcParams", _lc_stride, ARG, r"^stride: got 18446744073709551616, expected an integer"),
    Case(
        "oversegment",
        lambda: __import__("rgbd_rs.segmentation", fromlist=["oversegment"]).oversegment(
            np.zeros((8, 8, 9), np.float32), 4, n_samples=2**64
        ),
        ARG,
        r"^n_samples: got 18446744073709551616",
        "n_samples 2**64",
    ),
    Case("depth_views", _depth_views_background, ARG, r"^background: got inf, expected a finite"),
    Case(
        "ShapeEvaluation",
        lambda: _confusion(np.array([[np.inf, 1], [0, 1]])),
        ARG,
        r"^confusion: got values that are not counts",
        "inf",
    ),
    Case(
        "ShapeEvaluation",
        lambda: _confusion(np.ones((3, 3), np.int64)),
        SHAPE,
        r"^confusion: got shape \(3, 3\), expected \(2, 2\)",
        "shape",
    ),
    Case("_scene_rng", lambda: _scene_rng(1.5), ARG, r"^seed: got 1\.5, expected an integer"),
    Case(
        "_scene_rng", lambda: _scene_rng(-1), ARG, r"^seed: got -1, expected an integer >= 0", "-1"
    ),
    Case("_rig_poses", _rig_poses, ARG, r"^rig: got NoneType, expected a rgbd_rs\.ToFStereoRig"),
    Case("_consistent", _crosscheck, SHAPE, r"^target: got shape \(3, 3\), expected \(4, 4\)"),
    Case("_GroupedConv", _grouped_conv, ARG, r"^in_channels: got -4, expected an integer >= 1"),
    Case("_target_confidence", _target_confidence, SHAPE, r"^gt: got shape \(4, 4\), expected"),
    Case("load_checkpoint", _load_checkpoint_none, ARG, r"^path: got None, expected a checkpoint"),
    Case("_random_indoor_scene", _indoor_width_0, ARG, r"^width: got 0, expected an integer >= 1"),
    Case("TrainConfig", _train_batch, ARG, r"^batch_size: got 9223372036854775808"),
    Case(
        "PinholeCamera.cropped",
        lambda: CAM.cropped(2**31, 0, 4, 4),
        ARG,
        r"^x0: got 2147483648, expected an integer >= 0 and <= 63$",
    ),
    Case(
        "default_channel_weights",
        lambda: __import__(
            "rgbd_rs.segmentation.oversegment", fromlist=["x"]
        ).default_channel_weights(2**31),
        ARG,
        r"^n_channels: got 2147483648",
    ),
    Case(
        "depth_to_disparity",
        isolated(
            """
            from rgbd_rs.geometry import depth_to_disparity
            view = np.lib.stride_tricks.as_strided(np.ones(1, np.float32), (2**17, 2**17), (0, 0))
            depth_to_disparity(view, 0.1, 500.0)
            """
        ),
        SHAPE,
        r"^depth: got 17179869184 elements \(shape \(131072, 131072\)\), expected at most",
        "zero-stride view",
    ),
]


#: What the meta-test counts: the cases of names the package exports (the rest still run).
CASES: list[Case] = public_cases(ALL_CASES)


@pytest.mark.parametrize("case", params(ALL_CASES))
def test_bad_input(case: Case) -> None:
    check(case)


def test_file_cases(tmp_path: Path) -> None:
    """Loaders check a file's declared sizes and counts against what it holds."""
    check(Case("read_png", lambda: _read_png_huge(tmp_path), FILE, r"header says 200000x200000"))
    for binary in (False, True):
        check(
            Case(
                "load_shape",
                lambda b=binary: _load_pcd(tmp_path, b),  # type: ignore[misc]
                FILE,
                r"the header says 5 points, found 1: truncated\?",
            )
        )
    check(
        Case(
            "PointCloudSet",
            lambda: _point_pack(tmp_path, [0.0, 1.7], [0, 1]),
            FILE,
            r"labels of dtype float64 .* expected one integer per shape",
        )
    )
    check(
        Case(
            "PointCloudSet",
            lambda: _point_pack(tmp_path, [0, 1], [0, 7]),
            FILE,
            r"split codes \[7\], expected \[0, 1\] \(train, test\)",
        )
    )
    check(
        Case(
            "PointCloudSet",
            lambda: _point_pack(tmp_path, [0, 99], [0, 1]),
            FILE,
            r"labels in \[0, 99\], expected 0\.\.1 \(2 classes\)",
        )
    )


def test_a_huge_min_size_is_one_segment_not_an_overflow() -> None:
    from rgbd_rs.segmentation.evaluate import felzenszwalb_rgb

    rgb = np.random.default_rng(0).integers(0, 255, (16, 16, 3)).astype(np.uint8)
    labels = felzenszwalb_rgb(scale=1.0, min_size=1e300)(rgb, np.ones((16, 16), np.float32), CAM)
    assert np.unique(labels).size == 1


def test_inf_depth_is_missing_for_the_rgbd_baselines() -> None:
    """An inf depth is missing data (as NaN is), not a value that flattens every other depth."""
    from rgbd_rs.segmentation.evaluate import slic_rgbd

    rng = np.random.default_rng(0)
    rgb = rng.integers(0, 255, (32, 32, 3)).astype(np.uint8)
    depth = np.where(np.arange(32)[None, :] < 16, 1.0, 3.0).astype(np.float32) * np.ones((32, 1))
    depth = depth.astype(np.float32)
    run = slic_rgbd(n_segments=8, depth_weight=50.0)
    with_nan, with_inf = depth.copy(), depth.copy()
    with_nan[0, 0], with_inf[0, 0] = np.nan, np.inf
    np.testing.assert_array_equal(run(rgb, with_inf, CAM), run(rgb, with_nan, CAM))


def test_inf_cues_are_missing_not_nan_pdfs() -> None:
    from rgbd_rs.nn.semantic import SemanticNet
    from rgbd_rs.segmentation.labeling import SemanticLabeler

    torch.manual_seed(0)
    net = SemanticNet(width=8).eval()
    labeler = SemanticLabeler(net, (16, 12), tuple(f"c{i}" for i in range(net.n_classes)))
    cues = np.random.default_rng(0).random((9, 12, 16)).astype(np.float32)
    with_inf, with_zero = cues.copy(), cues.copy()
    with_inf[:, :3, :3], with_zero[:, :3, :3] = np.inf, 0.0
    got = labeler.pdfs_of_cues(with_inf)
    assert np.isfinite(got).all()
    np.testing.assert_allclose(got, labeler.pdfs_of_cues(with_zero), atol=1e-6)


def test_a_checkpoint_of_nan_weights_is_refused(tmp_path: Path) -> None:
    from rgbd_rs.nn.checkpoint import load_checkpoint, save_checkpoint
    from rgbd_rs.shapes.classify import shipped_weights

    ckpt = load_checkpoint(shipped_weights()["modelnet10"])
    key = next(k for k, v in ckpt.model_state.items() if v.is_floating_point())
    ckpt.model_state[key] = torch.full_like(ckpt.model_state[key], float("nan"))
    path = save_checkpoint(ckpt, tmp_path / "nan.pt")
    with pytest.raises(RgbdError, match=r"nan\.pt: the weights .* hold NaN or inf"):
        load_checkpoint(path)


def test_a_frame_folder_checks_every_image_against_the_camera(tmp_path: Path) -> None:
    from rgbd_rs.io import write_png
    from rgbd_rs.segmentation.semantic_data import FrameFolder

    write_png(tmp_path / "a_rgb.png", np.zeros((48, 64, 3), np.uint8))
    write_png(tmp_path / "a_depth.png", np.full((48, 64), 1000, np.uint16), rgb=False)
    write_png(tmp_path / "a_label13.png", np.ones((5, 5), np.uint8), rgb=False)
    with pytest.raises(RgbdError, match=r"a_label13\.png: got 5x5 pixels, expected the camera's"):
        FrameFolder(tmp_path, CAM)[0]


def test_a_cache_size_beyond_the_frames_is_refused_before_the_cache_exists(
    tmp_path: Path,
) -> None:
    from rgbd_rs.segmentation.semantic_data import LabeledFrame, build_semantic_cache

    frame = LabeledFrame(
        "f0",
        np.zeros((48, 64, 3), np.uint8),
        np.ones((48, 64), np.float32),
        np.ones((48, 64), np.uint8),
        CAM,
    )
    with pytest.raises(ShapeMismatchError, match=r"^size: got 640x480, larger than frame f0"):
        build_semantic_cache([frame], tmp_path / "cache", size=(640, 480), quiet=True)
    assert not (tmp_path / "cache").exists()


# -- the fresh fuzz of the public surface (issue 32): one case per class of finding -----------


def _fuzz_cases(tmp: Path) -> list[Case]:
    import rgbd_rs.fusion as fusion
    import rgbd_rs.nn as rnn
    import rgbd_rs.segmentation as seg
    import rgbd_rs.shapes as shapes
    from rgbd_rs import data, io, render, surface, viz
    from rgbd_rs.shapes.classify import shipped_weights

    grey = np.zeros((8, 8, 3), np.uint8)
    disp = np.ones((8, 8), np.float32)
    a_file = tmp / "a_file.bin"
    a_file.write_bytes(b"x")
    flags = np.array([True, False])
    return [
        Case(
            "segment",
            lambda: seg.segment(grey, disp, CAM.scaled(0.125), touching=flags),
            ARG,
            r"^touching: got an array of shape \(2,\), expected True or False",
            "array flag",
        ),
        Case(
            "write_json",
            lambda: io.write_json(str(tmp / "a\0b.json"), {}),
            ARG,
            r"^path: got .*NUL character",
            "NUL",
        ),
        Case(
            "build_cache",
            lambda: shapes.build_cache(shapes.open_shapes("modelnet10"), a_file, quiet=True),
            ARG,
            r"^out: got .*a_file\.bin, a file; expected a folder",
            "out is a file",
        ),
        Case(
            "lc_fuse",
            lambda: fusion.lc_fuse(grey, grey, [disp], target_sign=1.0),  # type: ignore[arg-type]
            ARG,
            r"^target_sign: got 1\.0, expected \+1 or -1",
            "float sign",
        ),
        Case(
            "PinholeCamera.scaled",
            lambda: CAM.scaled(1e308),
            ARG,
            r"^sx: got 1e\+308, which makes the image",
            "huge",
        ),
        Case("synth3_rig", lambda: data.synth3_rig(1e308), ARG, r"^scale: got 1e\+308", "huge"),
        Case(
            "tof_confidence",
            lambda: fusion.tof_confidence(disp, disp, read_noise=1e308),
            ARG,
            r"^read_noise: got 1e\+308, expected at most 1e\+100",
            "huge noise",
        ),
        Case(
            "class_legend",
            lambda: viz.class_legend(["a"], [(1, 2, 300)], 100),
            ARG,
            r"^colors\[0\]: got \(1, 2, 300\), expected three integers 0\.\.255",
            "colour range",
        ),
        Case(
            "class_picture",
            lambda: viz.class_picture(np.zeros((4, 4), int), None, [(1, 2, 3)], "t"),  # type: ignore[arg-type]
            ARG,
            r"^names: got NoneType, expected a list of str",
            "names None",
        ),
        Case(
            "ConfidenceEstimator",
            lambda: rnn.ConfidenceEstimator(None, [1, 1, 1, 1]),  # type: ignore[arg-type]
            ARG,
            r"^net: got NoneType, expected a ConfidenceNet",
            "net None",
        ),
        Case(
            "ConfidenceNet.forward",
            lambda: rnn.ConfidenceNet(4)(torch.zeros((1, 4, 16, 16), dtype=torch.int64)),
            ARG,
            r"^x: got dtype torch\.int64, expected torch\.float32",
            "int tensor",
        ),
        Case(
            "class_probabilities",
            lambda: rnn.class_probabilities(torch.zeros((1, 4, 2, 2), dtype=torch.int64)),
            ARG,
            r"^logits: got dtype torch\.int64, expected floating point",
            "int logits",
        ),
        Case(
            "TrainConfig.from_dict",
            lambda: rnn.TrainConfig.from_dict(None),  # type: ignore[arg-type]
            ARG,
            r"^config: got NoneType, expected a dict",
            "None",
        ),
        Case(
            "InputSpec.from_dict",
            lambda: shapes.InputSpec.from_dict({"representations": None}),
            ARG,
            r"^spec: representations None, expected a list",
            "None value",
        ),
        Case(
            "load_checkpoint",
            lambda: rnn.load_checkpoint(a_file, normalisation_keys=None),  # type: ignore[arg-type]
            ARG,
            r"^normalisation_keys: got None, expected a collection",
            "keys None",
        ),
        Case(
            "save_checkpoint",
            lambda: rnn.save_checkpoint(
                rnn.load_checkpoint(shipped_weights()["modelnet10"]),
                tmp,
            ),
            ARG,
            r"^path: got .*, a folder; expected a checkpoint file path",
            "a folder",
        ),
        Case(
            "fit_mask",
            lambda: surface.fit_mask(np.zeros((4, 4, 3), np.float32), [[True], [True, False]]),
            ARG,
            r"^mask: got list with rows of different lengths",
            "ragged",
        ),
        Case(
            "Texture.image",
            lambda: render.Texture.image([[1, 2], [3]], 1.0),
            ARG,
            r"^rgb: got list with rows of different lengths",
            "ragged",
        ),
        Case(
            "class_frequencies",
            lambda: data.synth_indoor.class_frequencies(None),  # type: ignore[arg-type]
            ARG,
            r"^labels: got NoneType, expected an iterable of label images",
            "None",
        ),
    ]


def test_fresh_fuzz_classes(tmp_path: Path) -> None:
    for case in _fuzz_cases(tmp_path):
        check(case)


def _fuzz_cases_2(tmp: Path) -> list[Case]:
    """The helper's second pass: records checked when made, subclasses of arrays, float32."""
    import rgbd_rs.fusion as fusion
    from rgbd_rs import metrics, render
    from rgbd_rs.data import AzureKinectFrame
    from rgbd_rs.meshes import box
    from rgbd_rs.shapes.evaluate import ShapeEvaluation

    eye = np.eye(2, dtype=np.int64)
    depth = np.ones((8, 8), np.float32)
    return [
        Case(
            "Scene",
            lambda: render.Scene(lights=None).add(box((1, 1, 1))).build(),  # type: ignore[arg-type]
            ARG,
            r"^lights: got NoneType, expected a list",
            "lights None",
        ),
        Case(
            "Texture",
            lambda: render.Texture("image", (0.5,), 0, "x"),  # type: ignore[arg-type]
            ARG,
            r"^image_rgb: got str for texture 'image'",
            "image not an array",
        ),
        Case(
            "OrthographicCamera",
            lambda: render.OrthographicCamera(10.0, 16, 12, cx="x"),  # type: ignore[arg-type]
            ARG,
            r"^cx: got 'x', expected a real number",
            "cx str",
        ),
        Case(
            "ShapeEvaluation",
            lambda: ShapeEvaluation(("a", "b"), eye, None, "c.pt", "pack", "test"),  # type: ignore[arg-type]
            ARG,
            r"^representations: got None, expected a tuple of names",
            "representations None",
        ),
        Case(
            "ShapeEvaluation",
            lambda: ShapeEvaluation(("a", "b"), eye, ("depth",), "c", "d", "test", turns="yes"),  # type: ignore[arg-type]
            ARG,
            r"^turns: got 'yes', expected True or False",
            "turns str",
        ),
        Case(
            "ShapeEvaluation.write",
            lambda: ShapeEvaluation(("a", "b"), eye, ("depth",), "c", "d", "test").write(
                tmp, "../../escaped"
            ),
            ARG,
            r"^stem: got '\.\./\.\./escaped', expected a plain file name",
            "stem escapes",
        ),
        Case(
            "rms_error",
            lambda: metrics.rms_error(np.ma.masked_array(depth), depth),
            ARG,
            r"got a masked array, expected a plain numpy array",
            "masked",
        ),
        Case(
            "AzureKinectFrame",
            lambda: AzureKinectFrame("x", None, 5),  # type: ignore[arg-type]
            ARG,
            r"^depth: got dtype <U1, expected a real numeric array",
            "strings",
        ),
        Case(
            "LcParams",
            lambda: fusion.LcParams(cross_check="no"),  # type: ignore[arg-type]
            ARG,
            r"^cross_check: got 'no', expected True or False",
            "cross_check str",
        ),
        Case(
            "ToFModel",
            lambda: render.ToFModel(noise="no"),  # type: ignore[arg-type]
            ARG,
            r"^noise: got 'no', expected True or False",
            "noise str",
        ),
        Case(
            "upsample_depth",
            lambda: fusion.upsample_depth(
                depth, np.zeros((8, 8, 3), np.uint8), sigma_spatial=1e-300
            ),
            ARG,
            r"^sigma_spatial: got 1e-300, expected a magnitude within float32's range",
            "sigma flushes to 0",
        ),
        Case(
            "Distortion.from_opencv",
            isolated(
                """
                from rgbd_rs import Distortion
                Distortion.from_opencv(np.broadcast_to(0.0, (2**32,)))
                """
            ),
            SHAPE,
            r"^coeffs: got 4294967296 elements",
            "a 2**32 view",
        ),
    ]


def test_fresh_fuzz_classes_second_pass(tmp_path: Path) -> None:
    for case in _fuzz_cases_2(tmp_path):
        check(case)
    from rgbd_rs.metrics import pixel_accuracy
    from rgbd_rs.shapes import build_cache

    labels = np.zeros((4, 4), int)
    with pytest.raises(InvalidArgumentError, match=r"^ignore: got 18446744073709551616"):
        pixel_accuracy(labels, labels, ignore=2**64)  # matched nothing: read as accuracy 0.0
    with pytest.raises(InvalidArgumentError, match=r"^source: got NoneType"):
        build_cache(None, tmp_path / "cache")  # type: ignore[arg-type]
    # np.matrix is read as the array it holds (it broke metrics' norms).
    from rgbd_rs import metrics

    with pytest.warns(PendingDeprecationWarning):
        a = np.asmatrix(np.ones((3, 4)))
    assert metrics.rms_error(a, np.zeros((3, 4))) == pytest.approx(1.0)
    # A numpy scalar becomes a Python number, so save_camera's JSON can hold it.
    from rgbd_rs.data import load_camera, save_camera

    cam = PinholeCamera(np.float32(20.0), 20.0, 3.5, 2.5, 8, 6)  # type: ignore[arg-type]
    assert type(cam.fx) is float
    assert load_camera(save_camera(tmp_path / "cam.json", cam)) == cam


def test_fresh_fuzz_classes_third_batch(tmp_path: Path) -> None:
    """Checkpoint fields checked before writing; map_location and init named; extreme cues."""
    import dataclasses

    from rgbd_rs.nn import load_checkpoint, save_checkpoint
    from rgbd_rs.nn.semantic import SemanticNet
    from rgbd_rs.segmentation.labeling import SemanticLabeler
    from rgbd_rs.shapes.classify import shipped_weights

    good = load_checkpoint(shipped_weights()["modelnet10"])
    with pytest.raises(InvalidArgumentError, match=r"^checkpoint\.arch_config: got NoneType"):
        save_checkpoint(dataclasses.replace(good, arch_config=None), tmp_path / "x.pt")  # type: ignore[arg-type]
    assert not (tmp_path / "x.pt").exists()
    with pytest.raises(InvalidArgumentError, match=r"^map_location: got 'bogus'"):
        load_checkpoint(good.path, map_location="bogus")
    torch.manual_seed(0)
    net = SemanticNet(width=8).eval()
    labeler = SemanticLabeler(net, (16, 12), tuple(f"c{i}" for i in range(net.n_classes)))
    huge = np.full((9, 12, 16), 3e38, np.float32)
    assert np.isfinite(labeler.pdfs_of_cues(huge)).all()  # clipped like the cache, not NaN
