"""Bad input of the shape classifier: the network (rgbd_rs.nn.shapes), datasets and cache
(rgbd_rs.shapes.dataset), training (rgbd_rs.shapes.train), classification and evaluation. Each
case states the exact error class and a pattern naming the argument or file (see
tests/bad_input.py).

``CASES`` (what the meta-test counts) holds the cases of the names rgbd_rs.shapes / rgbd_rs.nn
export; every case in ``ALL_CASES`` runs, exported or not."""

from __future__ import annotations

import tempfile
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest
import torch

from bad_input import Case, check, params, public_cases
from rgbd_rs import InvalidArgumentError, RgbdError, ShapeMismatchError
from rgbd_rs.meshes import Mesh, box, load_mesh
from rgbd_rs.nn.checkpoint import Checkpoint, save_checkpoint
from rgbd_rs.nn.shape_ensemble import ShapeEnsemble
from rgbd_rs.nn.shapes import (
    ARCH,
    ShapeNet,
    _input_shapes,
    _parse_representations,
    _view_pools,
    _volume_pools,
    pack,
    unpack,
)
from rgbd_rs.shapes.classify import ShapeClassifier, _weights_path, classify, to_z_up
from rgbd_rs.shapes.dataset import (
    InputSpec,
    OffTree,
    PointCloudSet,
    ShapeCache,
    batch_inputs,
    build_cache,
    load_shape,
    open_shapes,
    sample_surface,
    shape_inputs,
)
from rgbd_rs.shapes.evaluate import ShapeEvaluation, ablation_markdown, evaluate, row_name
from rgbd_rs.shapes.train import (
    ShapeRecipe,
    ablation_rows,
    default_config,
    ship,
    train_ablation,
    train_shapes,
)

SHAPE = ShapeMismatchError
ARG = InvalidArgumentError
_TMP = tempfile.TemporaryDirectory(prefix="rgbd_bad_input_shapes_nn_")
TMP = Path(_TMP.name)

# Files: not a mesh, a mesh without faces, NaN vertices, a point file of the wrong shape.
(TMP / "junk.off").write_text("this is not a mesh\n")
(TMP / "empty.off").write_text("OFF\n3 0 0\n0 0 0\n1 0 0\n0 1 0\n")
(TMP / "nan.off").write_text("OFF\n3 1 0\n0 0 0\nnan 0 0\n0 1 0\n3 0 1 2\n")
(TMP / "junk.ply").write_bytes(b"ply\nformat nonsense\n")
(TMP / "cut.obj").write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0")  # cut inside a vertex line
(TMP / "cutf.obj").write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nf 1 2 3\nf 1 2")  # a face
(TMP / "junk.pcd").write_text("# .PCD\nFIELDS x y\n")
_PCD = "FIELDS {f}\nSIZE 4 4 4\nTYPE F F F\nCOUNT {c}\nWIDTH 1\nPOINTS 1\nDATA ascii\n0 0 0\n"
(TMP / "no_x.pcd").write_text(_PCD.format(f="a y z", c="1 1 1"))
(TMP / "huge_count.pcd").write_text(_PCD.format(f="x y z", c="1 1 99999999999"))
(TMP / "shape.txt").write_text("1 2 3\n")
np.save(TMP / "flat.npy", np.zeros((5, 2)))
np.save(TMP / "nan.npy", np.array([[0.0, np.nan, 0.0]]))
(TMP / "garbage.pt").write_bytes(b"not a checkpoint")
(TMP / "tree").mkdir()
(TMP / "tree2" / "a" / "train").mkdir(parents=True)
(TMP / "tree2" / "a" / "train" / "broken.off").write_text("OFF\n3 1 0\n0 0 0\n")

