"""Shape datasets and the representation cache (rgbd_rs.shapes.dataset): the ModelNet point
packs, a fabricated Princeton OFF tree of real meshes, single-file readers, the inputs of one
shape and of a batch, and the resumable, sharded cache."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import numpy as np
import pytest
import torch
import trimesh

import rgbd_rs.shapes.dataset as D
from modelnet_packs import modelnet10_subset
from rgbd_rs.errors import RgbdError
from rgbd_rs.meshes import Mesh, box, load_mesh, sphere
from rgbd_rs.shapes import density_profiles, voxelize
from rgbd_rs.shapes.dataset import (
    InputSpec,
    OffTree,
    PointCloudSet,
    ShapeCache,
    available_representations,
    batch_inputs,
    build_cache,
    load_shape,
    open_shapes,
    sample_surface,
    shape_inputs,
)

#: LCN when this installation has it (rgbd_rs.shapes.views), else the global standardisation.
NORM = "lcn" if D._lcn() is not None else "standardize"
VOLUME = InputSpec(representations=("volume",), normalisation=NORM)


@pytest.fixture(scope="module")
def off_tree(tmp_path_factory: pytest.TempPathFactory, shared_data: Path) -> Path:
    """ModelNet10's layout with the shared real meshes: bathtub (3 train, 2 test), bunny (1, 1)."""
    root = tmp_path_factory.mktemp("modelnet_tree")
    meshes = shared_data / "meshes"
    for i in range(1, 6):
        split = "train" if i <= 3 else "test"
        dest = root / "bathtub" / split / f"bathtub_000{i}.off"
        dest.parent.mkdir(parents=True, exist_ok=True)
        shutil.copy(meshes / f"modelnet10_bathtub_000{i}.off", dest)
    for split in ("train", "test"):
        (root / "bunny" / split).mkdir(parents=True)
        shutil.copy(meshes / "stanford_bunny.off", root / "bunny" / split / f"bunny_{split}.off")
    (root / "README.txt").write_text("not a class")
    return root


@pytest.fixture(scope="module")
def mini_pack(tmp_path_factory: pytest.TempPathFactory, shared_data: Path) -> Path:
    """12 shapes of the real ModelNet10 pack (2 classes x (4 train + 2 test))."""
    path = tmp_path_factory.mktemp("mini_pack") / "mini.npz"
    return modelnet10_subset(shared_data, path, (0, 8), ((0, 4), (1, 2)))


def test_modelnet_packs_have_the_official_splits(shared_data: Path) -> None:
    m10 = open_shapes("modelnet10")
    assert isinstance(m10, PointCloudSet) and m10.kind == "points"
    assert len(m10.classes) == 10 and m10.classes[0] == "bathtub"
    assert int((m10.splits == 0).sum()) == 3991 and int((m10.splits == 1).sum()) == 908
    p = m10.load(0)
    assert p.shape == (1024, 3) and p.dtype == np.float32
    assert m10.names[0].startswith(m10.classes[m10.labels[0]])


def test_off_tree_is_read_like_modelnet(off_tree: Path) -> None:
    tree = open_shapes(off_tree)
    assert isinstance(tree, OffTree) and tree.kind == "mesh"
    assert tree.classes == ("bathtub", "bunny")
    assert list(tree.labels) == [0, 0, 0, 0, 0, 1, 1]
    assert list(tree.splits) == [0, 0, 0, 1, 1, 0, 1]  # per class: train, then test
    assert tree.names[:3] == ("bathtub_0001", "bathtub_0002", "bathtub_0003")
    mesh = tree.load(0)
    assert isinstance(mesh, Mesh) and len(mesh.triangles) > 100
    with pytest.raises(RgbdError, match="no <class>/train"):
        OffTree(off_tree / "bathtub")


