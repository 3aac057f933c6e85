"""Bad input of the semantic ConvNet: the network (rgbd_rs.nn.semantic), frames, cache and
dataset (rgbd_rs.segmentation.semantic_data), training (rgbd_rs.segmentation.semantic_train) and
the labeler (rgbd_rs.segmentation.labeling). Each case states the exact error class and a
pattern naming the argument or file (see tests/bad_input.py).

``CASES`` (what the meta-test counts) holds the cases of the names the package exports; every
case in ``ALL_CASES`` runs, exported or not."""

from __future__ import annotations

import tempfile
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import torch

from bad_input import Case, check, params, public_cases
from rgbd_rs import InvalidArgumentError, RgbdError, ShapeMismatchError
from rgbd_rs.camera import PinholeCamera
from rgbd_rs.nn.checkpoint import Checkpoint, save_checkpoint
from rgbd_rs.nn.semantic import (
    ARCH,
    SemanticNet,
    _block_filters,
    _GroupedConv,
    _LocalContrastNorm,
    class_probabilities,
    lcn_window,
)
from rgbd_rs.nn.train import TrainConfig
from rgbd_rs.segmentation.labeling import SemanticLabeler
from rgbd_rs.segmentation.semantic_data import (
    FrameFolder,
    LabeledFrame,
    NyuFrames,
    SemanticCache,
    SyntheticFrames,
    build_semantic_cache,
    downsample_cues,
    downsample_labels,
    open_frames,
)
from rgbd_rs.segmentation.semantic_train import (
    SemanticLoss,
    SemanticRecipe,
    default_config,
    score,
    ship,
    train_semantic,
)

SHAPE = ShapeMismatchError
ARG = InvalidArgumentError
_TMP = tempfile.TemporaryDirectory(prefix="rgbd_bad_input_semantic_")
TMP = Path(_TMP.name)
CAMERA = PinholeCamera(fx=40.0, fy=40.0, cx=15.5, cy=11.5, width=32, height=24)


def cues(rgb: np.ndarray, depth: np.ndarray, camera: Any, *, seed: int = 0) -> np.ndarray:
    x = np.zeros((9, *depth.shape), np.float32)
    x[:3] = np.moveaxis(rgb, -1, 0) / 255.0
    return x


def wrong_cues(rgb: np.ndarray, depth: np.ndarray, camera: Any, *, seed: int = 0) -> np.ndarray:
    return np.zeros((3, *depth.shape), np.float32)


_rng = np.random.default_rng(0)
FRAMES = [
    LabeledFrame(
        f"f{i}",
        _rng.integers(0, 256, (24, 32, 3), dtype=np.uint8),
        np.full((24, 32), 2.0, np.float32),
        _rng.integers(0, 14, (24, 32)).astype(np.uint8),
        CAMERA,
    )
    for i in range(3)
]
CACHE = build_semantic_cache(FRAMES, TMP / "cache", size=(16, 12), cues=cues, quiet=True)
OTHER_SIZE = build_semantic_cache(FRAMES, TMP / "cache8", size=(8, 8), cues=cues, quiet=True)
NET = SemanticNet(14, width=4, lcn_window=3)
NORM = {"input_size": [16, 12], "classes": list(CACHE.classes), "ignore_index": 0}
CKPT = save_checkpoint(
    Checkpoint(TMP / "c.pt", ARCH, NET.arch_config(), NORM, NET.state_dict()), TMP / "c.pt"
)
NET40 = SemanticNet(40, width=4, lcn_window=3)
NORM40 = {"input_size": [16, 12], "classes": [f"c{i}" for i in range(40)], "ignore_index": 0}
CKPT40 = save_checkpoint(
    Checkpoint(TMP / "c40.pt", ARCH, NET40.arch_config(), NORM40, NET40.state_dict()),
    TMP / "c40.pt",
)
MISFIT = save_checkpoint(
    Checkpoint(TMP / "m.pt", ARCH, {**NET.arch_config(), "width": 8}, NORM, NET.state_dict()),
    TMP / "m.pt",
)
NAMES_OFF = save_checkpoint(
    Checkpoint(TMP / "n.pt", ARCH, NET.arch_config(), {**NORM, "classes": ["a"]}, NET.state_dict()),
    TMP / "n.pt",
)
OTHER_CUES = save_checkpoint(
    Checkpoint(
        TMP / "oc.pt", ARCH, NET.arch_config(), {**NORM, "cues": CACHE.meta["cues"]},
        NET.state_dict(),
    ),
    TMP / "oc.pt",
)  # fmt: skip
OTHER_ARCH = save_checkpoint(
    Checkpoint(TMP / "o.pt", "other/1", {}, NORM, NET.state_dict()), TMP / "o.pt"
)
(TMP / "garbage.pt").write_bytes(b"not a checkpoint")
(TMP / "x.mat").write_bytes(b"not a MAT-file")
(TMP / "empty").mkdir()
(TMP / "notcache").mkdir()
(TMP / "notcache" / "meta.json").write_text('{"format": "other"}')
LAB = SemanticLabeler.load(CKPT)
CFG = default_config(epochs=1, device="cpu", checkpoint_steps=0)
X = torch.zeros(1, 9, 12, 16)