# A tiny real cache (volume profiles of random clouds) and a checkpoint that fits it.
_rng = np.random.default_rng(0)
np.savez(
    TMP / "pack.npz",
    points=_rng.normal(size=(4, 64, 3)).astype(np.float16),
    label=np.array([0, 1, 0, 1], np.int16),
    split=np.array([0, 0, 1, 1], np.uint8),
    classes=np.array(["a", "b"]),
    name=np.array(["a_1", "b_1", "a_2", "b_2"]),
)
SPEC = InputSpec(representations=("volume",), normalisation="standardize")
CACHE = build_cache(TMP / "pack.npz", TMP / "cache", spec=SPEC, quiet=True)
NET = ShapeNet(2, representations=("volume",), width=2)
NORM = {"spec": SPEC.to_dict(), "classes": ["a", "b"], "kind": "points", "points_per_shape": 64}
CKPT = save_checkpoint(
    Checkpoint(TMP / "c.pt", ARCH, NET.arch_config(), NORM, NET.state_dict()), TMP / "c.pt"
)
OTHER = save_checkpoint(
    Checkpoint(TMP / "o.pt", "other/1", {}, NORM, NET.state_dict()), TMP / "o.pt"
)
CLF = ShapeClassifier.load(CKPT)
EVAL = ShapeEvaluation(("a", "b"), np.eye(2, dtype=np.int64), ("volume",), "c.pt", "pack", "test")
P = np.zeros((4, 3))
X = {"volume": torch.zeros(2, 3, 32, 32)}
EMPTY = Mesh(np.zeros((3, 3), np.float32), np.zeros((0, 3), np.uint32))


def _without_curvature(call: Callable[[], object]) -> object:
    """``call()`` in an installation without curvature maps (e.g. a build lacking the spline
    kernel): every representation is computable in a full install."""
    from unittest import mock

    with mock.patch("rgbd_rs.shapes.dataset._curvature_maps", return_value=None):
        return call()