def test_single_files_load_as_meshes_or_points(tmp_path: Path, shared_data: Path) -> None:
    bunny = load_mesh(shared_data / "meshes" / "stanford_bunny.off")
    assert isinstance(load_shape(shared_data / "meshes" / "stanford_bunny.off"), Mesh)
    assert isinstance(load_shape(shared_data / "meshes" / "pyvista_ant.ply"), Mesh)
    tm = trimesh.Trimesh(bunny.vertices, bunny.triangles, process=False)
    tm.export(tmp_path / "bunny.obj")
    obj = load_shape(tmp_path / "bunny.obj")
    assert isinstance(obj, Mesh) and len(obj.triangles) == len(bunny.triangles)
    pts = sample_surface(bunny, 300)
    trimesh.PointCloud(pts).export(tmp_path / "cloud.ply")
    np.save(tmp_path / "cloud.npy", pts)
    np.savez(tmp_path / "cloud.npz", points=pts, other=np.zeros(3))
    for name in ("cloud.ply", "cloud.npy", "cloud.npz"):
        got = load_shape(tmp_path / name)
        assert isinstance(got, np.ndarray) and np.allclose(got, pts, atol=1e-6), name
    head = "VERSION .7\nFIELDS x y z rgb\nSIZE 4 4 4 4\nTYPE F F F F\nCOUNT 1 1 1 1\n"
    head += f"WIDTH {len(pts)}\nHEIGHT 1\nPOINTS {len(pts)}\n"
    rgb = np.ones((len(pts), 1), np.float32)
    ascii_body = "\n".join(" ".join(f"{v:.7g}" for v in row) for row in np.hstack([pts, rgb]))
    (tmp_path / "a.pcd").write_text(head + "DATA ascii\n" + ascii_body + "\n")
    binary = np.hstack([pts, rgb]).astype("<f4").tobytes()
    (tmp_path / "b.pcd").write_bytes((head + "DATA binary\n").encode() + binary)
    for name in ("a.pcd", "b.pcd"):
        assert np.allclose(load_shape(tmp_path / name), pts, atol=1e-5), name


def test_surface_samples_lie_on_the_mesh_and_repeat_by_seed() -> None:
    m = box((2.0, 1.0, 0.5))
    p = sample_surface(m, 2000, seed=3)
    on_face = np.isclose(np.abs(p), [1.0, 0.5, 0.25], atol=1e-5).any(axis=1)
    assert on_face.all() and np.abs(p).max() <= 1.0 + 1e-6
    assert np.array_equal(p, sample_surface(m, 2000, seed=3))
    assert not np.array_equal(p, sample_surface(m, 2000, seed=4))
    # area-weighted: the two 2 x 1 faces hold 2 / (2 + 1 + 0.5) of the area
    top_bottom = np.isclose(np.abs(p[:, 2]), 0.25, atol=1e-5).mean()
    assert abs(top_bottom - 2 / 3.5) < 0.04


def test_inputs_of_a_shape_and_of_a_batch_agree() -> None:
    shapes = [sphere(1.0), box((1.0, 2.0, 0.5)), sample_surface(sphere(0.5), 500)]
    one = [shape_inputs(s, VOLUME) for s in shapes]
    many = batch_inputs(shapes, VOLUME, workers=2)
    assert many["volume"].shape == (3, 3, 32, 32)
    for i, item in enumerate(one):
        assert np.array_equal(many["volume"][i], item["volume"])
        assert item["volume"].dtype == np.float32 and np.isfinite(item["volume"]).all()
    # meshes are voxelized solid (the inside counts), point clouds by occupancy
    solid = density_profiles(voxelize(shapes[0], 32, fill="solid"))
    assert solid[0, 16, 16] > 25
    assert np.array_equal(
        one[0]["volume"], D._normalise_maps(solid, NORM, VOLUME.volume_lcn_window)
    )
    occupancy = density_profiles(voxelize(shapes[2], 32))
    assert np.array_equal(
        one[2]["volume"], D._normalise_maps(occupancy, NORM, VOLUME.volume_lcn_window)
    )
    assert "volume" in available_representations()


@pytest.mark.skipif("depth" not in available_representations(), reason="depth views not built")
def test_depth_inputs_have_six_views() -> None:
    spec = InputSpec(representations=("depth", "volume"), view_resolution=16, normalisation=NORM)
    item = shape_inputs(box((1.0, 1.0, 1.0)), spec)
    assert item["depth"].shape == (6, 16, 16) and np.isfinite(item["depth"]).all()


def test_cache_is_memory_mappable_and_matches_the_inputs(mini_pack: Path, tmp_path: Path) -> None:
    cache = build_cache(mini_pack, tmp_path / "c", spec=VOLUME, quiet=True)
    assert cache.complete and len(cache) == 12 and cache.kind == "points"
    arr = np.load(tmp_path / "c" / "volume.npy", mmap_mode="r")
    assert isinstance(arr, np.memmap) and arr.dtype == np.float16 and arr.shape == (12, 3, 32, 32)
    src = PointCloudSet(mini_pack)
    want = shape_inputs(src.load(5), VOLUME)["volume"]
    assert np.allclose(arr[5], want, atol=2e-3 * max(1.0, float(np.abs(want).max())))
    data = cache.dataset("test")
    assert len(data) == 4
    x, y = data[0]
    assert x.shape == (3 * 32 * 32,) and x.dtype == torch.float32 and y.dtype == torch.int64
    assert list(cache.indices("train")) == [0, 1, 2, 3, 6, 7, 8, 9]
    meta = json.loads((tmp_path / "c" / "meta.json").read_text())
    assert meta["points_per_shape"] == 1024 and meta["classes"] == ["bathtub", "table"]


