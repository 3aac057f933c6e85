"""The six orthographic depth views of thesis §5.3.1 and local contrast normalisation
(rgbd_rs.shapes.views)."""

from __future__ import annotations

import numpy as np
import pytest
from scipy import ndimage

from rgbd_rs import _rgbd_rs
from rgbd_rs.data import data_root
from rgbd_rs.meshes import Mesh, box, concat, load_mesh, sphere
from rgbd_rs.shapes.views import (
    MIN_SPLAT_PX,
    VIEW_NAMES,
    depth_views,
    depth_views_batch,
    lcn_window,
    local_contrast_normalize,
    splat_radii,
)

# The documented view table, written out independently: (right, up, forward) per view.
AXES = {
    "+x": ((0, 1, 0), (0, 0, 1), (-1, 0, 0)),
    "+y": ((-1, 0, 0), (0, 0, 1), (0, -1, 0)),
    "-x": ((0, -1, 0), (0, 0, 1), (1, 0, 0)),
    "-y": ((1, 0, 0), (0, 0, 1), (0, 1, 0)),
    "top": ((1, 0, 0), (0, 1, 0), (0, 0, -1)),
    "bottom": ((-1, 0, 0), (0, 1, 0), (0, 0, 1)),
}


def raw(shape: Mesh | np.ndarray, res: int, **kw: object) -> np.ndarray:
    return depth_views(shape, res, lcn=False, background=np.nan, **kw)  # type: ignore[arg-type]


def sphere_points(n: int, seed: int = 0) -> np.ndarray:
    p = np.random.default_rng(seed).normal(size=(n, 3))
    return (p / np.linalg.norm(p, axis=1, keepdims=True)).astype(np.float32)


def test_sphere_views_are_discs_with_the_sphere_profile() -> None:
    res = 64
    d = raw(sphere(1.0, rings=96, segments=192), res)
    assert d.shape == (6, res, res) and d.dtype == np.float32
    c = (np.arange(res) + 0.5) / res - 0.5  # pixel centres in cube sides
    x, y = np.meshgrid(c, -c)
    rho2 = x**2 + y**2
    inside = rho2 < 0.24  # radius 0.5 in cube units, minus a pixel-wide rim
    expect = 0.5 - np.sqrt(np.maximum(0.25 - rho2, 0.0))
    for k in range(6):
        assert np.isnan(d[k][rho2 > 0.26]).all(), VIEW_NAMES[k]
        assert not np.isnan(d[k][inside]).any()
        assert np.abs(d[k][inside] - expect[inside]).max() < 3e-3, VIEW_NAMES[k]


def test_box_views_are_flat_and_centred() -> None:
    res = 32
    d = raw(box((2.0, 1.0, 0.5), (3.0, -1.0, 7.0)), res)
    # Cube side 2: x spans it (depth 0 from +-x), y fills the middle half at depth 0.25,
    # z the middle quarter at depth 0.375.
    for k, depth, filled in [(0, 0.0, 1 / 8), (2, 0.0, 1 / 8), (1, 0.25, 1 / 4), (3, 0.25, 1 / 4)]:
        v = d[k][~np.isnan(d[k])]
        assert np.abs(v - depth).max() < 1e-4 and v.size == filled * res * res, VIEW_NAMES[k]
    for k in (4, 5):
        v = d[k][~np.isnan(d[k])]
        assert np.abs(v - 0.375).max() < 1e-4 and v.size == res * res // 2


def test_top_view_of_a_table_shows_the_top_and_the_bottom_view_the_legs() -> None:
    top = box((1.0, 1.0, 0.05), (0.0, 0.0, 0.475))
    legs = [box((0.05, 0.05, 0.95), (x, y, 0.0)) for x in (-0.45, 0.45) for y in (-0.45, 0.45)]
    d = raw(concat([top, *legs]), 64)
    # Height 0.975 < width 1: centred in the cube, so 0.0125 below the top face.
    assert np.abs(d[4] - 0.0125).max() < 1e-4, "the top, everywhere"
    under = d[5]
    assert not np.isnan(under).any()
    near = under < 0.02  # the leg ends
    assert 4 * 3 * 3 <= near.sum() <= 4 * 4 * 4
    assert np.abs(under[~near] - 0.9375).max() < 1e-3, "elsewhere the top's underside"
    _, n = ndimage.label(near)
    assert n == 4