ALL_CASES: list[Case] = [
    # -- the network
    Case("SemanticNet", lambda: SemanticNet(1), ARG, r"^n_classes: got 1"),
    Case("SemanticNet", lambda: SemanticNet(width=0), ARG, r"^width: got 0", "width"),
    Case("SemanticNet", lambda: SemanticNet(lcn_window=4), ARG, r"^lcn_window: got 4", "even"),
    Case("SemanticNet.forward", lambda: NET(torch.zeros(1, 3, 16, 16)), SHAPE, r"^x: got"),
    Case(
        "SemanticNet.forward",
        lambda: NET(torch.zeros(1, 9, 2, 16)),
        SHAPE,
        r"^x: got 2 x 16",
        "tiny",
    ),
    Case(
        "SemanticNet.from_config",
        lambda: SemanticNet.from_config({"width": 3}),
        ARG,
        r"^arch_config",
    ),
    Case("_LocalContrastNorm", lambda: _LocalContrastNorm(4), ARG, r"^window: got 4"),
    Case("_LocalContrastNorm", lambda: _LocalContrastNorm(3, eps=0), ARG, r"^eps", "eps"),
    Case("_GroupedConv", lambda: _GroupedConv(9, 10, 7, 9), ARG, r"^groups: got 9"),
    Case("lcn_window", lambda: lcn_window(0), ARG, r"^width: got 0"),
    Case("_block_filters", lambda: _block_filters(-1), ARG, r"^width: got -1"),
    Case("class_probabilities", lambda: class_probabilities(torch.zeros(2, 3)), SHAPE, r"^logits"),
    Case(
        "class_probabilities",
        lambda: class_probabilities(torch.zeros(1, 3, 2, 2), ignore_index=3),
        ARG,
        r"^ignore_index: got 3",
        "ignore",
    ),
    Case(
        "class_probabilities",
        lambda: class_probabilities(torch.zeros(1, 2, 2, 2)),
        SHAPE,
        r"^logits: got 2 classes",
        "two",
    ),
    Case(
        "class_probabilities",
        lambda: class_probabilities(torch.zeros(1, 3, 2, 2), (0, 4)),
        ARG,
        r"^size\[0\]: got 0",
        "size",
    ),
    # -- reductions and frames
    Case("downsample_cues", lambda: downsample_cues(np.zeros((4, 4)), (2, 2)), SHAPE, r"^cues"),
    Case(
        "downsample_cues", lambda: downsample_cues(np.zeros((1, 4, 4)), (2,)), ARG, r"^size", "size"
    ),
    Case(
        "downsample_labels",
        lambda: downsample_labels(np.zeros((4, 4), np.float32), (2, 2)),
        ARG,
        r"^labels: got dtype float32",
    ),
    Case(
        "downsample_labels",
        lambda: downsample_labels(np.full((4, 4), 20, np.uint8), (2, 2)),
        ARG,
        r"^labels: got values in \[20, 20\], expected 0\.\.13",
        "range",
    ),
    Case("open_frames", lambda: open_frames("nowhere"), ARG, r"^frames: got 'nowhere'"),
    Case("open_frames", lambda: open_frames("nyuv2", "val"), ARG, r"^split: got 'val'", "split"),
    Case(
        "open_frames",
        lambda: open_frames(TMP / "empty", "train"),
        ARG,
        r"^split: got 'train' for the folder",
        "folder split",
    ),
    Case("open_frames", lambda: open_frames(TMP / "empty"), RgbdError, r"empty: no NAME_", "empty"),
    Case(
        "open_frames",
        lambda: open_frames(TMP / "x.mat", camera=CAMERA),
        ARG,
        r"^camera: given with a \.mat file",
        "mat camera",
    ),
    Case(
        "open_frames",
        lambda: open_frames(TMP / "x.mat"),
        RgbdError,
        r"x\.mat: not an HDF5 file",
        "mat garbage",
    ),
    Case("NyuFrames", lambda: NyuFrames("all", TMP / "empty"), RgbdError, r"empty: no NNNN_"),
    Case("NyuFrames", lambda: NyuFrames("none"), ARG, r"^split: got 'none'", "split"),
    Case("FrameFolder", lambda: FrameFolder(TMP / "nope"), RgbdError, r"nope: not a folder"),
    Case("FrameFolder", lambda: FrameFolder(""), ARG, r"^folder: got ''", "empty"),
    Case(
        "SyntheticFrames", lambda: SyntheticFrames(TMP / "empty"), RgbdError, r"empty: no complete"
    ),
    Case(
        "SyntheticFrames",
        lambda: SyntheticFrames(TMP / "empty", partial=1),  # type: ignore[arg-type]
        ARG,
        r"^partial: got 1",
        "partial",
    ),
    # -- the cache
    Case(
        "build_semantic_cache",
        lambda: build_semantic_cache("frames", TMP / "x"),
        ARG,
        r"^frames: got str",
    ),
    Case(
        "build_semantic_cache",
        lambda: build_semantic_cache([], TMP / "x"),
        ARG,
        r"^frames: got no frames",
        "none",
    ),
    Case(
        "build_semantic_cache",
        lambda: build_semantic_cache(FRAMES, TMP / "x", size=(2, 12), cues=cues),
        ARG,
        r"^size\[0\]: got 2",
        "size",
    ),
    Case(
        "build_semantic_cache",
        lambda: build_semantic_cache(FRAMES, TMP / "x", shard=(2, 2), cues=cues),
        ARG,
        r"^shard: got \(2, 2\)",
        "shard",
    ),
    Case(
        "build_semantic_cache",
        lambda: build_semantic_cache(FRAMES, TMP / "x", cues=3),
        ARG,
        r"^cues: got int",
        "cues",
    ),
    Case(
        "build_semantic_cache",
        lambda: build_semantic_cache([FRAMES[0], FRAMES[0]], TMP / "x", cues=cues),
        ARG,
        r"^frames: got repeated frame names",
        "names",
    ),
    Case(
        "build_semantic_cache",
        lambda: build_semantic_cache(FRAMES, TMP / "cache", size=(16, 12), cues=cues, seed=9),
        RgbdError,
        r"cache: a cache of other frames or settings .*seed",
        "settings",
    ),
    Case(
        "build_semantic_cache",
        lambda: build_semantic_cache(FRAMES, TMP / "cache", size=(16, 12), cues=wrong_cues),
        RgbdError,
        r"other frames or settings .*cues",
        "cue function",
    ),
    Case("SemanticCache", lambda: SemanticCache(TMP / "empty"), RgbdError, r"empty: no meta\.json"),
    Case(
        "SemanticCache",
        lambda: SemanticCache(TMP / "absent"),
        RgbdError,
        r"absent: no such folder, expected a cache .*`rgbd semantic cache`",
        "absent",
    ),
    Case(
        "SemanticCache",
        lambda: SemanticCache(TMP / "notcache"),
        RgbdError,
        r"meta\.json: format 'other'",
        "format",
    ),
    Case(
        "SemanticCache.dataset",
        lambda: CACHE.dataset([0, 7]),
        ARG,
        r"^indices: got values in \[0, 7\]",
    ),
    Case(
        "SemanticCache.dataset",
        lambda: CACHE.dataset([0], partial="yes"),  # type: ignore[arg-type]
        ARG,
        r"^partial: got 'yes'",
    ),
    Case(
        "SemanticCache.dataset",
        lambda: CACHE.dataset(augment=1),  # type: ignore[arg-type]
        ARG,
        r"^augment: got 1",
        "augment",
    ),
    # -- training
    Case("SemanticRecipe", lambda: SemanticRecipe(width=0), ARG, r"^width: got 0"),
    Case("SemanticRecipe", lambda: SemanticRecipe(val_fraction=1.0), ARG, r"^val_fraction", "val"),
    Case("SemanticRecipe", lambda: SemanticRecipe(lcn_window=2), ARG, r"^lcn_window: got 2", "lcn"),
    Case("default_config", lambda: default_config(lr=-1), ARG, r"^lr: got -1"),
    Case(
        "default_config",
        lambda: default_config(lr_step=5),
        ARG,
        r"^lr_plateau: got 10 with lr_step 5",
        "two schedules",
    ),
    Case("TrainConfig", lambda: TrainConfig(lr_plateau=-1), ARG, r"^lr_plateau: got -1", "plateau"),
    Case(
        "TrainConfig",
        lambda: TrainConfig(lr_plateau=3, lr_gamma=1.5),
        ARG,
        r"^lr_gamma: got 1\.5 with lr_plateau",
        "plateau gamma",
    ),
    Case("SemanticLoss", lambda: SemanticLoss(-1), ARG, r"^ignore_index: got -1"),
    Case(
        "train_semantic",
        lambda: train_semantic(CACHE, TMP / "t", recipe=3, config=CFG),  # type: ignore[arg-type]
        ARG,
        r"^recipe: got int",
    ),
    Case(
        "train_semantic",
        lambda: train_semantic(CACHE, TMP / "t", config={"lr": 1}),
        ARG,
        r"^config: got dict",
        "config",
    ),
    Case(
        "train_semantic",
        lambda: train_semantic(
            CACHE, TMP / "t", recipe=SemanticRecipe(ignore_index=14), config=CFG
        ),
        ARG,
        r"^ignore_index: got 14",
        "ignore",
    ),
    Case(
        "train_semantic",
        lambda: train_semantic(TMP / "empty", TMP / "t", config=CFG),
        RgbdError,
        r"empty: no meta\.json",
        "cache",
    ),
    Case(
        "train_semantic",
        lambda: train_semantic(CACHE, TMP / "t", config=CFG, val_cache=OTHER_SIZE),
        RgbdError,
        r"cache8: validation cache of size \(8, 8\)",
        "val cache",
    ),
    Case(
        "train_semantic",
        lambda: train_semantic(OTHER_SIZE, TMP / "t", config=CFG, init=CKPT),
        RgbdError,
        r"c\.pt: --init checkpoint has input_size \[16, 12\], expected \[8, 8\]",
        "init size",
    ),
    Case(
        "train_semantic",
        lambda: train_semantic(CACHE, TMP / "t", config=CFG, init=OTHER_ARCH),
        RgbdError,
        r"o\.pt: checkpoint of architecture 'other/1'",
        "init arch",
    ),
    Case("ship", lambda: ship(TMP / "garbage.pt", TMP / "s.pt"), RgbdError, r"garbage\.pt"),
    Case(
        "ship",
        lambda: ship(OTHER_ARCH, TMP / "s.pt"),
        RgbdError,
        r"o\.pt: checkpoint of arch",
        "arch",
    ),
    Case("score", lambda: score(CKPT, OTHER_SIZE), RgbdError, r"c\.pt: network for \(16, 12\)"),
    Case("score", lambda: score(CKPT, CACHE, batch_size=0), ARG, r"^batch_size: got 0", "batch"),
    # -- the labeler
    Case(
        "SemanticLabeler.load",
        lambda: SemanticLabeler.load(CKPT40, n_classes=14),
        RgbdError,
        r"c40\.pt: a network of 40 classes, expected 14",
    ),
    Case(
        "SemanticLabeler.load",
        lambda: SemanticLabeler.load(CKPT, input_size=(320, 240)),
        RgbdError,
        r"c\.pt: a network for 16 x 12 inputs, expected 320 x 240",
        "size",
    ),
    Case(
        "SemanticLabeler.load",
        lambda: SemanticLabeler.load(MISFIT),
        RgbdError,
        r"m\.pt: weights do not fit the model",
        "misfit",
    ),
    Case(
        "SemanticLabeler.load",
        lambda: SemanticLabeler.load(NAMES_OFF),
        RgbdError,
        r"n\.pt: invalid semantic ConvNet checkpoint \(classes: got 1 names, expected 14",
        "names",
    ),
    Case(
        "SemanticLabeler.load",
        lambda: SemanticLabeler.load(OTHER_ARCH),
        RgbdError,
        r"o\.pt: checkpoint of architecture 'other/1', expected 'semantic-convnet/1'",
        "arch",
    ),
    Case(
        "SemanticLabeler.load",
        lambda: SemanticLabeler.load(TMP / "garbage.pt"),
        RgbdError,
        r"garbage\.pt: not a readable rgbd_rs checkpoint",
        "garbage",
    ),
    Case(
        "SemanticLabeler.load",
        lambda: SemanticLabeler.load(TMP / "missing.pt"),
        RgbdError,
        r"missing\.pt: checkpoint file not found",
        "missing",
    ),
    Case(
        "SemanticLabeler.load",
        lambda: SemanticLabeler.load(""),
        ARG,
        r"^path: got ''",
        "empty path",
    ),
    Case(
        "SemanticLabeler",
        lambda: SemanticLabeler(NET, (16, 12), ("a",)),
        ARG,
        r"^classes: got 1 names, expected 14",
    ),
    Case(
        "SemanticLabeler",
        lambda: SemanticLabeler(3, (16, 12), ("a",)),
        ARG,
        r"^net: got int",
        "net",
    ),  # type: ignore[arg-type]
    Case(
        "SemanticLabeler.pdfs_of_cues",
        lambda: LAB.pdfs_of_cues(np.zeros((9, 24, 32))),
        SHAPE,
        r"^cues: got shape \(1, 9, 24, 32\), expected \(9, 12, 16\)",
    ),
    Case(
        "SemanticLabeler.pdfs_of_cues",
        lambda: LAB.pdfs_of_cues(np.zeros((12, 16))),
        SHAPE,
        r"^cues: got shape \(12, 16\)",
        "2-D",
    ),
    Case(
        "SemanticLabeler.pdfs_from_full_cues",
        lambda: LAB.pdfs_from_full_cues(np.zeros((3, 24, 32))),
        SHAPE,
        r"^cues: got shape \(3, 24, 32\), expected \(9, H, W\)",
    ),
    Case(
        "SemanticLabeler.pdfs_from_full_cues",
        lambda: LAB.pdfs_from_full_cues(np.zeros((9, 24, 32), dtype=bool)),
        ARG,
        r"^cues: got dtype bool",
        "dtype",
    ),
    Case(
        "SemanticLabeler.pdfs",
        lambda: LAB.pdfs(np.zeros((24, 32, 3), np.uint8), np.zeros((20, 32), np.float32), CAMERA),
        SHAPE,
        r"depth",
    ),
    Case(
        "SemanticLabeler.pdfs",
        lambda: SemanticLabeler.load(OTHER_CUES).pdfs(
            np.zeros((24, 32, 3), np.uint8), np.ones((24, 32), np.float32), CAMERA
        ),
        RgbdError,
        r"oc\.pt: a network trained on the cues of test_bad_input_semantic\.cues",
        "other cues",
    ),
    Case(
        "SemanticLabeler.labels",
        lambda: LAB.labels(np.zeros((24, 32), np.uint8), np.zeros((24, 32), np.float32), CAMERA),
        SHAPE,
        r"rgb",
    ),
]


def test_a_bad_frame_is_marked_failed_naming_it(tmp_path: Path) -> None:
    """A frame whose cue function returns the wrong channels fails alone, with a warning naming
    the frame and the cues."""
    with pytest.warns(UserWarning, match=r"frame 0 \(f0\): frame f0 cues: got shape \(3, 24, 32\)"):
        c = build_semantic_cache(
            FRAMES[:1], tmp_path / "c", size=(16, 12), cues=wrong_cues, quiet=True
        )
    assert c.done.tolist() == [2]
    with pytest.raises(RgbdError, match="no computed frames"):
        c.dataset()


#: What the meta-test counts: the cases of names the package exports (the rest still run).
CASES: list[Case] = public_cases(ALL_CASES)


@pytest.mark.parametrize("case", params(ALL_CASES))
def test_bad_input(case: Case) -> None:
    check(case)