def test_cache_is_sharded_and_resumable(
    mini_pack: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    out = tmp_path / "c"
    build_cache(mini_pack, out, spec=VOLUME, shard=(1, 3), quiet=True)
    assert list(np.flatnonzero(ShapeCache(out).done)) == [1, 4, 7, 10]
    # a cache with shapes still to compute is refused, not read as if it were the dataset
    part = ShapeCache(out)
    with pytest.raises(RgbdError, match=r"6 of the 8 shapes of split 'train' not computed yet"):
        part.dataset("train")
    with pytest.raises(RgbdError, match=r"2 of the 4 shapes of split 'test'.*rgbd shapes cache"):
        part.dataset("test")
    with pytest.raises(RgbdError, match=r"8 of the 12 shapes of split 'all'"):
        part.dataset("all")
    assert len(part.dataset("train", partial=True)) == 2
    assert len(part.dataset("train", indices=[1, 4])) == 2, "chosen rows: the caller's choice"
    # a run killed after 5 shapes keeps every chunk it flushed
    calls = {"n": 0}
    real = D._inputs

    def dying(x: object, s: InputSpec) -> dict[str, object]:
        calls["n"] += 1
        if calls["n"] > 5:
            raise KeyboardInterrupt
        return real(x, s)  # type: ignore[arg-type]

    monkeypatch.setattr(D, "_inputs", dying)
    with pytest.raises(KeyboardInterrupt):
        build_cache(mini_pack, out, spec=VOLUME, workers=1, chunk=2, quiet=True)
    done = ShapeCache(out).done
    assert int(done.sum()) == 4 + 4, done  # two chunks of 2 flushed, the third lost
    monkeypatch.setattr(D, "_inputs", real)
    calls["n"] = 0
    counted: list[int] = []
    monkeypatch.setattr(D, "_inputs", lambda x, s: counted.append(1) or real(x, s))
    cache = build_cache(mini_pack, out, spec=VOLUME, workers=1, quiet=True)
    assert cache.complete and len(counted) == 12 - 8
    fresh = build_cache(mini_pack, tmp_path / "fresh", spec=VOLUME, quiet=True)
    assert np.array_equal(cache.array("volume"), fresh.array("volume"))
    other = InputSpec(("volume",), volume_resolution=16, normalisation=NORM)
    with pytest.raises(RgbdError, match="other data or settings"):
        build_cache(mini_pack, out, spec=other, quiet=True)


def test_off_tree_cache_marks_broken_meshes_failed(off_tree: Path, tmp_path: Path) -> None:
    tree = tmp_path / "tree"
    shutil.copytree(off_tree, tree)
    (tree / "bunny" / "train" / "broken.off").write_text("OFF\n3 1 0\n0 0 0\n1 1\n")
    with pytest.warns(UserWarning, match=r"broken.*not a valid OFF mesh"):
        cache = build_cache(tree, tmp_path / "c", spec=VOLUME, quiet=True)
    assert cache.complete and int((cache.done == 2).sum()) == 1
    assert len(cache.dataset("all")) == 7 and cache.kind == "mesh"
    assert cache.meta["points_per_shape"] is None


def test_a_split_without_shapes_is_named_not_sent_to_build(
    shared_data: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """A cache of test shapes only: asking for its training split said 'build the cache'."""
    from rgbd_rs.cli import main
    from rgbd_rs.errors import InvalidArgumentError

    pack = modelnet10_subset(shared_data, tmp_path / "p.npz", (1, 2), ((1, 2),))
    spec = D.InputSpec(representations=("volume",), normalisation="standardize")
    D.build_cache(pack, tmp_path / "c", spec=spec, quiet=True)
    cache = D.ShapeCache(tmp_path / "c")
    assert len(cache.dataset("test")) == 4
    with pytest.raises(InvalidArgumentError, match=r"^split: got 'train', which has no shape in"):
        cache.dataset("train")
    with pytest.raises(InvalidArgumentError, match=r"\(0 train, 4 test\), expected a split"):
        cache.dataset("train")
    argv = ["train", "shapes", "--cache", str(tmp_path / "c"), "--out", str(tmp_path / "t")]
    assert main([*argv, "--quiet", "--device", "cpu"]) == 2
    err = capsys.readouterr().err
    assert "split: got 'train', which has no shape" in err and "build" not in err, err
