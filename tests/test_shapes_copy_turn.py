"""Scaled copies that are also turned about z and jittered (``ScaledCopies(turn=, jitter=)``,
``rgbd shapes cache --copy-turn / --copy-jitter``): what a copy is, that the scale factors stay
those of a cache without them, units invariance, and what the cache records."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

import rgbd_rs.shapes.dataset as D
from modelnet_packs import Boxes, modelnet10_subset
from rgbd_rs.errors import RgbdError
from rgbd_rs.meshes import Mesh, box
from rgbd_rs.shapes.dataset import InputSpec, PointCloudSet, ShapeSource, build_cache
from rgbd_rs.shapes.scaling import JITTER_CLIP, ScaledCopies

NORM = "lcn" if D._lcn() is not None else "standardize"
VOLUME = InputSpec(representations=("volume",), normalisation=NORM)


@pytest.fixture(scope="module")
def pack(tmp_path_factory: pytest.TempPathFactory, shared_data: Path) -> Path:
    """10 shapes of the real ModelNet10 pack: 2 classes x (3 train + 2 test)."""
    path = tmp_path_factory.mktemp("turn") / "mini.npz"
    return modelnet10_subset(shared_data, path, (0, 8), ((0, 3), (1, 2)))


def _turned(p: np.ndarray, degrees: float) -> np.ndarray:
    a = np.deg2rad(degrees)
    x, y = p[:, 0], p[:, 1]
    return np.stack([np.cos(a) * x - np.sin(a) * y, np.sin(a) * x + np.cos(a) * y, p[:, 2]], 1)


def test_off_by_default_and_the_same_scale_factors(pack: Path) -> None:
    plain = ScaledCopies(PointCloudSet(pack), 2, seed=3)
    turned = ScaledCopies(PointCloudSet(pack), 2, seed=3, turn=20.0, jitter=0.01)
    assert set(plain.augmentation) == {"scale_copies", "scale_range", "scale_seed", "originals"}
    assert turned.augmentation["copy_turn"] == 20.0
    assert turned.augmentation["copy_jitter"] == 0.01
    for i in range(len(plain)):
        np.testing.assert_array_equal(turned.scale(i), plain.scale(i))
        assert plain.turn_angle(i) == 0.0
    np.testing.assert_array_equal(turned.load(4), plain.load(4))  # originals untouched
    assert turned.turn_angle(4) == 0.0


def test_a_copy_is_scaled_then_turned_about_z(pack: Path) -> None:
    base = PointCloudSet(pack)
    src = ScaledCopies(base, 3, seed=1, turn=30.0)
    angles = []
    for i in range(len(base), len(src)):
        k = base.names.index(src.names[i].split("#")[0])
        a = src.turn_angle(i)
        assert -30.0 <= a <= 30.0
        angles.append(a)
        want = _turned(np.asarray(base.load(k), np.float64) * src.scale(i), a)
        np.testing.assert_allclose(np.asarray(src.load(i)), want, rtol=1e-5, atol=1e-6)
    assert len(set(angles)) == len(angles) and max(map(abs, angles)) > 5.0
    again = ScaledCopies(PointCloudSet(pack), 3, seed=1, turn=30.0)
    np.testing.assert_array_equal(again.load(len(src) - 1), src.load(len(src) - 1))


def test_jitter_is_relative_to_the_shape_and_clipped(pack: Path) -> None:
    base = PointCloudSet(pack)
    plain = ScaledCopies(base, 1)
    shaky = ScaledCopies(base, 1, jitter=0.02)
    i = len(base)
    p = np.asarray(plain.load(i), np.float64)
    radius = np.linalg.norm(p - p.mean(0), axis=1).max()
    d = np.asarray(shaky.load(i)) - p
    assert abs(d.std() / (0.02 * radius) - 1.0) < 0.1
    assert np.abs(d).max() <= JITTER_CLIP * 0.02 * radius * (1 + 1e-5)

    class _Big(ShapeSource):  # the same shapes in millimetres
        kind = "points"
        path, classes, labels, splits, names = (
            base.path,
            base.classes,
            base.labels,
            base.splits,
            base.names,
        )

        def load(self, index: int) -> np.ndarray:
            return base.load(index).astype(np.float32) * 1000.0

    big = ScaledCopies(_Big(), 1, jitter=0.02, turn=10.0)
    small = ScaledCopies(base, 1, jitter=0.02, turn=10.0)
    got = np.asarray(big.load(i)) / 1000.0
    np.testing.assert_allclose(got, np.asarray(small.load(i)), rtol=1e-4, atol=1e-5)


def test_mesh_copies_move_vertices_and_keep_triangles() -> None:
    src = ScaledCopies(Boxes((1.0, 2.0, 3.0)), 1, turn=45.0, jitter=0.01)
    m = src.load(2)
    assert isinstance(m, Mesh)
    orig = box((1.0, 2.0, 3.0))
    np.testing.assert_array_equal(m.triangles, orig.triangles)
    want = _turned(orig.vertices.astype(np.float64) * src.scale(2), src.turn_angle(2))
    assert not np.allclose(m.vertices, want, atol=1e-6), "jittered"
    np.testing.assert_allclose(m.vertices, want, atol=JITTER_CLIP * 0.01 * 3.0)


def test_cache_records_turn_and_jitter(pack: Path, tmp_path: Path) -> None:
    src = ScaledCopies(PointCloudSet(pack), 1, turn=10.0, jitter=0.01)
    build_cache(src, tmp_path / "c", spec=VOLUME, workers=1, quiet=True)
    aug = json.loads((tmp_path / "c" / "meta.json").read_text())["augmentation"]
    assert aug["copy_turn"] == 10.0 and aug["copy_jitter"] == 0.01
    with pytest.raises(RgbdError, match=r"augmentation.*copy_turn"):
        build_cache(
            ScaledCopies(PointCloudSet(pack), 1, jitter=0.01),
            tmp_path / "c",
            spec=VOLUME,
            workers=1,
            quiet=True,
        )


def test_cli_flags(pack: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    from rgbd_rs.cli import main

    out = tmp_path / "c"
    argv = ["shapes", "cache", "--data", str(pack), "--out", str(out), "--quiet"]
    argv += ["--representations", "volume", "--normalisation", NORM, "--workers", "1"]
    assert main([*argv, "--scale-copies", "1", "--copy-turn", "15", "--copy-jitter", "0.01"]) == 0
    aug = json.loads((out / "meta.json").read_text())["augmentation"]
    assert (aug["copy_turn"], aug["copy_jitter"]) == (15.0, 0.01)
    ref = ScaledCopies(PointCloudSet(pack), 1, turn=15.0, jitter=0.01)
    want = build_cache(ref, tmp_path / "ref", spec=VOLUME, workers=1, quiet=True)
    np.testing.assert_array_equal(D.ShapeCache(out).array("volume"), want.array("volume"))
    capsys.readouterr()
    bad = ["shapes", "cache", "--data", str(pack), "--out", str(tmp_path / "b"), "--quiet"]
    assert main([*bad, "--copy-turn", "5"]) == 2
    assert "--copy-turn: got 5 without --scale-copies" in capsys.readouterr().err
    assert main([*bad, "--copy-jitter", "0.01"]) == 2
    assert "--copy-jitter: got 0.01 without --scale-copies" in capsys.readouterr().err
    with pytest.raises(SystemExit) as exc:
        main([*bad, "--scale-copies", "1", "--copy-turn", "181"])
    assert exc.value.code == 2
    assert "--copy-turn: got 181, expected a number >= 0 and <= 180" in capsys.readouterr().err
