"""rgbd_rs.data.nyuv2_mat: the official NYUv2 labeled-set reader on a fabricated MATLAB v7.3
(HDF5) file of the same layout (tests/nyuv2_fake.py), the class mappings and split of the shared
data, the 654 test labels, and (when ``RGBD_NYUV2_MAT`` names the real file) the real file."""

from __future__ import annotations

import os
import pickle
from pathlib import Path

import numpy as np
import pytest

import nyuv2_fake as fake
from rgbd_rs import InvalidArgumentError
from rgbd_rs.data import NYUV2_CAMERA, data_root, load_nyuv2_frame, nyuv2_frames
from rgbd_rs.data.nyuv2 import LABEL13_NAMES, NyuFrame, instance_ground_truth
from rgbd_rs.data.nyuv2_mat import (
    NyuClassMapping,
    NyuMatDataset,
    NyuSplits,
    NyuTestLabels,
    load_nyuv2_mapping,
    load_nyuv2_splits,
)

ROOT = data_root()
NYU = None if ROOT is None else ROOT / "nyuv2"
needs_data = pytest.mark.skipif(
    NYU is None or not (NYU / "splits.mat").is_file(), reason="shared NYUv2 folder not found"
)
SPLITS = NyuSplits(train=(2, 4), test=(1, 3, 5))


@pytest.fixture(scope="module")
def mapping() -> NyuClassMapping:
    if NYU is None or not (NYU / "classMapping40.mat").is_file():
        pytest.skip("shared NYUv2 folder not found")
    return load_nyuv2_mapping()


@pytest.fixture
def written(tmp_path: Path) -> fake.Fake:
    return fake.write(tmp_path / "nyu_depth_v2_labeled.mat")


# -- mappings and split of the shared data -------------------------------------------------


def test_mapping_by_hand(mapping: NyuClassMapping) -> None:
    raw = np.array(fake.RAW, np.uint16)
    label40 = mapping.label40(raw)
    assert label40.dtype == np.uint8
    assert label40.tolist() == [fake.TO40[r] for r in fake.RAW]
    assert mapping.label13(label40).tolist() == [fake.TO13[r] for r in fake.RAW]
    # The names agree along the chain: floor -> floor -> floor, table -> table -> table, ...
    for raw_name, name40, name13 in [
        ("floor", "floor", "floor"),
        ("table", "table", "table"),
        ("cabinet", "cabinet", "furniture"),
        ("ceiling", "ceiling", "ceiling"),
        ("chair", "chair", "chair"),
        ("book", "otherprop", "objects"),
    ]:
        r = mapping.names894.index(raw_name)
        assert mapping.names40[int(mapping.to40[r])] == name40
        assert LABEL13_NAMES[int(mapping.to13[mapping.to40[r]])] == name13
    assert (len(mapping.to40), len(mapping.to13)) == (895, 41)
    assert mapping.names40[0] == mapping.names894[0] == "unlabeled"
    assert set(mapping.to13[1:].tolist()) == set(range(1, 14))  # every 13-class is reached


@needs_data
def test_mapping_matches_the_shared_frames(mapping: NyuClassMapping) -> None:
    # The shared PNGs hold both label40 and label13: label13 is the 40 -> 13 mapping of label40.
    for index in nyuv2_frames()[::5]:
        frame = load_nyuv2_frame(index)
        np.testing.assert_array_equal(mapping.label13(frame.label40), frame.label13)


@needs_data
def test_official_split() -> None:
    splits = load_nyuv2_splits()
    assert (len(splits.train), len(splits.test)) == (795, 654)
    assert sorted(splits.train + splits.test) == list(range(1, 1450))
    assert splits.train[:3] == (3, 4, 5) and splits.test[:3] == (1, 2, 9)
    assert (splits.of(1), splits.of(3)) == ("test", "train")
    # The 50 shared frames are official test frames.
    assert set(nyuv2_frames()) <= set(splits.test)


