"""Curvature maps of the six depth views (rgbd_rs.shapes.curvature, thesis §5.3.3, issue 14):
sphere, cylinder and plane against their known curvatures, a point-cloud sphere, scale
invariance, empty pixels, and the maps as dataset inputs and network inputs."""

from __future__ import annotations

import itertools
from pathlib import Path

import numpy as np
import pytest
import torch

from rgbd_rs import _rgbd_rs
from rgbd_rs.meshes import Mesh, cylinder, quad, sphere
from rgbd_rs.shapes.curvature import curvature_maps, knot_spacing
from rgbd_rs.shapes.views import depth_views

#: Fine UV sphere (facets of about 1 px at 64 x 64): its k1, k2 are 1/r up to the tessellation.
BALL = sphere(1.0, rings=128, segments=256)


def _cube_side(shape: Mesh | np.ndarray) -> float:
    v = shape.vertices if isinstance(shape, Mesh) else shape
    return float((v.max(0) - v.min(0)).max())


def _radial(res: int, side: float, radius: float) -> np.ndarray:
    """Distance of each pixel centre from the view centre, in units of ``radius``."""
    c = (np.arange(res) + 0.5) / res - 0.5
    x, y = np.meshgrid(c, c)
    return np.hypot(x, y) * side / radius


def _sphere_errors(
    maps: np.ndarray, side: float, radius: float, rings: list[float]
) -> list[tuple[float, float]]:
    """Per ring ``[rings[i], rings[i+1])`` of the view (in radii): median and 90th percentile of
    ``max(|k1 r - 1|, |k2 r - 1|)`` with k in 1/m (maps are in 1/cube side)."""
    res = maps.shape[-1]
    rho = _radial(res, side, radius)
    k = maps / side * radius  # k · r
    err = np.maximum(np.abs(k[0] - 1), np.abs(k[1] - 1))
    out = []
    for a, b in itertools.pairwise(rings):
        e = err[(rho >= a) & (rho < b)]
        out.append((float(np.median(e)), float(np.percentile(e, 90))))
    return out


RINGS = [0.0, 0.5, 0.6, 0.7, 0.8]


@pytest.mark.parametrize("res", [64, 320])
def test_sphere_k1_k2_within_5_percent_over_the_inner_80_percent(res: int) -> None:
    maps = curvature_maps(BALL, res)
    assert maps.shape == (6, 2, res, res) and maps.dtype == np.float32
    side = _cube_side(BALL)
    for view in (0, 4):  # a side view and the top view (the UV sphere's pole)
        errs = _sphere_errors(maps[view], side, 1.0, RINGS)
        for (a, b), (median, p90) in zip(itertools.pairwise(RINGS), errs, strict=True):
            assert median < 0.05 and p90 < 0.05, (res, view, a, b, median, p90)


def test_without_the_rim_cut_the_sphere_fit_rings(monkeypatch: pytest.MonkeyPatch) -> None:
    """The rim handling is what makes the sphere accurate: fitting every object pixel rings."""
    import rgbd_rs.shapes.curvature as C

    monkeypatch.setattr(C, "MAX_SLOPE", float("inf"))
    errs = _sphere_errors(C.curvature_maps(BALL, 64)[0], _cube_side(BALL), 1.0, RINGS)
    assert max(m for m, _ in errs) > 0.10, errs