def test_view_order_and_orientation_follow_the_table() -> None:
    # A unit block with a nub on its +x side, towards +y and +z: each view sees the nub (or
    # not) at the pixel the documented axes give.
    block = box((1.0, 1.0, 1.0))
    nub = box((0.2, 0.2, 0.2), (0.6, 0.2, 0.3))
    res = 60
    d = raw(concat([block, nub]), res)
    centre, side = np.array([0.1, 0.0, 0.0]), 1.2
    nub_lo, nub_hi = np.array([0.5, 0.1, 0.2]), np.array([0.7, 0.3, 0.4])
    q = (np.array([0.6, 0.2, 0.3]) - centre) / side
    for k, name in enumerate(VIEW_NAMES):
        right, up, fwd = (np.array(a, float) for a in AXES[name])
        col = round((q @ right + 0.5) * res - 0.5)
        row = round((0.5 - q @ up) * res - 0.5)
        face = (centre - fwd * side / 2) @ fwd  # coordinate of the near face along fwd
        nub_near = np.where(fwd > 0, nub_lo, nub_hi) @ fwd
        expect = (nub_near - face) / side
        if name == "-x":  # hidden behind the block, whose -x face is on the cube face
            expect = 0.0
        assert abs(d[k, row, col] - expect) < 1e-4, (name, d[k, row, col], expect)
        # The mirrored pixel (a flipped image would put the nub there) sees something else.
        assert abs(d[k, row, res - 1 - col] - expect) > 0.05 or name == "-x"


def test_turning_the_shape_about_z_cycles_the_side_views() -> None:
    p = np.random.default_rng(1).uniform(-1, 1, (3000, 3)).astype(np.float32)
    p[:, 0] *= 0.6  # not symmetric under the turn
    turned = np.stack([-p[:, 1], p[:, 0], p[:, 2]], 1)  # +90 degrees about z
    a, b = raw(p, 48), raw(turned, 48)

    def same(x: np.ndarray, y: np.ndarray) -> float:
        return float(np.mean((np.isnan(x) & np.isnan(y)) | (np.abs(x - y) < 1e-5)))

    for k in range(4):
        assert same(a[k], b[(k + 1) % 4]) > 0.99, k
    assert same(np.rot90(a[4], 1), b[4]) > 0.99
    assert same(np.rot90(a[5], -1), b[5]) > 0.99
    assert same(a[0], b[0]) < 0.9, "the test shape is not symmetric"


def test_mesh_rasterizer_agrees_with_the_ray_caster_on_a_real_mesh() -> None:
    root = data_root()
    if root is None:
        pytest.skip("shared data not found")
    m = load_mesh(root / "meshes" / "stanford_bunny.off")
    a = _rgbd_rs.mesh_depth_views(m.vertices, m.triangles, 96)
    b = _rgbd_rs.mesh_depth_views_raycast(m.vertices, m.triangles, 96)
    agree = (np.isnan(a) & np.isnan(b)) | (np.abs(a - b) < 1e-4)
    assert agree.mean() > 0.999
    assert 0.2 < np.mean(~np.isnan(a)) < 0.8


def test_dense_points_agree_with_the_mesh() -> None:
    m = sphere(1.0, rings=64, segments=128)
    p = sphere_points(40000)
    dm, dp = raw(m, 64), raw(p, 64)
    sil, cov = ~np.isnan(dm), ~np.isnan(dp)
    assert cov[sil].mean() > 0.995, "closed"
    assert (cov & ~sil).sum() < 0.06 * sil.sum(), "the silhouette grows by at most a pixel"
    both = sil & cov
    assert np.median(np.abs(dm[both] - dp[both])) < 0.01


@pytest.mark.skipif(data_root() is None, reason="shared data not found")
def test_modelnet_points_give_closed_views() -> None:
    root = data_root()
    assert root is not None
    pack = np.load(root / "modelnet" / "modelnet10_1024.npz")
    test = np.flatnonzero(pack["split"] == 1)
    pick = np.random.default_rng(0).choice(test, 30, replace=False)
    points = pack["points"]  # one decompression
    clouds = [points[i].astype(np.float32) for i in pick]

    def filled(views: np.ndarray) -> list[float]:
        out = []
        for v in ~np.isnan(views):
            # The silhouette: the filled pixels with 1-px gaps bridged and enclosed holes filled.
            sil = ndimage.binary_fill_holes(ndimage.binary_closing(v, np.ones((3, 3))))
            out.append(float(v[sil].mean()))
        return out

    auto = [f for c in clouds for f in filled(raw(c, 64))]
    dots = [f for c in clouds[:10] for f in filled(raw(c, 64, splat_radius=MIN_SPLAT_PX))]
    assert np.mean(auto) > 0.96 and np.percentile(auto, 10) > 0.9, np.mean(auto)
    assert np.mean(dots) < 0.8, "one pixel per point is not closed: the rule matters"
    r = splat_radii(clouds[0], 64)
    assert r.shape == (1024,) and 2.0 < np.median(r) < 6.0
    assert np.allclose(splat_radii(clouds[0], 320), np.minimum(5 * r, 64), rtol=1e-4)


