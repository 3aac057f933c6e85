"""Bad input to :mod:`rgbd_rs.data.nyuv2_mat` and :func:`rgbd_rs.data.nyuv2.instance_ground_truth`
(see tests/test_bad_input.py for the contract and the meta-test that counts these cases). The
.mat files are fabricated (tests/nyuv2_fake.py) and broken on purpose; none needs the shared
data."""

from __future__ import annotations

import io
import tarfile
import tempfile
from pathlib import Path

import cv2
import numpy as np
import pytest
from scipy.io import savemat

import nyuv2_fake as fake
from bad_input import Case, check, params
from rgbd_rs import InvalidArgumentError, RgbdError, ShapeMismatchError
from rgbd_rs.data.nyuv2 import LABEL13_NAMES, instance_ground_truth
from rgbd_rs.data.nyuv2_mat import (
    NyuClassMapping,
    NyuMatDataset,
    NyuSplits,
    NyuTestLabels,
    load_nyuv2_mapping,
    load_nyuv2_splits,
)

SHAPE = ShapeMismatchError
ARG = InvalidArgumentError
FILE = RgbdError

_TMP = tempfile.TemporaryDirectory(prefix="rgbd_bad_input_nyuv2_mat_")
TMP = Path(_TMP.name)

TO40 = np.r_[0, np.arange(894) % 40 + 1].astype(np.uint8)
TO13 = np.r_[0, np.arange(40) % 13 + 1].astype(np.uint8)
N40 = ("unlabeled", *(f"c{i}" for i in range(1, 41)))
N894 = ("unlabeled", *(f"r{i}" for i in range(1, 895)))
MAP = NyuClassMapping(TO40, TO13, N40, N894)
SPLITS = NyuSplits(train=(2, 4), test=(1, 3, 5))


def _fresh(name: str) -> Path:
    return Path(tempfile.mkdtemp(dir=TMP)) / name


def _mat(**kw: object) -> Path:
    """A fabricated nyu_depth_v2_labeled.mat (``kw`` as tests/nyuv2_fake.write takes)."""
    return fake.write(_fresh("nyu_depth_v2_labeled.mat"), **kw).path  # type: ignore[arg-type]


def _ds(path: Path, split: str = "all", **kw: object) -> NyuMatDataset:
    return NyuMatDataset(path, split, mapping=MAP, splits=SPLITS, **kw)  # type: ignore[arg-type]


def _text_file() -> Path:
    p = _fresh("nyu_depth_v2_labeled.mat")
    p.write_text("not a MAT-file\n")
    return p


def _v5_mat() -> Path:
    p = _fresh("nyu_depth_v2_labeled.mat")
    savemat(p, {"images": np.zeros((2, 2), np.uint8)})
    return p


