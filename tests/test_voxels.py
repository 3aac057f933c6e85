"""Voxelization and the density profiles of thesis §5.3.2 (rgbd_rs.shapes.voxels)."""

from __future__ import annotations

import numpy as np
import pytest

from rgbd_rs.data import data_root
from rgbd_rs.meshes import box, concat, load_mesh, sphere
from rgbd_rs.shapes import density_profiles, voxelize


def test_solid_sphere_fills_its_volume() -> None:
    m = sphere(1.0, segments=64, rings=32)
    v = voxelize(m, 32, fill="solid")
    # A ball inscribed in the cube fills pi/6 of it; the surface voxels add a shell.
    frac = v.filled.mean()
    assert np.pi / 6 < frac < np.pi / 6 + 0.12, frac
    s = voxelize(m, 32)
    assert s.filled.sum() < 0.4 * v.filled.sum(), "the surface is a thin shell"
    assert v.filled[16, 16, 16] and not s.filled[16, 16, 16]


def test_points_on_a_sphere_mark_its_shell() -> None:
    rng = np.random.default_rng(0)
    p = rng.normal(size=(20000, 3))
    p /= np.linalg.norm(p, axis=1, keepdims=True)
    v = voxelize(p, 16)
    assert not v.filled[8, 8, 8] and v.filled.sum() > 300
    d = voxelize(p[:300], 16, dilate=1)
    assert d.filled.sum() > voxelize(p[:300], 16).filled.sum()


def test_table_profiles_show_legs_from_above() -> None:
    top = box((1.0, 1.0, 0.05), (0.0, 0.0, 0.475))
    legs = [box((0.05, 0.05, 0.95), (x, y, 0.0)) for x in (-0.45, 0.45) for y in (-0.45, 0.45)]
    v = voxelize(concat([top, *legs]), 32, fill="solid")
    px, _, pz = density_profiles(v)
    # Top view: the legs' columns are the deepest, the plain top is thin.
    assert pz.max() >= 28 and np.median(pz[pz > 0]) <= 3
    assert np.sum(pz >= 20) >= 4
    # Side views: the top row is deep across the width, the leg columns below it.
    assert px[0].mean() > 10 and px[16, 16] == 0


def test_flat_and_single_point_shapes_are_centred() -> None:
    flat = voxelize(np.array([[0.0, 0.0, 0.0], [1.0, 1.0, 0.0]]), 8)
    assert flat.filled[4].sum() == 2 and flat.filled.sum() == 2, "z = 0 sits mid-grid"
    one = voxelize(np.array([[3.0, 3.0, 3.0]]), 5)
    assert one.filled[2, 2, 2] and one.filled.sum() == 1


@pytest.mark.skipif(data_root() is None, reason="shared data not found")
def test_real_meshes_voxelize() -> None:
    root = data_root()
    assert root is not None
    for name in ("stanford_bunny.off", "modelnet10_bathtub_0001.off", "pyvista_ant.ply"):
        m = load_mesh(root / "meshes" / name)
        s, v = voxelize(m, 32), voxelize(m, 32, fill="solid")
        assert 0 < s.filled.sum() <= v.filled.sum(), name
        # The grid is tight: the shape touches both ends of its longest axis.
        occupied = [
            np.flatnonzero(s.filled.any(axis=tuple(b for b in range(3) if b != a)))
            for a in range(3)
        ]
        assert any(o[0] == 0 and o[-1] == 31 for o in occupied), name