@needs_data
def test_test_labels_archives() -> None:
    splits = load_nyuv2_splits()
    for classes in (13, 40):
        labels = NyuTestLabels(classes)
        assert len(labels) == 654 and labels.indices == splits.test
        for index in (1, 46):
            frame = load_nyuv2_frame(index)
            np.testing.assert_array_equal(labels.label(index), getattr(frame, f"label{classes}"))


# -- the reader on the fabricated file ------------------------------------------------------


def test_frames_read_back_transposed(written: fake.Fake, mapping: NyuClassMapping) -> None:
    with NyuMatDataset(written.path, mapping=mapping, splits=SPLITS) as ds:
        assert (len(ds), ds.indices, ds.frames_in_file) == (5, (1, 2, 3, 4, 5), 5)
        assert (ds.height, ds.width, ds.has_instances) == (fake.H, fake.W, True)
        for k, frame in enumerate(ds):
            assert isinstance(frame, NyuFrame) and frame.index == k + 1
            assert frame.rgb.shape == (fake.H, fake.W, 3) and frame.rgb.dtype == np.uint8
            np.testing.assert_array_equal(frame.rgb, written.rgb[k])
            assert frame.depth.dtype == np.float32 and frame.depth.flags.c_contiguous
            np.testing.assert_array_equal(frame.depth, written.depth[k])
            np.testing.assert_array_equal(frame.label894, written.labels[k])
            np.testing.assert_array_equal(frame.instances, written.instances[k])
            assert frame.label40.dtype == frame.label13.dtype == np.uint8
            for raw in fake.RAW:
                here = written.labels[k] == raw
                assert (frame.label40[here] == fake.TO40[raw]).all()
                assert (frame.label13[here] == fake.TO13[raw]).all()
        # A pixel away from the diagonal tells H x W from W x H.
        assert ds[0].rgb[3, 50].tolist() == written.rgb[0, 3, 50].tolist()
        assert ds.frame(4).index == 4


def test_splits_and_official_split(written: fake.Fake, mapping: NyuClassMapping) -> None:
    train = NyuMatDataset(written.path, "train", mapping=mapping, splits=SPLITS)
    test = NyuMatDataset(written.path, "test", mapping=mapping, splits=SPLITS)
    assert (train.indices, test.indices) == ((2, 4), (1, 3, 5))
    assert train.names == ("0002", "0004") and train[0].name == "0002"
    assert [f.index for f in train] == [2, 4]
    assert (train[1].split, test[0].split) == ("train", "test")
    assert test[2].official_split == "test"
    np.testing.assert_array_equal(test[1].rgb, written.rgb[2])  # test[1] is frame 3
    # frame() reads by NYU index whatever the split.
    assert train.frame(5).split == "test"
    with pytest.raises(InvalidArgumentError, match=r"^i: got 2"):
        train[2]


def test_raw_depth_holes_are_nan(written: fake.Fake, mapping: NyuClassMapping) -> None:
    ds = NyuMatDataset(written.path, raw_depth=True, mapping=mapping, splits=SPLITS)
    frame = ds[2]
    holes = written.raw_depth[2] == 0
    assert holes.sum() == 10 * 10 + fake.W  # the block and row 0 (they do not overlap)
    assert np.isnan(frame.depth[holes]).all()
    np.testing.assert_array_equal(frame.depth[~holes], written.raw_depth[2][~holes])
    assert not np.isnan(NyuMatDataset(written.path, mapping=mapping, splits=SPLITS)[2].depth).any()


def test_depth_zero_and_nan_in_filled_depth(tmp_path: Path, mapping: NyuClassMapping) -> None:
    _, depth, *_ = fake.arrays()
    depth[1, 5, 7] = 0.0
    depth[1, 6, 8] = np.nan
    written = fake.write(tmp_path / "f.mat", replace={"depths": depth.transpose(0, 2, 1)})
    frame = NyuMatDataset(written.path, mapping=mapping, splits=SPLITS)[1]
    assert np.isnan(frame.depth[5, 7]) and np.isnan(frame.depth[6, 8])
    assert int(np.isnan(frame.depth).sum()) == 2