def test_cylinder_has_k1_one_over_r_and_k2_zero() -> None:
    r = 0.5
    cyl = cylinder(r, 2.0, segments=512, axis=2)  # vertical (z up), cube side 2
    res = 64
    maps = curvature_maps(cyl, res)
    side = _cube_side(cyl)
    c = (np.arange(res) + 0.5) / res - 0.5
    across = np.abs(c) * side / r  # side views: columns across the axis
    cols = across < 0.8
    rows = np.abs(c) * side < 0.8  # away from the caps (height 2 = the whole view)
    for view in range(4):
        k1 = maps[view, 0][np.ix_(rows, cols)] * r / side
        k2 = maps[view, 1][np.ix_(rows, cols)] / side
        assert np.median(np.abs(k1 - 1)) < 0.05, view
        assert np.percentile(np.abs(k1 - 1), 90) < 0.10, view
        assert np.percentile(np.abs(k2), 90) < 0.05 / r, view  # 5 % of 1/r
    # The caps seen from the top and bottom are flat discs.
    cap = _radial(res, side, r) < 0.8
    assert np.abs(maps[4:, :, cap]).max() < 0.05 / r * side


def test_plane_has_zero_curvature_everywhere() -> None:
    tilted = quad([[-1, -1, -0.5], [1, -1, -0.5], [1, 1, 0.5], [-1, 1, 0.5]])  # slope 0.5
    maps = curvature_maps(tilted, 64)
    seen = np.isfinite(depth_views(tilted, 64, lcn=False, background=np.nan))
    assert seen[4].mean() > 0.9  # the top view sees the plane
    assert np.abs(maps).max() < 1e-3, np.abs(maps).max()


def test_empty_pixels_get_zero_curvature() -> None:
    small = sphere(0.3, center=(0.7, 0.0, 0.0), rings=64, segments=128).merged(
        sphere(0.3, center=(-0.7, 0.0, 0.0), rings=64, segments=128)
    )
    maps = curvature_maps(small, 64)
    empty = np.isnan(depth_views(small, 64, lcn=False, background=np.nan))
    assert empty.any() and (~empty).any()
    assert (maps[:, 0][empty] == 0).all() and (maps[:, 1][empty] == 0).all()
    assert (maps[:, 0][~empty] > 0).mean() > 0.8  # balls bulge towards every view


def test_scale_and_unit_do_not_change_the_maps() -> None:
    """The views are measured in cube sides, so maps are the same for a shape in mm and in m."""
    big = Mesh(BALL.vertices * np.float32(1000), BALL.triangles)
    shifted = Mesh(BALL.vertices + np.float32(3), BALL.triangles)
    a = curvature_maps(BALL, 64)
    for other in (big, shifted):
        b = curvature_maps(other, 64)
        assert np.allclose(a, b, rtol=1e-3, atol=1e-3 * np.abs(a).max())


def _unit_sphere_points(n: int, seed: int = 0) -> np.ndarray:
    p = np.random.default_rng(seed).normal(size=(n, 3))
    return np.asarray(p / np.linalg.norm(p, axis=1, keepdims=True), np.float32)


def test_point_cloud_sphere_of_1024_points() -> None:
    """Measured on three clouds of 1024 random points, six views, 64 and 320 px (out/notes/
    curvature.md): median |k r - 1| per view at most 4.2 % inside half the radius, 5.0 % in
    0.5-0.7 and 7.8 % in 0.7-0.8 of it; the test allows 1.4x that. Fitting the splatted views
    like a mesh's instead is off by more than 50 %."""
    import rgbd_rs.shapes.curvature as C

    p = _unit_sphere_points(1024)
    side = _cube_side(p)
    rings = [0.0, 0.5, 0.7, 0.8]
    maps = curvature_maps(p, 64)
    for view in range(6):
        errs = [m for m, _ in _sphere_errors(maps[view], side, 1.0, rings)]
        assert errs[0] < 0.06 and errs[1] < 0.07 and errs[2] < 0.11, (view, errs)
    # Splat depth is piecewise flat: a mesh-style fit of those views is useless.
    depth = depth_views(p, 64, lcn=False, background=np.nan)
    k = _rgbd_rs.depth_view_curvatures(depth, 64.0, C.knot_spacing(64), 1e-6, C.MAX_SLOPE)
    (inner, _), *_ = _sphere_errors(np.nan_to_num(k[0] * 64), side, 1.0, rings)
    assert inner > 0.5, inner


