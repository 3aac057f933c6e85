"""Scaled copies that also lose points (``ScaledCopies(drop=)``, ``rgbd shapes cache
--copy-drop``): a copy keeps a subset of exactly the points it has without the option, the
fraction follows U(0, drop), meshes keep every vertex, and what the cache records."""

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
from rgbd_rs.shapes.scaling import MAX_DROP, ScaledCopies

NORM = "lcn" if D._lcn() is not None else "standardize"
VOLUME = InputSpec(representations=("volume",), normalisation=NORM)


@pytest.fixture(scope="module")
def pack(tmp_path_factory: pytest.TempPathFactory, shared_data: Path) -> Path:
    """10 shapes of the real ModelNet10 pack: 2 classes x (3 train + 2 test)."""
    path = tmp_path_factory.mktemp("drop") / "mini.npz"
    return modelnet10_subset(shared_data, path, (0, 8), ((0, 3), (1, 2)))


def test_a_copy_keeps_a_subset_of_the_same_moved_points(pack: Path) -> None:
    base = PointCloudSet(pack)
    plain = ScaledCopies(base, 4, seed=2, turn=10.0, jitter=0.01)
    dropped = ScaledCopies(base, 4, seed=2, turn=10.0, jitter=0.01, drop=0.875)
    assert "copy_drop" not in plain.augmentation
    assert dropped.augmentation["copy_drop"] == 0.875
    for i in range(len(base)):  # originals untouched
        np.testing.assert_array_equal(dropped.load(i), plain.load(i))
    kept = []
    for i in range(len(base), len(dropped)):
        full = np.asarray(plain.load(i))
        keep = dropped.kept(i, len(full))
        np.testing.assert_array_equal(dropped.load(i), full[keep])
        np.testing.assert_array_equal(dropped.kept(i, len(full)), keep)  # deterministic
        kept.append(keep.mean())
    # 24 copies, each keeping 1 - U(0, 0.875) of its 1024 points: between 12.5 % and all, and
    # not all the same fraction.
    assert min(kept) > 0.1 and max(kept) <= 1.0 and np.ptp(kept) > 0.2
    assert 0.45 < np.mean(kept) < 0.75  # E = 1 - 0.875 / 2 = 0.56


def test_at_least_one_point_stays_and_the_limit(pack: Path) -> None:
    src = ScaledCopies(PointCloudSet(pack), 2, drop=MAX_DROP)
    n = len(src.base)
    assert all(src.kept(i, 1).sum() == 1 for i in range(n, len(src)))
    assert all(src.kept(i, 0).size == 0 for i in range(n, len(src)))
    with pytest.raises(RgbdError, match=r"drop: got 0\.96, expected 0 <= drop <= 0\.95"):
        ScaledCopies(PointCloudSet(pack), 1, drop=0.96)
    with pytest.raises(RgbdError, match=r"drop"):
        ScaledCopies(PointCloudSet(pack), 1, drop=-0.1)


def test_mesh_copies_keep_every_vertex() -> None:
    m = ScaledCopies(Boxes((1.0, 2.0, 3.0)), 1, drop=0.9).load(2)
    want = ScaledCopies(Boxes((1.0, 2.0, 3.0)), 1).load(2)
    assert isinstance(m, Mesh) and isinstance(want, Mesh)
    np.testing.assert_array_equal(m.vertices, want.vertices)
    np.testing.assert_array_equal(m.triangles, want.triangles)


def test_cache_records_drop_and_the_cli_flag(
    pack: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    from rgbd_rs.cli import main

    out = tmp_path / "c"
    argv = ["shapes", "cache", "--data", str(pack), "--out", str(out), "--quiet"]
    argv += ["--representations", "volume", "--normalisation", NORM, "--workers", "1"]
    assert main([*argv, "--scale-copies", "1", "--copy-drop", "0.5"]) == 0
    assert json.loads((out / "meta.json").read_text())["augmentation"]["copy_drop"] == 0.5
    want = build_cache(
        ScaledCopies(PointCloudSet(pack), 1, drop=0.5),
        tmp_path / "ref",
        spec=VOLUME,
        workers=1,
        quiet=True,
    )
    plain = build_cache(
        ScaledCopies(PointCloudSet(pack), 1), tmp_path / "plain", spec=VOLUME, workers=1, quiet=True
    )
    got = D.ShapeCache(out).array("volume")
    np.testing.assert_array_equal(got, want.array("volume"))
    assert not np.array_equal(got, plain.array("volume")), "the copies lost points"
    np.testing.assert_array_equal(got[:10], plain.array("volume")[:10])  # originals
    with pytest.raises(RgbdError, match=r"augmentation.*copy_drop"):
        build_cache(ScaledCopies(PointCloudSet(pack), 1), out, spec=VOLUME, workers=1, quiet=True)
    capsys.readouterr()
    bad = ["shapes", "cache", "--data", str(pack), "--out", str(tmp_path / "b"), "--quiet"]
    assert main([*bad, "--copy-drop", "0.5"]) == 2
    assert "--copy-drop: got 0.5 without --scale-copies" in capsys.readouterr().err
    with pytest.raises(SystemExit) as exc:
        main([*bad, "--scale-copies", "1", "--copy-drop", "1"])
    assert exc.value.code == 2
    assert "--copy-drop: got 1, expected a number >= 0 and <= 0.95" in capsys.readouterr().err
