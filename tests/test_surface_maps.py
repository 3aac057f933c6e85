"""rgbd_rs.surface: the maps of a fit are computed on first access, inside the fitted pixels' box
only, and equal those of a whole-image evaluation (issue 16)."""

from __future__ import annotations

import dataclasses
import pickle

import numpy as np
import pytest

from bad_input import Case, check, params
from rgbd_rs import InvalidArgumentError, PinholeCamera
from rgbd_rs.surface import SegmentFits, SurfaceFit, SurfaceMaps, fit_grid, fit_mask

CAM = PinholeCamera(fx=200.0, fy=200.0, cx=63.5, cy=47.5, width=128, height=96)
MAPS = ("fitted", "error", "k1", "k2", "mean", "gaussian")


def bowl() -> np.ndarray:
    """Points of a curved, noisy surface with a NaN hole."""
    v, u = np.mgrid[0:96, 0:128].astype(np.float64)
    z = 2.0 + 0.3 * np.sin(u / 20.0) * np.cos(v / 15.0)
    z += np.random.default_rng(3).normal(0.0, 1e-3, z.shape)
    z[40:44, 70:75] = np.nan
    return CAM.depth_to_points(z.astype(np.float32))


def blob() -> np.ndarray:
    """A segment that does not start on a knot: an ellipse with a hole."""
    v, u = np.mgrid[0:96, 0:128]
    inside = ((u - 61) / 37.0) ** 2 + ((v - 50) / 23.0) ** 2 < 1.0
    return np.asarray(inside & ~((u > 55) & (u < 60) & (v > 45) & (v < 52)), bool)


def test_maps_equal_the_segment_fits_maps_of_the_same_surface() -> None:
    # SegmentFits.maps evaluates every pixel of the image; fit_mask only its box. A label image
    # with one segment gives the same fit, so the maps must be equal to the bit.
    pts, mask = bowl(), blob()
    for spacing, degree in ((8.0, 3), (5.5, 2), (16.0, 3)):
        fit = fit_mask(pts, mask, spacing=spacing, degree=degree)
        labels = np.where(mask, 0, -1).astype(np.int32)
        whole = SegmentFits(pts, labels, spacing=spacing, degree=degree, criterion="mse")
        ref = whole.maps(pts)
        for name in MAPS:
            np.testing.assert_array_equal(getattr(fit, name), getattr(ref, name), err_msg=name)
        assert np.isfinite(fit.k1[mask]).mean() > 0.99 and np.isnan(fit.k1[~mask]).all()


def test_crop_gives_the_box_of_the_full_maps() -> None:
    pts, mask = bowl(), blob()
    full = fit_mask(pts, mask, spacing=8)
    crop = fit_mask(pts, mask, spacing=8, crop=True)
    r0, r1, c0, c1 = crop.box
    rows, cols = np.nonzero(mask)
    assert crop.box == (rows.min(), rows.max() + 1, cols.min(), cols.max() + 1) == full.box
    assert crop.cropped and not full.cropped
    assert crop.fitted.shape == (r1 - r0, c1 - c0, 3) and full.fitted.shape == (96, 128, 3)
    for name in MAPS:
        np.testing.assert_array_equal(getattr(crop, name), getattr(full, name)[r0:r1, c0:c1])
    assert (crop.n, crop.sse, crop.dof) == (full.n, full.sse, full.dof)


def test_maps_use_the_points_as_they_were_at_fit_time() -> None:
    pts = bowl()
    fit = fit_grid(pts, spacing=8)
    before = fit_grid(pts.copy(), spacing=8).error
    pts[...] = 0.0  # the caller reuses its buffer before reading the maps
    np.testing.assert_array_equal(fit.error, before)
    assert fit.box == (0, 96, 0, 128)


def test_fit_is_frozen_picklable_and_still_a_surface_maps() -> None:
    fit = fit_mask(bowl(), blob(), spacing=8)
    assert isinstance(fit, SurfaceMaps) and isinstance(fit, SurfaceFit)
    with pytest.raises(dataclasses.FrozenInstanceError):
        fit.n = 3
    with pytest.raises(dataclasses.FrozenInstanceError):
        fit.k1 = fit.k2  # type: ignore[misc]
    back = pickle.loads(pickle.dumps(fit))
    for name in MAPS:
        np.testing.assert_array_equal(getattr(back, name), getattr(fit, name))
    assert (back.n, back.sse, back.dof, back.linear, back.box) == (
        fit.n,
        fit.sse,
        fit.dof,
        fit.linear,
        fit.box,
    )
    assert "SurfaceFit(n=" in repr(fit) and fit.mse == fit.sse / fit.n
    # The first access computed all six maps once; later reads are the same arrays.
    assert fit.k1 is fit.k1


def test_tiny_segment_linear_fallback_has_box_maps() -> None:
    mask = np.zeros((96, 128), bool)
    mask[30, 40:45] = True  # 5 pixels < 16: linear fit
    fit = fit_mask(bowl(), mask, spacing=8, crop=True)
    assert fit.linear and fit.box == (30, 31, 40, 45)
    assert fit.fitted.shape == (1, 5, 3) and np.isfinite(fit.fitted).all()


CASES: list[Case] = [
    Case(
        "fit_mask",
        lambda: fit_mask(bowl(), blob(), crop="yes"),  # type: ignore[arg-type]
        InvalidArgumentError,
        r"^crop: got 'yes'",
        "crop",
    ),
]


@pytest.mark.parametrize("case", params(CASES))
def test_bad_input(case: Case) -> None:
    check(case)