ALL_CASES: list[Case] = [
    # -- the network
    Case("ShapeNet", lambda: ShapeNet(1), ARG, r"^n_classes: got 1"),
    Case(
        "ShapeNet",
        lambda: ShapeNet(3, representations="colour"),
        ARG,
        r"^representations: got unknown \['colour'\]",
        "unknown",
    ),
    Case("ShapeNet", lambda: ShapeNet(3, representations=[]), ARG, r"^representations", "none"),
    Case(
        "ShapeNet", lambda: ShapeNet(3, view_resolution=4), ARG, r"^view_resolution: got 4", "small"
    ),
    Case(
        "ShapeNet",
        lambda: ShapeNet(3, volume_resolution=8),
        ARG,
        r"^volume_resolution: got 8",
        "vol",
    ),
    Case("ShapeNet", lambda: ShapeNet(3, width=0), ARG, r"^width: got 0", "width"),
    Case(
        "ShapeNet.forward",
        lambda: NET({"volume": torch.zeros(2, 3, 16, 16)}),
        SHAPE,
        r"^x\['volume'\]: got shape \(2, 3, 16, 16\)",
    ),
    Case(
        "ShapeNet.forward",
        lambda: NET({"depth": torch.zeros(2, 6, 32, 32)}),
        ARG,
        r"^x: got representations \['depth'\].*missing \['volume'\]",
        "missing",
    ),
    Case(
        "ShapeNet.forward",
        lambda: NET(torch.zeros(2, 100)),
        SHAPE,
        r"^x: got shape \(2, 100\), expected \(N, 3072\)",
        "packed",
    ),
    Case("ShapeNet.forward", lambda: NET("x"), ARG, r"^x: got str", "type"),  # type: ignore[arg-type]
    Case("ShapeNet.features", lambda: NET.features(torch.zeros(3)), SHAPE, r"^x: got shape \(3,\)"),
    Case(
        "ShapeNet.from_config",
        lambda: ShapeNet.from_config({"width": 2}),
        ARG,
        r"^arch_config: got \['width'\]",
    ),
    Case("ShapeEnsemble", lambda: ShapeEnsemble([NET]), ARG, r"^members: got 1 members"),
    Case(
        "ShapeEnsemble.forward",
        lambda: ShapeEnsemble([NET, NET])(torch.zeros(2, 100)),
        SHAPE,
        r"^x: got shape \(2, 100\), expected \(N, 3072\)",
    ),
    Case(
        "ShapeEnsemble.from_config",
        lambda: ShapeEnsemble.from_config({"members": 2, "member": {"width": 2}}),
        ARG,
        r"^arch_config: got \['width'\]",
    ),
    Case(
        "_parse_representations",
        lambda: _parse_representations("depth,depth"),
        ARG,
        r"^representations: got \['depth', 'depth'\]",
    ),
    Case(
        "_parse_representations",
        lambda: _parse_representations(3),
        ARG,
        r"^representations: got 3",
        "type",
    ),  # type: ignore[arg-type]
    Case("_view_pools", lambda: _view_pools(7), ARG, r"^resolution: got 7"),
    Case("_volume_pools", lambda: _volume_pools(15), ARG, r"^volume_resolution: got 15"),
    Case(
        "_input_shapes", lambda: _input_shapes(["volume"], 0, 32), ARG, r"^view_resolution: got 0"
    ),
    Case(
        "pack",
        lambda: pack({"volume": np.zeros((2, 3, 8, 8))}, NET.shapes),
        SHAPE,
        r"^inputs\['volume'\]: got shape \(2, 3, 8, 8\)",
    ),
    Case(
        "pack", lambda: pack({}, NET.shapes), ARG, r"^inputs: got representations \[\]", "missing"
    ),
    Case("pack", lambda: pack([1], NET.shapes), ARG, r"^inputs: got list", "type"),  # type: ignore[arg-type]
    Case("unpack", lambda: unpack(torch.zeros(2, 5), NET.shapes), SHAPE, r"^x: got shape \(2, 5\)"),
    # -- inputs, files, datasets, cache
    Case(
        "InputSpec",
        lambda: InputSpec(representations=("colour",)),
        ARG,
        r"^representations: got unknown",
    ),
    Case("InputSpec", lambda: InputSpec(view_resolution=2), ARG, r"^view_resolution: got 2", "res"),
    Case(
        "InputSpec",
        lambda: InputSpec(normalisation="zca"),
        ARG,
        r"^normalisation: got 'zca'",
        "norm",
    ),
    Case("InputSpec", lambda: InputSpec(volume_fill="hollow"), ARG, r"^volume_fill", "fill"),
    Case(
        "InputSpec",
        lambda: InputSpec(normalisation="lcn", view_lcn_window=4),
        ARG,
        r"^view_lcn_window: got 4, expected an odd",
        "even-window",
    ),
    Case(
        "InputSpec",
        lambda: InputSpec(normalisation="standardize", volume_lcn_window=5),
        ARG,
        r"^volume_lcn_window: got 5 with normalisation 'standardize'",
        "window-without-lcn",
    ),
    Case(
        "InputSpec.from_dict",
        lambda: InputSpec.from_dict({"colour": 1}),
        ARG,
        r"^spec: got \['colour'\]",
    ),
    Case(
        "InputSpec.check_available",
        lambda: _without_curvature(InputSpec(representations=("curvature",)).check_available),
        RgbdError,
        r"^representations: \['curvature'\] cannot be computed",
    ),
    Case(
        "shape_inputs",
        lambda: shape_inputs(EMPTY, SPEC),
        ARG,
        r"^shape: got a mesh with no triangles",
    ),
    Case(
        "shape_inputs",
        lambda: shape_inputs(np.array([[0.0, np.nan, 0.0]]), SPEC),
        ARG,
        r"^shape: got 1 non-finite",
        "nan",
    ),
    Case(
        "shape_inputs",
        lambda: shape_inputs(np.zeros((4, 2)), SPEC),
        SHAPE,
        r"^shape: got shape \(4, 2\)",
        "2-D",
    ),
    Case(
        "shape_inputs",
        lambda: shape_inputs(np.zeros((0, 3)), SPEC),
        SHAPE,
        r"^shape: got an empty",
        "empty",
    ),
    Case("shape_inputs", lambda: shape_inputs(P, "volume"), ARG, r"^spec: got str", "spec"),  # type: ignore[arg-type]
    Case(
        "shape_inputs",
        lambda: _without_curvature(
            lambda: shape_inputs(P, InputSpec(("curvature",), normalisation="standardize"))
        ),
        RgbdError,
        r"^representations: \['curvature'\]",
        "absent",
    ),
    Case(
        "batch_inputs",
        lambda: batch_inputs([P, EMPTY], SPEC),
        ARG,
        r"^shapes\[1\]: got a mesh with no triangles",
    ),
    Case("batch_inputs", lambda: batch_inputs(P, SPEC), ARG, r"^shapes: got ndarray", "array"),
    Case(
        "batch_inputs",
        lambda: batch_inputs([P], SPEC, workers=0),
        ARG,
        r"^workers: got 0",
        "workers",
    ),
    Case(
        "load_shape",
        lambda: load_shape(TMP / "junk.off"),
        RgbdError,
        r"junk\.off: not a valid OFF mesh",
    ),
    Case(
        "load_shape",
        lambda: load_shape(TMP / "empty.off"),
        RgbdError,
        r"empty\.off: not a valid OFF mesh \(no faces of three or more vertices",
        "no-faces",
    ),
    Case(
        "load_mesh",
        lambda: load_mesh(TMP / "empty.off"),
        RgbdError,
        r"empty\.off: not a valid OFF mesh \(no faces of three or more vertices",
        "no-faces",
    ),
    Case(
        "load_shape",
        lambda: load_shape(TMP / "cut.obj"),
        RgbdError,
        r"cut\.obj: the file ends inside the line 'v 0 0' \(truncated file\?\)",
        "truncated obj",
    ),
    Case(
        "load_shape",
        lambda: load_shape(TMP / "cutf.obj"),
        RgbdError,
        r"cutf\.obj: the file ends inside the line 'f 1 2' \(truncated file\?\)",
        "truncated obj face",
    ),
    Case(
        "load_shape",
        lambda: load_shape(TMP / "nan.off"),
        RgbdError,
        r"nan\.off: .*not finite",
        "nan",
    ),
    Case("load_shape", lambda: load_shape(TMP / "junk.ply"), RgbdError, r"junk\.ply", "ply"),
    Case(
        "load_shape",
        lambda: load_shape(TMP / "junk.pcd"),
        RgbdError,
        r"junk\.pcd: not a PCD",
        "pcd",
    ),
    Case(
        "load_shape",
        lambda: load_shape(TMP / "no_x.pcd"),
        RgbdError,
        r"no_x\.pcd: not a PCD point cloud \(its FIELDS a y z lack x\)$",
        "pcd without x",
    ),
    Case(
        "load_shape",
        lambda: load_shape(TMP / "huge_count.pcd"),
        RgbdError,
        r"huge_count\.pcd: .*COUNT 1 1 99999999999: expected .*counts of 1 to 4096\)$",
        "pcd count",
    ),
    Case(
        "load_shape",
        lambda: load_shape(TMP / "flat.npy"),
        RgbdError,
        r"flat\.npy: got shape \(5, 2\)",
        "npy",
    ),
    Case(
        "load_shape",
        lambda: load_shape(TMP / "nan.npy"),
        RgbdError,
        r"nan\.npy: got 1 non-finite",
        "npy-nan",
    ),
    Case(
        "load_shape",
        lambda: load_shape(TMP / "shape.txt"),
        ARG,
        r"^path: got a '\.txt' file",
        "suffix",
    ),
    Case(
        "load_shape",
        lambda: load_shape(TMP / "none.off"),
        ARG,
        r"^path: got .*none\.off",
        "missing",
    ),
    Case(
        "sample_surface", lambda: sample_surface(EMPTY), ARG, r"^mesh: got a mesh with no triangles"
    ),
    Case("sample_surface", lambda: sample_surface(box((1, 1, 1)), 0), ARG, r"^n: got 0", "n"),
    Case("sample_surface", lambda: sample_surface(P), ARG, r"^mesh: got ndarray", "type"),  # type: ignore[arg-type]
    Case("open_shapes", lambda: open_shapes(TMP / "nothing"), ARG, r"^data: got .*nothing"),
    Case(
        "open_shapes",
        lambda: open_shapes(TMP / "tree"),
        RgbdError,
        r"tree: no <class>/train",
        "empty-tree",
    ),
    Case("OffTree", lambda: OffTree(TMP / "junk.off"), RgbdError, r"junk\.off: not a folder"),
    Case(
        "OffTree.load",
        lambda: OffTree(TMP / "tree2").load(0),
        RgbdError,
        r"broken\.off: not a valid OFF",
    ),
    Case(
        "PointCloudSet",
        lambda: PointCloudSet(TMP / "cache" / "meta.json"),
        RgbdError,
        r"meta\.json: not a readable npz archive \(not a zip archive\)",
    ),
    Case(
        "PointCloudSet.load", lambda: PointCloudSet(TMP / "pack.npz").load(4), ARG, r"^index: got 4"
    ),
    Case(
        "build_cache",
        lambda: build_cache(TMP / "pack.npz", TMP / "c2", spec=SPEC, shard=(2, 2)),
        ARG,
        r"^shard: got \(2, 2\)",
    ),
    Case(
        "build_cache",
        lambda: build_cache(
            TMP / "pack.npz",
            TMP / "cache",
            spec=InputSpec(("volume",), volume_resolution=16, normalisation="standardize"),
        ),
        RgbdError,
        r"cache: a cache of other data or settings",
        "other",
    ),
    Case(
        "build_cache",
        lambda: build_cache(TMP / "pack.npz", TMP / "c3", spec=SPEC, chunk=0),
        ARG,
        r"^chunk: got 0",
        "chunk",
    ),
    Case("ShapeCache", lambda: ShapeCache(TMP / "tree"), RgbdError, r"tree: no meta\.json"),
    Case("ShapeCache.array", lambda: CACHE.array("depth"), ARG, r"^representation: got 'depth'"),
    Case("ShapeCache.indices", lambda: CACHE.indices("val"), ARG, r"^split: got 'val'"),
    Case(
        "ShapeCache.require_complete",
        lambda: CACHE.require_complete("val"),
        ARG,
        r"^split: got 'val'",
    ),
    Case(
        "ShapeCache.dataset",
        lambda: CACHE.dataset("train", "depth"),
        ARG,
        r"^representations: got \['depth'\] not in the cache",
    ),
    Case(
        "ShapeCache.dataset",
        lambda: CACHE.dataset(indices=[0], partial=1),  # type: ignore[arg-type]
        ARG,
        r"^partial: got 1",
    ),
    Case(
        "ShapeCache.dataset",
        lambda: CACHE.dataset(indices=[9]),
        ARG,
        r"^indices: got values in \[9, 9\]",
        "index",
    ),
    # -- training
    Case("ShapeRecipe", lambda: ShapeRecipe(val_fraction=1.0), ARG, r"^val_fraction: got 1\.0"),
    Case("ShapeRecipe", lambda: ShapeRecipe(rotate="yes"), ARG, r"^rotate: got 'yes'", "rotate"),  # type: ignore[arg-type]
    Case(
        "ShapeRecipe",
        lambda: ShapeRecipe(representations=("nurbs",)),
        ARG,
        r"^representations",
        "reps",
    ),
    Case("default_config", lambda: default_config(lr=-1), ARG, r"^lr: got -1"),
    Case(
        "train_shapes",
        lambda: train_shapes(CACHE, TMP / "t", recipe="fast"),
        ARG,
        r"^recipe: got str",
    ),  # type: ignore[arg-type]
    Case(
        "train_shapes",
        lambda: train_shapes(CACHE, TMP / "t", recipe=ShapeRecipe(("depth",))),
        ARG,
        r"^representations: got \['depth'\] not in the cache",
        "reps",
    ),
    Case(
        "train_shapes",
        lambda: train_shapes(TMP / "tree", TMP / "t"),
        RgbdError,
        r"tree: no meta\.json",
        "cache",
    ),
    Case(
        "train_ablation",
        lambda: train_ablation(CACHE, TMP / "t", config="fast"),
        ARG,
        r"^config: got str",
    ),  # type: ignore[arg-type]
    Case(
        "ablation_rows",
        lambda: ablation_rows(("depth", "colour")),
        ARG,
        r"^representations: got unknown",
    ),
    Case("ship", lambda: ship(TMP / "garbage.pt", TMP / "s.pt"), RgbdError, r"garbage\.pt"),
    Case(
        "ship",
        lambda: ship(OTHER, TMP / "s.pt"),
        RgbdError,
        r"o\.pt: checkpoint of architecture 'other/1'",
        "arch",
    ),
    Case("ship", lambda: ship(CKPT), ARG, r"^dest: none given for a 2-class checkpoint", "dest"),
    # -- classification and evaluation
    Case(
        "ShapeClassifier",
        lambda: ShapeClassifier(NET, SPEC, ("a",)),
        ARG,
        r"^classes: got 1 names, expected 2",
    ),
    Case(
        "ShapeClassifier",
        lambda: ShapeClassifier("net", SPEC, ("a", "b")),
        ARG,
        r"^net: got str",
        "net",
    ),  # type: ignore[arg-type]
    Case(
        "ShapeClassifier.load",
        lambda: ShapeClassifier.load(TMP / "garbage.pt"),
        RgbdError,
        r"garbage\.pt: not a readable",
    ),
    Case(
        "ShapeClassifier.load",
        lambda: ShapeClassifier.load(TMP / "none.pt"),
        RgbdError,
        r"none\.pt: checkpoint file not found",
        "missing",
    ),
    Case(
        "ShapeClassifier.load",
        lambda: ShapeClassifier.load(OTHER),
        RgbdError,
        r"o\.pt: checkpoint of architecture",
        "arch",
    ),
    Case(
        "ShapeClassifier.load",
        lambda: ShapeClassifier.load(CKPT, dataset="modelnet10"),
        ARG,
        r"^path: got .* together with dataset=.modelnet10.",
        "both",
    ),
    Case(
        "ShapeClassifier.probabilities",
        lambda: CLF.probabilities([EMPTY]),
        ARG,
        r"^shapes\[0\]: got a mesh with no triangles",
    ),
    Case(
        "ShapeClassifier.probabilities",
        lambda: CLF.probabilities([TMP / "junk.off"]),
        RgbdError,
        r"junk\.off: not a valid OFF",
        "file",
    ),
    Case(
        "ShapeClassifier.probabilities",
        lambda: CLF.probabilities(P),
        ARG,
        r"^shapes: got ndarray",
        "type",
    ),  # type: ignore[arg-type]
    Case(
        "ShapeClassifier.probabilities_of_inputs",
        lambda: CLF.probabilities_of_inputs({"volume": np.zeros((1, 3, 8, 8))}),
        SHAPE,
        r"^inputs\['volume'\]",
    ),
    Case(
        "classify",
        lambda: classify(TMP / "junk.off", checkpoint=CKPT),
        RgbdError,
        r"junk\.off: not a valid OFF mesh",
    ),
    Case(
        "classify",
        lambda: classify(np.array([[np.nan, 0, 0]]), checkpoint=CKPT),
        ARG,
        r"^shape: got 1 non-finite",
        "nan",
    ),
    Case(
        "classify",
        lambda: classify(np.zeros((4, 3), np.float32), checkpoint=CKPT, up="-z"),
        ARG,
        r"^up: got '-z', expected one of",
        "up",
    ),
    Case(
        "classify",
        lambda: classify(np.ones((1024, 3), np.float32), checkpoint=CKPT),
        ARG,
        r"^shape: got 1024 points that all lie on one point, expected a 3-D shape",
        "one point",
    ),
    Case(
        "classify",
        lambda: classify(np.outer(np.arange(50.0), [1.0, 2.0, -1.0]), checkpoint=CKPT),
        ARG,
        r"^shape: got 50 points that all lie on one line",
        "line",
    ),
    Case(
        "classify",
        lambda: classify(
            Mesh(np.ones((3, 3), np.float32), np.array([[0, 1, 2]], np.uint32)), checkpoint=CKPT
        ),
        ARG,
        r"^shape: got a mesh whose 1 triangle\(s\) all have zero area",
        "degenerate triangle",
    ),
    Case(
        "to_z_up",
        lambda: to_z_up(np.zeros((4, 3), np.float32), "up"),
        ARG,
        r"^up: got 'up', expected one of",
    ),
    Case(
        "classify",
        lambda: classify(EMPTY, checkpoint=CKPT),
        ARG,
        r"^shape: got a mesh with no triangles",
        "empty",
    ),
    Case(
        "classify",
        lambda: classify(P, checkpoint=TMP / "garbage.pt"),
        RgbdError,
        r"garbage\.pt",
        "ckpt",
    ),
    Case(
        "classify",
        lambda: classify(P, dataset="shapenet"),
        ARG,
        r"^dataset: got 'shapenet'",
        "dataset",
    ),
    Case("classify", lambda: classify(P, checkpoint=3), ARG, r"^checkpoint: got 3", "type"),  # type: ignore[arg-type]
    Case("_weights_path", lambda: _weights_path("modelnet20"), ARG, r"^dataset: got 'modelnet20'"),
    Case("evaluate", lambda: evaluate(TMP / "garbage.pt", CACHE), RgbdError, r"garbage\.pt"),
    Case("evaluate", lambda: evaluate(CLF, CACHE, split="val"), ARG, r"^split: got 'val'", "split"),
    Case(
        "evaluate", lambda: evaluate(CLF, CACHE, batch_size=0), ARG, r"^batch_size: got 0", "batch"
    ),
    Case(
        "evaluate",
        lambda: evaluate(
            ShapeClassifier(
                ShapeNet(3, representations=("volume",), width=2), SPEC, ("a", "b", "c")
            ),
            CACHE,
        ),
        RgbdError,
        r"does not fit the cache .*classes",
        "classes",
    ),
    Case("ShapeEvaluation.write", lambda: EVAL.write(TMP / "junk.off"), RgbdError, r"junk\.off"),
    Case("ablation_markdown", lambda: ablation_markdown({}), ARG, r"^results"),
    Case(
        "ablation_markdown",
        lambda: ablation_markdown({"m": [1]}),
        ARG,
        r"^results\['m'\]: got int",
        "type",
    ),  # type: ignore[list-item]
    Case("row_name", lambda: row_name(["colour"]), ARG, r"^representations: got unknown"),
]