def test_closed_form_normals_match_eigh(shared_data: Path) -> None:
    from scipy.spatial import cKDTree

    import rgbd_rs.shapes.curvature as C
    from rgbd_rs.shapes.dataset import PointCloudSet

    p = PointCloudSet(shared_data / "modelnet" / "modelnet10_1024.npz").load(7).astype(np.float64)
    _, idx = cKDTree(p).query(p, C.NORMAL_NEIGHBOURS)
    nb = p[idx] - p[idx].mean(axis=1, keepdims=True)
    ref = np.linalg.eigh(np.einsum("nki,nkj->nij", nb, nb))[1][:, :, 0]
    cos = np.abs((C._normals(p) * ref).sum(axis=1))
    assert cos.min() > 1 - 1e-9


def test_a_single_point_and_a_tiny_cloud_give_zero_maps() -> None:
    assert (curvature_maps(np.zeros((1, 3), np.float32), 16) == 0).all()
    assert (curvature_maps(_unit_sphere_points(5), 16) == 0).all()


def test_precomputed_views_give_the_same_maps() -> None:
    cloud = _unit_sphere_points(1024, seed=3)
    for shape in (BALL, cloud):
        views = depth_views(shape, 64, lcn=False, background=np.nan)
        assert np.array_equal(curvature_maps(shape, 64, views=views), curvature_maps(shape, 64))


# -- as inputs ---------------------------------------------------------------------------------


def test_curvature_is_an_available_representation() -> None:
    from rgbd_rs.shapes.dataset import available_representations

    assert "curvature" in available_representations()


def test_shape_inputs_with_curvature_on_a_modelnet_cloud(shared_data: Path) -> None:
    from rgbd_rs.shapes.dataset import InputSpec, PointCloudSet, shape_inputs

    src = PointCloudSet(shared_data / "modelnet" / "modelnet10_1024.npz")
    chair = src.load(int(np.flatnonzero(src.labels == src.classes.index("chair"))[0]))
    spec = InputSpec(representations=("depth", "volume", "curvature"), view_resolution=32)
    out = shape_inputs(chair, spec)
    assert out["curvature"].shape == (6, 2, 32, 32)
    assert np.isfinite(out["curvature"]).all()
    raw = curvature_maps(chair, 32)
    assert (raw != 0).mean() > 0.2  # a chair's views are mostly curved or planar surfaces
    assert out["curvature"].std(axis=(-2, -1)).min() > 0  # every map carries something


def test_tiny_shape_network_runs_on_curvature_inputs(shared_data: Path) -> None:
    from rgbd_rs.nn.shapes import ShapeNet
    from rgbd_rs.shapes.dataset import InputSpec, PointCloudSet, batch_inputs

    src = PointCloudSet(shared_data / "modelnet" / "modelnet10_1024.npz")
    spec = InputSpec(representations=("depth", "volume", "curvature"), view_resolution=32)
    x = batch_inputs([src.load(i) for i in range(3)], spec, workers=1)
    threaded = batch_inputs([src.load(i) for i in range(3)], spec, workers=3)
    assert np.array_equal(threaded["curvature"], x["curvature"])  # thread-safe, deterministic
    torch.manual_seed(0)
    net = ShapeNet(10, representations="combined", view_resolution=32, width=4).eval()
    with torch.no_grad():
        tensors = {k: torch.from_numpy(v) for k, v in x.items()}
        logits = net(tensors)
        flat = net({**tensors, "curvature": torch.zeros_like(tensors["curvature"])})
    assert logits.shape == (3, 10) and torch.isfinite(logits).all()
    assert not torch.allclose(logits, flat)  # the curvature branches feed the classifier


def test_knot_spacing_follows_the_resolution() -> None:
    assert knot_spacing(64) == 64 / 24 and knot_spacing(320) == 320 / 24
    assert knot_spacing(8) == 1 and knot_spacing(64, 16) == 4