def test_without_instances(tmp_path: Path, mapping: NyuClassMapping) -> None:
    written = fake.write(tmp_path / "f.mat", skip=("instances", "rawDepths"))
    ds = NyuMatDataset(written.path, mapping=mapping, splits=SPLITS)
    assert not ds.has_instances and ds[0].instances is None


def test_pickled_copy_reopens_and_close_reopens(
    written: fake.Fake, mapping: NyuClassMapping
) -> None:
    ds = NyuMatDataset(written.path, "test", mapping=mapping, splits=SPLITS)
    copy = pickle.loads(pickle.dumps(ds))  # what a DataLoader worker gets
    np.testing.assert_array_equal(copy[0].rgb, ds[0].rgb)
    ds.close()
    ds.close()
    np.testing.assert_array_equal(ds[1].label40, copy[1].label40)


def test_frame_camera(written: fake.Fake, mapping: NyuClassMapping) -> None:
    cam = NyuMatDataset(written.path, mapping=mapping, splits=SPLITS)[0].camera
    assert (cam.width, cam.height) == (fake.W, fake.H)
    assert cam.fx == pytest.approx(NYUV2_CAMERA.fx * fake.W / 640)
    assert cam.cy == pytest.approx((NYUV2_CAMERA.cy + 0.5) * fake.H / 480 - 0.5)
    full = NyuFrame(
        1,
        np.zeros((480, 640, 3), np.uint8),
        np.ones((480, 640), np.float32),
        np.zeros((480, 640), np.uint8),
        np.zeros((480, 640), np.uint8),
    )
    assert full.camera is NYUV2_CAMERA
    assert (full.split, full.official_split, full.label894) == ("train", None, None)


def test_instance_ground_truth_by_hand() -> None:
    label = np.array([[0, 5, 5, 7], [5, 5, 7, 7], [0, 5, 5, 0]], np.uint16)
    inst = np.array([[0, 1, 1, 1], [2, 2, 1, 1], [0, 1, 1, 0]], np.uint8)
    want = np.array([[-1, 0, 0, 1], [2, 2, 1, 1], [-1, 0, 0, -1]], np.int32)
    got = instance_ground_truth(label, inst)
    assert got.dtype == np.int32
    np.testing.assert_array_equal(got, want)
    # (class 5, instance 1) is one object although an occluder (row 1) splits it; (5, 2) and
    # (7, 1) touching it are others. All-unlabeled gives all -1.
    assert (
        instance_ground_truth(np.zeros((2, 2), np.uint8), np.ones((2, 2), np.uint8)) == -1
    ).all()


def test_instance_ground_truth_of_fabricated_frame(
    written: fake.Fake, mapping: NyuClassMapping
) -> None:
    frame = NyuMatDataset(written.path, mapping=mapping, splits=SPLITS)[0]
    assert frame.label894 is not None and frame.instances is not None
    regions = instance_ground_truth(frame.label894, frame.instances)
    flat = zip(frame.label894.ravel(), frame.instances.ravel(), strict=True)
    pairs = {(int(a), int(b)) for a, b in flat if a}
    assert int(regions.max()) + 1 == len(pairs)
    assert ((regions == -1) == (frame.label894 == 0)).all()


# -- the real file, when the user has it ------------------------------------------------------

REAL = os.environ.get("RGBD_NYUV2_MAT")


@pytest.mark.skipif(REAL is None, reason="set RGBD_NYUV2_MAT to nyu_depth_v2_labeled.mat")
@needs_data
def test_real_file_matches_the_shared_frames() -> None:
    with NyuMatDataset(str(REAL), "test") as ds:
        assert (ds.frames_in_file, len(ds), ds.height, ds.width) == (1449, 654, 480, 640)
        labels13 = NyuTestLabels(13)
        for index in (1, 46):
            frame, png = ds.frame(index), load_nyuv2_frame(index)
            np.testing.assert_array_equal(frame.label40, png.label40)
            np.testing.assert_array_equal(frame.label13, labels13.label(index))
            np.testing.assert_array_equal(frame.rgb, png.rgb)
            np.testing.assert_allclose(frame.depth, png.depth, atol=1e-3)
            assert frame.camera is NYUV2_CAMERA