def _truncated() -> Path:
    p = _mat()
    data = p.read_bytes()
    p.write_bytes(data[: len(data) // 3])
    return p


def _bad_label() -> NyuMatDataset:
    *_, labels, _ = fake.arrays()
    labels[1, 7, 9] = 900
    return _ds(_mat(replace={"labels": labels.transpose(0, 2, 1)}))


def _mapping_folder(
    map_class: object = None, labels13: object = None, names13: object = None
) -> Path:
    folder = _fresh("mapping")
    folder.mkdir()
    savemat(
        folder / "classMapping40.mat",
        {
            "mapClass": TO40[1:][None] if map_class is None else map_class,
            "className": np.array([[np.array([n]) for n in N40[1:]]], dtype=object),
            "allClassName": np.array([[np.array([n]) for n in N894[1:]]], dtype=object),
        },
    )
    names = LABEL13_NAMES[1:] if names13 is None else names13
    struct = {
        "labels13": TO13[1:][None] if labels13 is None else labels13,
        "classNames": np.array([[np.array([n]) for n in names]], dtype=object),  # type: ignore[union-attr]
    }
    savemat(folder / "class13Mapping.mat", {"classMapping13": struct})
    return folder


def _splits_folder(**variables: object) -> Path:
    folder = _fresh("splits")
    folder.mkdir()
    savemat(folder / "splits.mat", variables)
    return folder


def _corrupt(folder: Path, name: str) -> Path:
    (folder / name).write_bytes(b"MATLAB 5.0 MAT-file" + bytes(200))
    return folder


def _png(img: np.ndarray) -> bytes:
    ok, buf = cv2.imencode(".png", img)
    assert ok
    return bytes(buf)


def _tgz(classes: int = 13, members: dict[str, bytes] | None = None) -> Path:
    folder = _fresh("labels")
    folder.mkdir()
    if members is None:
        members = {"new_nyu_class13_0001.png": _png(np.ones((4, 5), np.uint8))}
    with tarfile.open(folder / f"nyuv2_test_class{classes}.tgz", "w:gz") as tar:
        for name, data in members.items():
            info = tarfile.TarInfo(name)
            info.size = len(data)
            tar.addfile(info, io.BytesIO(data))
    return folder


def _tgz_bytes(folder: Path) -> Path:
    (folder / "nyuv2_test_class13.tgz").write_bytes(b"\x1f\x8b" + bytes(50))
    return folder


CASES: list[Case] = [
    # -- NyuMatDataset: arguments ---------------------------------------------------------
    Case("NyuMatDataset", lambda: NyuMatDataset(3), ARG, r"^path: got 3"),  # type: ignore[arg-type]
    Case("NyuMatDataset", lambda: _ds(_mat(), "val"), ARG, r"^split: got 'val'", "split"),
    Case("NyuMatDataset", lambda: _ds(_mat(), raw_depth=1), ARG, r"^raw_depth: got 1", "raw"),
    Case(
        "NyuMatDataset",
        lambda: NyuMatDataset(_mat(), mapping="nyu", splits=SPLITS),  # type: ignore[arg-type]
        ARG,
        r"^mapping: got str, expected a NyuClassMapping",
        "mapping",
    ),
    Case(
        "NyuMatDataset",
        lambda: NyuMatDataset(_mat(), mapping=MAP, splits=(1, 2)),  # type: ignore[arg-type]
        ARG,
        r"^splits: got tuple, expected a NyuSplits",
        "splits",
    ),
    # -- NyuMatDataset: the file ------------------------------------------------------------
    Case(
        "NyuMatDataset",
        lambda: _ds(TMP / "nope.mat"),
        FILE,
        r"nope\.mat: file not found \(expected nyu_depth_v2_labeled\.mat\)",
        "missing",
    ),
    Case(
        "NyuMatDataset",
        lambda: _ds(_v5_mat()),
        FILE,
        r"\.mat: a MATLAB v5 MAT-file, expected .* v7\.3 \(HDF5\)",
        "v5",
    ),
    Case("NyuMatDataset", lambda: _ds(_text_file()), FILE, r"\.mat: not an HDF5 file", "text"),
    Case("NyuMatDataset", lambda: _ds(_truncated()), FILE, r"\.mat: corrupt or trunc", "trunc"),
    Case(
        "NyuMatDataset",
        lambda: _ds(_mat(skip=("labels",))),
        FILE,
        r"\.mat: has no dataset 'labels' \(expected images, depths, rawDepths, labels",
        "no labels",
    ),
    Case(
        "NyuMatDataset",
        lambda: _ds(_mat(skip=("rawDepths",)), raw_depth=True),
        FILE,
        r"\.mat: has no dataset 'rawDepths'",
        "no raw",
    ),
    Case(
        "NyuMatDataset",
        lambda: _ds(_mat(replace={"images": fake.arrays()[0]})),  # N x H x W x 3: not transposed
        FILE,
        r"dataset 'images' is uint8 of shape \(5, 48, 64, 3\), expected uint8 N x 3 x W x H",
        "images",
    ),
    Case(
        "NyuMatDataset",
        lambda: _ds(_mat(replace={"depths": fake.arrays()[1]})),  # N x H x W: not transposed
        FILE,
        r"dataset 'depths' is float32 of shape \(5, 48, 64\), expected float \(5, 64, 48\)",
        "depths",
    ),
    Case(
        "NyuMatDataset",
        lambda: _ds(_mat(replace={"labels": np.zeros((5, 64, 48), np.float32)})),
        FILE,
        r"dataset 'labels' is float32 of shape \(5, 64, 48\), expected integer",
        "labels",
    ),
    Case(
        "NyuMatDataset",
        lambda: _ds(_mat(replace={"instances": np.zeros((4, 64, 48), np.uint8)})),
        FILE,
        r"dataset 'instances' is uint8 of shape \(4, 64, 48\), expected integer \(5, 64, 48\)",
        "instances",
    ),
    Case(
        "NyuMatDataset",
        lambda: _ds(
            _mat(
                replace={
                    k: np.zeros(s, t)
                    for k, s, t in [
                        ("images", (0, 3, 64, 48), np.uint8),
                        ("depths", (0, 64, 48), np.float32),
                        ("labels", (0, 64, 48), np.uint16),
                    ]
                },
                skip=("rawDepths", "instances"),
            )
        ),
        FILE,
        r"dataset 'images' is empty",
        "empty",
    ),
    Case(
        "NyuMatDataset",
        lambda: NyuMatDataset(_mat(), "test", mapping=MAP, splits=NyuSplits((2,), (1, 1449))),
        FILE,
        r"\.mat: holds 5 frames, but the test split names frame 1449 \(expected the 1449-frame",
        "split beyond",
    ),
    Case(
        "NyuMatDataset",
        lambda: _ds(_mat(), "train")[2],
        ARG,
        r"^i: got 2, expected an integer >= 0 and <= 1",
        "getitem",
    ),
    Case("NyuMatDataset", lambda: _ds(_mat())[-1], ARG, r"^i: got -1", "getitem negative"),
    Case(
        "NyuMatDataset",
        lambda: NyuMatDataset(_mat(), "train", mapping=MAP, splits=NyuSplits((), (1,)))[0],
        ARG,
        r"^i: got 0, expected no index \(the split is empty\)",
        "getitem empty",
    ),
    Case(
        "NyuMatDataset", lambda: _bad_label()[1], FILE, r"frame 2: 'labels' holds class 900", "cls"
    ),
    # -- NyuMatDataset.frame ------------------------------------------------------------------
    Case(
        "NyuMatDataset.frame",
        lambda: _ds(_mat()).frame(6),
        ARG,
        r"^index: got 6, expected an integer >= 1 and <= 5",
    ),
    Case("NyuMatDataset.frame", lambda: _ds(_mat()).frame(0), ARG, r"^index: got 0", "zero"),
    Case(
        "NyuMatDataset.frame",
        lambda: _ds(_mat()).frame("1"),  # type: ignore[arg-type]
        ARG,
        r"^index: got '1', expected an integer",
        "str",
    ),
    Case(
        "NyuMatDataset.frame",
        lambda: _bad_label().frame(2),
        FILE,
        r"nyu_depth_v2_labeled\.mat: frame 2: 'labels' holds class 900, expected 0\.\.894",
        "class",
    ),
    # -- NyuClassMapping ----------------------------------------------------------------------
    Case(
        "NyuClassMapping",
        lambda: NyuClassMapping(TO40[:-1], TO13, N40, N894),
        ARG,
        r"^to40: got uint8 of shape \(894,\), expected a uint8 table of 895 classes",
    ),
    Case(
        "NyuClassMapping",
        lambda: NyuClassMapping(TO40, TO13.astype(np.int64), N40, N894),
        ARG,
        r"^to13: got int64",
        "dtype",
    ),
    Case(
        "NyuClassMapping",
        lambda: NyuClassMapping(TO40, np.r_[TO13[:-1], 14].astype(np.uint8), N40, N894),
        ARG,
        r"^to13: got classes 0 at 0 and up to 14, expected 0 at 0 \(unlabeled\) and "
        r"classes 0\.\.13",
        "range",
    ),
    Case(
        "NyuClassMapping",
        lambda: NyuClassMapping(np.r_[3, TO40[1:]].astype(np.uint8), TO13, N40, N894),
        ARG,
        r"^to40: got classes 3 at 0",
        "unlabeled",
    ),
    Case(
        "NyuClassMapping",
        lambda: NyuClassMapping(TO40, TO13, N40[1:], N894),
        ARG,
        r"^names40: got tuple of 40 items, expected 41 names",
        "names",
    ),
    Case(
        "NyuClassMapping",
        lambda: NyuClassMapping(TO40, TO13, N40, "names"),  # type: ignore[arg-type]
        ARG,
        r"^names894: got str, expected a tuple of 895 names",
        "names str",
    ),
    Case(
        "NyuClassMapping.label40",
        lambda: MAP.label40(np.array([1.0, 2.0])),
        ARG,
        r"^label894: got dtype float64, expected integer labels",
    ),
    Case(
        "NyuClassMapping.label40",
        lambda: MAP.label40(np.array([0, 895])),
        ARG,
        r"^label894: got labels in \[0, 895\], expected 0\.\.894",
        "range",
    ),
    Case(
        "NyuClassMapping.label13",
        lambda: MAP.label13(np.array([[41]], np.uint8)),
        ARG,
        r"^label40: got labels in \[41, 41\], expected 0\.\.40",
    ),
    Case(
        "NyuClassMapping.label13",
        lambda: MAP.label13(np.array([-1, 3])),
        ARG,
        r"^label40: got labels in \[-1, 3\]",
        "negative",
    ),
    # -- NyuSplits ------------------------------------------------------------------------------
    Case(
        "NyuSplits",
        lambda: NyuSplits([1, 2], (3,)),  # type: ignore[arg-type]
        ARG,
        r"^train: got \[1, 2\], expected a tuple of 1-based frame indices",
    ),
    Case("NyuSplits", lambda: NyuSplits((1,), (0, 2)), ARG, r"^test: got \(0, 2\)", "zero"),
    Case(
        "NyuSplits",
        lambda: NyuSplits((3, 1), (2,)),
        ARG,
        r"^train: got unsorted or repeated indices",
        "unsorted",
    ),
    Case(
        "NyuSplits",
        lambda: NyuSplits((1, 2), (2, 3)),
        ARG,
        r"^test: got frame 2 in both splits, expected disjoint",
        "overlap",
    ),
    Case("NyuSplits.of", lambda: SPLITS.of(0), ARG, r"^index: got 0, expected an integer >= 1"),
    Case("NyuSplits.of", lambda: SPLITS.of(1.0), ARG, r"^index: got 1\.0", "float"),  # type: ignore[arg-type]
    # -- load_nyuv2_mapping -------------------------------------------------------------------
    Case("load_nyuv2_mapping", lambda: load_nyuv2_mapping(3), ARG, r"^folder: got 3"),  # type: ignore[arg-type]
    Case(
        "load_nyuv2_mapping",
        lambda: load_nyuv2_mapping(TMP),
        FILE,
        r"classMapping40\.mat: file not found",
        "missing",
    ),
    Case(
        "load_nyuv2_mapping",
        lambda: load_nyuv2_mapping(_corrupt(_mapping_folder(), "classMapping40.mat")),
        FILE,
        r"classMapping40\.mat: corrupt or not a MATLAB v5 MAT-file",
        "corrupt",
    ),
    Case(
        "load_nyuv2_mapping",
        lambda: load_nyuv2_mapping(_mapping_folder(map_class=np.full((1, 894), 41, np.uint8))),
        FILE,
        r"classMapping40\.mat: mapClass holds values in \[41, 41\], expected integers 1\.\.40",
        "range",
    ),
    Case(
        "load_nyuv2_mapping",
        lambda: load_nyuv2_mapping(_mapping_folder(map_class=np.ones((1, 40), np.uint8))),
        FILE,
        r"classMapping40\.mat: mapClass holds 40 uint8 values, expected 894 classes",
        "size",
    ),
    Case(
        "load_nyuv2_mapping",
        lambda: load_nyuv2_mapping(_mapping_folder(labels13=np.zeros((1, 40), np.uint8))),
        FILE,
        r"class13Mapping\.mat: classMapping13\.labels13 holds values in \[0, 0\]",
        "labels13",
    ),
    Case(
        "load_nyuv2_mapping",
        lambda: load_nyuv2_mapping(_mapping_folder(names13=[*LABEL13_NAMES[2:], "bed"])),
        FILE,
        r"class13Mapping\.mat: classNames are \['books', .*, expected \['bed', 'books'",
        "names13",
    ),
    Case(
        "load_nyuv2_mapping",
        lambda: load_nyuv2_mapping(_mapping_folder(names13=LABEL13_NAMES[1:-1])),
        FILE,
        r"class13Mapping\.mat: classMapping13\.classNames holds 12 names, expected 13",
        "12 names",
    ),
    # -- load_nyuv2_splits ----------------------------------------------------------------------
    Case("load_nyuv2_splits", lambda: load_nyuv2_splits(""), ARG, r"^folder: got ''"),
    Case(
        "load_nyuv2_splits",
        lambda: load_nyuv2_splits(TMP),
        FILE,
        r"splits\.mat: file not found",
        "missing",
    ),
    Case(
        "load_nyuv2_splits",
        lambda: load_nyuv2_splits(_splits_folder(trainNdxs=np.array([[1], [2]], np.uint16))),
        FILE,
        r"splits\.mat: has no variable 'testNdxs'",
        "variable",
    ),
    Case(
        "load_nyuv2_splits",
        lambda: load_nyuv2_splits(_splits_folder(trainNdxs=np.array([0, 1]), testNdxs=[[3]])),
        FILE,
        r"splits\.mat: trainNdxs holds values that are not integers >= 1, expected 1-based",
        "zero",
    ),
    Case(
        "load_nyuv2_splits",
        lambda: load_nyuv2_splits(_splits_folder(trainNdxs=[[1], [2]], testNdxs=[[2], [3]])),
        FILE,
        r"splits\.mat: trainNdxs and testNdxs share frames",
        "overlap",
    ),
    Case(
        "load_nyuv2_splits",
        lambda: load_nyuv2_splits(_splits_folder(trainNdxs=[[1.5]], testNdxs=[[3]])),
        FILE,
        r"splits\.mat: trainNdxs holds values that are not integers >= 1",
        "fraction",
    ),
    # -- NyuTestLabels --------------------------------------------------------------------------
    Case("NyuTestLabels", lambda: NyuTestLabels(14, _tgz()), ARG, r"^classes: got 14"),
    Case("NyuTestLabels", lambda: NyuTestLabels(True, _tgz()), ARG, r"^classes: got True", "bool"),  # type: ignore[arg-type]
    Case("NyuTestLabels", lambda: NyuTestLabels(13, 5), ARG, r"^folder: got 5", "folder"),  # type: ignore[arg-type]
    Case(
        "NyuTestLabels",
        lambda: NyuTestLabels(40, TMP),
        FILE,
        r"nyuv2_test_class40\.tgz: file not found",
        "missing",
    ),
    Case(
        "NyuTestLabels",
        lambda: NyuTestLabels(13, _tgz_bytes(_tgz())),
        FILE,
        r"nyuv2_test_class13\.tgz: corrupt or not a \.tgz archive",
        "corrupt",
    ),
    Case(
        "NyuTestLabels",
        lambda: NyuTestLabels(40, _tgz(40)),  # holds new_nyu_class13_*.png only
        FILE,
        r"nyuv2_test_class40\.tgz: no new_nyu_class40_NNNN\.png label images",
        "empty",
    ),
    Case(
        "NyuTestLabels.label",
        lambda: NyuTestLabels(13, _tgz()).label(3),
        ARG,
        r"^index: got 3, expected one of the 1 test frames of nyuv2_test_class13\.tgz",
    ),
    Case(
        "NyuTestLabels.label",
        lambda: NyuTestLabels(13, _tgz()).label(0),
        ARG,
        r"^index: got 0",
        "0",
    ),
    Case(
        "NyuTestLabels.label",
        lambda: NyuTestLabels(13, _tgz(members={"new_nyu_class13_0001.png": b"garbage"})).label(1),
        FILE,
        r"\.tgz: new_nyu_class13_0001\.png: got undecodable data, expected a uint8 label PNG",
        "undecodable",
    ),
    Case(
        "NyuTestLabels.label",
        lambda: NyuTestLabels(
            13,
            _tgz(members={"new_nyu_class13_0001.png": _png(np.full((480, 640), 14, np.uint8))}),
        ).label(1),
        FILE,
        r"new_nyu_class13_0001\.png: got class 14, expected 0\.\.13",
        "class",
    ),
    Case(
        "NyuTestLabels.label",
        lambda: NyuTestLabels(
            13, _tgz(members={"new_nyu_class13_0001.png": _png(np.ones((5, 5), np.uint8))})
        ).label(1),
        FILE,
        r"new_nyu_class13_0001\.png: got a 5x5 label image, expected NYUv2's 640x480 frames",
        "size",
    ),
    Case(
        "NyuTestLabels.label",
        lambda: NyuTestLabels(
            13, _tgz(members={"new_nyu_class13_0001.png": _png(np.ones((3, 3), np.uint16))})
        ).label(1),
        FILE,
        r"new_nyu_class13_0001\.png: got uint16 \(3, 3\), expected a uint8 label PNG",
        "uint16",
    ),
    # -- instance_ground_truth ------------------------------------------------------------------
    Case(
        "instance_ground_truth",
        lambda: instance_ground_truth(np.ones((3, 4)), np.ones((3, 4), np.uint8)),
        ARG,
        r"^label894: got dtype float64, expected an integer label image",
    ),
    Case(
        "instance_ground_truth",
        lambda: instance_ground_truth(np.ones((3, 4), np.uint16), np.ones((3, 4, 1), np.uint8)),
        SHAPE,
        r"^instances: got shape \(3, 4, 1\), expected a non-empty \(H, W\) image",
        "3d",
    ),
    Case(
        "instance_ground_truth",
        lambda: instance_ground_truth(np.ones((3, 4), np.uint16), np.ones((4, 3), np.uint8)),
        SHAPE,
        r"^instances: got shape \(4, 3\), expected \(3, 4\) like label894",
        "mismatch",
    ),
    Case(
        "instance_ground_truth",
        lambda: instance_ground_truth(np.full((2, 2), -1), np.ones((2, 2), np.uint8)),
        ARG,
        r"^label894: got values in \[-1, -1\], expected 0\.\.65535",
        "negative",
    ),
    Case(
        "instance_ground_truth",
        lambda: instance_ground_truth(np.zeros((0, 3), np.uint16), np.zeros((0, 3), np.uint8)),
        SHAPE,
        r"^label894: got shape \(0, 3\)",
        "empty",
    ),
]


@pytest.mark.parametrize("case", params(CASES))
def test_bad_input(case: Case) -> None:
    check(case)
