"""Scaled copies of training shapes (rgbd_rs.shapes.scaling): what the source serves, what the
cache records, and the validation split that keeps copies with their originals."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

import rgbd_rs.shapes.dataset as D
from modelnet_packs import Boxes, modelnet10_subset
from rgbd_rs.errors import RgbdError
from rgbd_rs.meshes import Mesh
from rgbd_rs.shapes.dataset import InputSpec, PointCloudSet, build_cache
from rgbd_rs.shapes.scaling import SCALE_RANGE, ScaledCopies, original_name, original_rows
from rgbd_rs.shapes.train import _split_by_shape

NORM = "lcn" if D._lcn() is not None else "standardize"
VOLUME = InputSpec(representations=("volume",), normalisation=NORM)


@pytest.fixture(scope="module")
def pack(tmp_path_factory: pytest.TempPathFactory, shared_data: Path) -> Path:
    """10 shapes of the real ModelNet10 pack: 2 classes x (3 train + 2 test)."""
    path = tmp_path_factory.mktemp("scaling") / "mini.npz"
    return modelnet10_subset(shared_data, path, (0, 8), ((0, 3), (1, 2)))


def test_copies_of_training_shapes_only(pack: Path) -> None:
    base = PointCloudSet(pack)
    src = ScaledCopies(base, 2, seed=3)
    train = np.flatnonzero(base.splits == 0)
    assert len(src) == len(base) + 2 * len(train)
    assert src.names[: len(base)] == base.names
    assert src.names[len(base)] == f"{base.names[train[0]]}#s1"
    assert src.names[-1] == f"{base.names[train[-1]]}#s2"
    assert (src.splits[len(base) :] == 0).all(), "test shapes are never copied"
    np.testing.assert_array_equal(src.labels[len(base) :], np.tile(base.labels[train], 2))
    np.testing.assert_array_equal(src.load(4), base.load(4))
    scales = []
    for i in range(len(base), len(src)):
        k = base.names.index(original_name(src.names[i]))
        s = src.scale(i)
        assert ((s >= SCALE_RANGE[0]) & (s <= SCALE_RANGE[1])).all()
        np.testing.assert_allclose(src.load(i), base.load(k) * s, rtol=1e-6)
        scales.append(s)
    assert len({tuple(s) for s in scales}) == len(scales), "every copy its own factors"
    again = ScaledCopies(PointCloudSet(pack), 2, seed=3)
    np.testing.assert_array_equal(again.load(len(src) - 1), src.load(len(src) - 1))
    other = ScaledCopies(base, 2, seed=4)
    assert not np.allclose(other.scale(len(base)), src.scale(len(base)))


def test_meshes_are_scaled_too() -> None:
    src = ScaledCopies(Boxes(), 1, scale_range=(0.5, 2.0))
    assert len(src) == 3 and src.names[2] == "a#s1"
    m = src.load(2)
    assert isinstance(m, Mesh)
    lo, hi = m.bounds()
    np.testing.assert_allclose(hi - lo, src.scale(2), rtol=1e-6)


def test_cache_records_the_copies(pack: Path, tmp_path: Path) -> None:
    src = ScaledCopies(PointCloudSet(pack), 1)
    cache = build_cache(src, tmp_path / "c", spec=VOLUME, workers=1, quiet=True)
    assert cache.complete and len(cache) == 16
    meta = json.loads((tmp_path / "c" / "meta.json").read_text())
    assert meta["augmentation"] == {
        "scale_copies": 1,
        "scale_range": list(SCALE_RANGE),
        "scale_seed": 0,
        "originals": 10,
    }
    vol = cache.array("volume")
    assert not np.array_equal(vol[10], vol[0]), "a copy's profiles differ from its original's"
    with pytest.raises(RgbdError, match=r"other data or settings.*augmentation"):
        build_cache(PointCloudSet(pack), tmp_path / "c", spec=VOLUME, workers=1, quiet=True)
    with pytest.raises(RgbdError, match=r"augmentation.*'scale_seed': 0.*'scale_seed': 1"):
        build_cache(
            ScaledCopies(PointCloudSet(pack), 1, seed=1),
            tmp_path / "c",
            spec=VOLUME,
            workers=1,
            quiet=True,
        )
    # Validation: originals only, never a copy of a validation shape in training.
    data = cache.dataset("train")
    train, val = _split_by_shape(cache, data, 0.34, 0)
    names = [cache.names[int(data.indices[i])] for i in range(len(data))]
    val_names = {names[i] for i in val.indices}
    assert val_names and all("#" not in n for n in val_names)
    assert not {original_name(names[i]) for i in train.indices} & val_names
    assert len(train) + 2 * len(val) == len(data)


def test_copies_follow_their_original_by_row_not_by_name(pack: Path, tmp_path: Path) -> None:
    # Two training shapes share a name: validating one must not drop the other or its copies.
    d = dict(np.load(pack))
    d["name"] = np.where(d["name"] == d["name"][1], d["name"][0], d["name"])
    dup = tmp_path / "dup.npz"
    np.savez(dup, **d)
    cache = build_cache(
        ScaledCopies(PointCloudSet(dup), 2), tmp_path / "c", spec=VOLUME, workers=1, quiet=True
    )
    data = cache.dataset("train")
    for seed in range(6):
        train, val = _split_by_shape(cache, data, 0.2, seed)
        assert len(train) + 3 * len(val) == len(data) == 18
        rows = np.asarray(data.indices)
        origin = original_rows(cache.meta["augmentation"], cache.splits)
        held = set(rows[val.indices].tolist())
        assert all(origin[rows[i]] not in held for i in train.indices)
        assert all(origin[rows[i]] == rows[i] for i in val.indices), "validation: originals only"


def test_too_few_originals_to_validate(tmp_path: Path) -> None:
    cache = build_cache(ScaledCopies(Boxes(), 3), tmp_path / "b", spec=VOLUME, quiet=True)
    with pytest.raises(RgbdError, match=r"1 original training shape\(s\) \(\+3 scaled copies\)"):
        _split_by_shape(cache, cache.dataset("train"), 0.1, 0)


def test_without_copies_the_split_is_the_trainers(pack: Path, tmp_path: Path) -> None:
    from rgbd_rs.nn.train import split

    d = dict(np.load(pack))
    d["name"] = np.char.add(d["name"], "#x")  # a '#' in a name is not a copy
    named = tmp_path / "named.npz"
    np.savez(named, **d)
    cache = build_cache(PointCloudSet(named), tmp_path / "c", spec=VOLUME, workers=1, quiet=True)
    data = cache.dataset("train")
    for seed in range(4):
        a, b = _split_by_shape(cache, data, 0.34, seed)
        a2, b2 = split(data, 0.34, seed=seed)
        assert (a.indices, b.indices) == (a2.indices, b2.indices)


def test_excluded_names_and_their_copies_are_neither_trained_nor_validated(
    pack: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    import importlib

    from rgbd_rs.errors import InvalidArgumentError
    from rgbd_rs.nn.train import TrainConfig
    from rgbd_rs.shapes.train import ShapeRecipe, train_shapes

    cache = build_cache(
        ScaledCopies(PointCloudSet(pack), 2), tmp_path / "c", spec=VOLUME, workers=1, quiet=True
    )
    seen: dict[str, list[str]] = {}

    class Stop(Exception):
        pass

    def spy(model: object, train_set: object, val_set: object, *a: object, **k: object) -> None:
        for side, subset in (("train", train_set), ("val", val_set)):
            rows = np.asarray(subset.dataset.indices)[subset.indices]  # type: ignore[attr-defined]
            seen[side] = [cache.names[int(r)] for r in rows]
        raise Stop

    # rgbd_rs.nn re-exports the function train, which hides the module of that name
    monkeypatch.setattr(importlib.import_module("rgbd_rs.nn.train"), "train", spy)
    cfg = TrainConfig(epochs=1, batch_size=2, device="cpu", seed=0)
    data = cache.dataset("train")
    _, val = _split_by_shape(cache, data, 0.34, 0)
    val_names = [cache.names[int(data.indices[i])] for i in val.indices]
    train_names = [n for n in cache.names[:10] if n not in val_names]
    train_idx = [i for i in range(10) if cache.splits[i] == 0 and cache.names[i] in train_names]
    drop = (val_names[0], cache.names[train_idx[0]])
    recipe = ShapeRecipe(width=4, val_fraction=0.34, split_seed=0, exclude=list(drop))
    with pytest.raises(Stop):
        train_shapes(cache, tmp_path / "run", recipe=recipe, config=cfg, quiet=True)
    assert not {original_name(n) for n in seen["train"] + seen["val"]} & set(drop)
    assert set(seen["val"]) == set(val_names) - set(drop), "the rest of the split unchanged"
    assert len(seen["train"]) == len(data) - 3 * len(val_names) - 3
    for bad, pattern in (
        (["no_such_shape"], r"^exclude: 1 name\(s\) are not training shapes of .*no_such_shape"),
        ([cache.names[int(np.flatnonzero(cache.splits == 1)[0])]], r"^exclude: 1 name\(s\)"),
    ):
        with pytest.raises(InvalidArgumentError, match=pattern):
            train_shapes(
                cache,
                tmp_path / "bad",
                recipe=ShapeRecipe(width=4, val_fraction=0.34, exclude=bad),
                config=cfg,
                quiet=True,
            )
    with pytest.raises(InvalidArgumentError, match=r"^exclude: got str"):
        ShapeRecipe(exclude="chair_0001")  # type: ignore[arg-type]
    with pytest.raises(InvalidArgumentError, match=r"^exclude: got ''"):
        ShapeRecipe(exclude=[""])


def test_exclude_refuses_a_name_that_names_two_shapes(pack: Path, tmp_path: Path) -> None:
    from rgbd_rs.errors import InvalidArgumentError
    from rgbd_rs.nn.train import TrainConfig
    from rgbd_rs.shapes.train import ShapeRecipe, train_shapes

    d = dict(np.load(pack))
    d["name"] = np.where(d["name"] == d["name"][1], d["name"][0], d["name"])
    dup = tmp_path / "dup.npz"
    np.savez(dup, **d)
    cache = build_cache(PointCloudSet(dup), tmp_path / "c", spec=VOLUME, workers=1, quiet=True)
    recipe = ShapeRecipe(width=4, val_fraction=0, exclude=[str(d["name"][0])])
    cfg = TrainConfig(epochs=1, batch_size=2, device="cpu")
    with pytest.raises(InvalidArgumentError, match=r"^exclude: '.*' names 2 training shapes"):
        train_shapes(cache, tmp_path / "r", recipe=recipe, config=cfg, quiet=True)


def test_cli_scale_range(pack: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """`rgbd shapes cache --scale-range LOW HIGH`: the copies' factors come from it and the cache
    records it (a resume with another range is refused); a bad range names the flag."""
    from rgbd_rs.cli import main

    out = tmp_path / "c"
    argv = ["shapes", "cache", "--data", str(pack), "--out", str(out), "--quiet"]
    argv += ["--representations", "volume", "--normalisation", NORM, "--workers", "1"]
    copies = ["--scale-copies", "2"]
    assert main([*argv, *copies, "--scale-range", "0.9", "1.1"]) == 0
    meta = json.loads((out / "meta.json").read_text())
    assert meta["augmentation"]["scale_range"] == [0.9, 1.1]
    src = ScaledCopies(PointCloudSet(pack), 2, scale_range=(0.9, 1.1))
    factors = np.array([src.scale(i) for i in range(10, len(src))])
    assert ((factors >= 0.9) & (factors <= 1.1)).all()
    vol = D.ShapeCache(out).array("volume")
    ref = build_cache(src, tmp_path / "ref", spec=VOLUME, workers=1, quiet=True).array("volume")
    np.testing.assert_array_equal(vol, ref)
    capsys.readouterr()
    assert main([*argv, *copies]) == 2, "a resume must repeat the range"
    assert "augmentation" in capsys.readouterr().err
    bad = tmp_path / "bad"
    bad_argv = ["shapes", "cache", "--data", str(pack), "--out", str(bad), "--quiet"]
    assert main([*bad_argv, *copies, "--scale-range", "2", "1"]) == 2
    err = capsys.readouterr().err
    assert "--scale-range: got (2.0, 1.0), expected 0.001 <= low <= high" in err
    assert main([*bad_argv, "--scale-range", "0.8", "1.25"]) == 2
    assert "--scale-range: got 0.8 1.25 without --scale-copies" in capsys.readouterr().err
    with pytest.raises(SystemExit) as exc:  # argparse's own refusal
        main([*bad_argv, *copies, "--scale-range", "0", "1"])
    assert exc.value.code == 2
    assert "--scale-range: got 0, expected a number >= 0.001" in capsys.readouterr().err