#: What the meta-test counts: the cases of names the package exports (the rest still run).
CASES: list[Case] = public_cases(ALL_CASES)


@pytest.mark.parametrize("case", params(ALL_CASES))
def test_bad_input(case: Case) -> None:
    check(case)


def test_a_dense_cloud_is_classified_from_a_seeded_subset_of_the_network_size() -> None:
    # The network saw 1024-point clouds; a 2M-point scan is cut to that many (it took minutes).
    from rgbd_rs.shapes.classify import SAMPLE_SEED

    n = CLF.points_per_shape or 1024
    dense = np.random.default_rng(3).normal(size=(20 * n, 3)).astype(np.float32)
    pick = np.sort(np.random.default_rng(SAMPLE_SEED).choice(len(dense), n, replace=False))
    np.testing.assert_array_equal(CLF.probabilities([dense]), CLF.probabilities([dense[pick]]))
    assert not np.array_equal(CLF.probabilities([dense]), CLF.probabilities([dense[:n]]))


def test_a_cloud_files_non_finite_points_are_dropped_with_a_warning(tmp_path: Path) -> None:
    # An organised depth-camera cloud marks its holes with NaN: a file's are dropped (warned),
    # an array given in Python is refused with the way to drop them.
    pts = np.random.default_rng(0).random((50, 3))
    pts[[3, 7]] = np.nan
    np.save(tmp_path / "holes.npy", pts)
    with pytest.warns(RuntimeWarning, match=r"holes\.npy: dropped 2 of 50 points that are not"):
        got = load_shape(tmp_path / "holes.npy")
    assert isinstance(got, np.ndarray) and got.shape == (48, 3)
    with pytest.raises(InvalidArgumentError, match=r"drop the non-finite points first"):
        shape_inputs(pts, SPEC)