def test_lcn_matches_the_formula_and_normalises() -> None:
    rng = np.random.default_rng(0)
    img = rng.normal(size=(12, 10)) * 3 + np.linspace(0, 50, 10)
    out = local_contrast_normalize(img, 3)

    # Brute force: 3 x 3 box, zero padding, border correction.
    def smooth(a: np.ndarray) -> np.ndarray:
        p = np.pad(a, 1)
        return np.array([[p[i : i + 3, j : j + 3].sum() for j in range(10)] for i in range(12)])

    n = smooth(np.ones_like(img))
    v = img - smooth(img) / n
    s = np.sqrt(smooth(v * v) / n)
    ref = v / np.maximum(np.maximum(s, s.mean()), 1e-4)
    assert np.allclose(out, ref, atol=1e-5)
    big = local_contrast_normalize(rng.normal(size=(64, 64)) * 7 + 100)
    assert abs(big.mean()) < 0.05 and 0.6 < big.std() < 1.5
    assert np.abs(local_contrast_normalize(np.full((8, 8), 3.0))).max() < 1e-6, "constant -> 0"
    stack = rng.normal(size=(2, 3, 16, 16))
    assert np.allclose(local_contrast_normalize(stack)[1, 2], local_contrast_normalize(stack[1, 2]))
    assert [lcn_window(r) for r in (8, 32, 64, 128, 320)] == [3, 5, 9, 19, 45]


def test_lcn_views_and_background() -> None:
    m = sphere(1.0)
    plain = depth_views(m, 32, lcn=False)
    assert plain.max() == 1.0 and (plain == 1.0).sum() > 6 * 32 * 32 * 0.15, "background 1"
    v = depth_views(m, 32)
    assert v.shape == (6, 32, 32) and np.isfinite(v).all()
    assert np.allclose(v, local_contrast_normalize(plain, 5))
    assert np.allclose(depth_views(m, 32, lcn_window=3), local_contrast_normalize(plain, 3))


def test_deterministic_and_batch_equals_single() -> None:
    clouds = [sphere_points(1024, s) * (s + 1) for s in range(5)]
    m = box((1.0, 2.0, 3.0))
    one = [depth_views(c, 40) for c in clouds] + [depth_views(m, 40)]
    batch = depth_views_batch([*clouds, m], 40)
    assert batch.shape == (6, 6, 40, 40)
    assert np.array_equal(batch, np.stack(one))
    assert np.array_equal(depth_views_batch([*clouds, m], 40), batch)
    assert depth_views_batch([], 8).shape == (0, 6, 8, 8)


def test_degenerate_shapes_have_documented_views() -> None:
    # One point: a cube of side 1 around it; its pixel at depth 0.5 in every view.
    d = raw(np.array([[5.0, -2.0, 1.0]]), 9)
    assert (np.count_nonzero(~np.isnan(d), axis=(1, 2)) == 1).all()
    assert np.allclose(d[:, 4, 4], 0.5)
    # A flat square (zero z extent): top and bottom flat at 0.5; edge-on side views empty.
    sq = Mesh(
        np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]], np.float32),
        np.array([[0, 1, 2], [0, 2, 3]], np.uint32),
    )
    d = raw(sq, 16)
    assert np.allclose(d[4:], 0.5) and np.isnan(d[:4]).all()
    # Points on a flat square: side views are a line at mid-height.
    p = np.random.default_rng(0).uniform(0, 1, (500, 3)).astype(np.float32)
    p[:, 2] = 0
    d = raw(p, 16)
    assert np.isfinite(d[0, 7:9]).all() and np.isnan(d[0, :5]).all()
    # Scale and offset do not matter, huge coordinates included.
    c = sphere_points(2000)
    a, b = raw(c, 32), raw(c.astype(np.float64) * 1e25 + 3e25, 32)
    assert (np.isnan(a) == np.isnan(b)).mean() > 0.999
    assert np.nanmax(np.abs(a - b)) < 1e-4