def test_a_ply_clouds_non_finite_points_are_dropped_too(tmp_path: Path) -> None:
    pts = np.random.default_rng(0).random((20, 3))
    pts[5] = np.nan
    rows = "\n".join(" ".join("nan" if np.isnan(v) else f"{v:.5f}" for v in p) for p in pts)
    head = "ply\nformat ascii 1.0\nelement vertex 20\nproperty float x\nproperty float y\n"
    (tmp_path / "c.ply").write_text(head + f"property float z\nend_header\n{rows}\n")
    with pytest.warns(RuntimeWarning, match=r"c\.ply: dropped 1 of 20 points"):
        got = load_shape(tmp_path / "c.ply")
    assert isinstance(got, np.ndarray) and got.shape == (19, 3)


def test_coordinates_beyond_float32_are_not_called_holes(tmp_path: Path) -> None:
    # Finite float64 values that overflow float32 are out of range, not non-finite points to
    # drop (and no numpy overflow warning leaks: the suite turns warnings into errors).
    pts = np.random.default_rng(0).random((20, 3))
    pts[:2] *= 1e300
    np.save(tmp_path / "far.npy", pts)
    with pytest.raises(RgbdError, match=r"far\.npy: got 6 values beyond float32's range"):
        load_shape(tmp_path / "far.npy")
    with pytest.raises(InvalidArgumentError, match=r"^shape: got 6 values beyond float32's range"):
        shape_inputs(pts, SPEC)
