"""Normalized-cuts over-segmentation with the Nyström approximation (thesis §4.4).

The per-pixel feature vectors (normally the 9-D vectors of eq. 4.1 from
:func:`rgbd_rs.segmentation.features.features`) are grouped by normalized cuts (Shi & Malik)
with the one-shot Nyström method of Fowlkes et al. (PAMI 2004):

1. ``n_samples`` valid pixels are drawn (seeded); the affinity is the Gaussian kernel
   ``W_ij = exp(-||p_i - p_j||^2 / sigma^2)`` (``sigma`` = 3 in the thesis; note ``sigma^2``,
   not ``2 sigma^2``).
2. The sample-sample block ``A`` is eigen-decomposed (faer); its pseudo-inverse and inverse square
   root keep only eigenvalues above 1e-6 of the largest, which makes the one-shot method stable
   although ``A`` is only positive semi-definite in floating point.
3. Every pixel is embedded on the leading ``n_vectors`` non-trivial approximate eigenvectors of
   ``D^-1/2 W D^-1/2`` (divided by the leading one, as in Fowlkes et al., and weighted by their
   eigenvalues). The pixels x samples affinity is never stored: it is streamed in float32 blocks
   of 2048 rows with rayon, three times.
4. Seeded k-means (k-means++ seeding) groups the embedding (scaled to unit variance per
   dimension) together with the input features themselves (times ``feature_weight``) and the
   pixel position (in grid steps ``sqrt(n_valid / n_segments)``, times ``spatial_weight``, like
   SLIC's compactness). On NYUv2 the embedding alone gives coarse, smooth clusters whose
   boundaries miss many ground-truth edges (boundary recall ~0.5 against SLIC's ~0.72); the
   features restore the sharp edges.
   The centres are fitted on a seeded subsample of ``fit_points`` pixels and every pixel is then
   assigned once to its nearest centre: k-means on all 307k pixels x 300 clusters would cost
   several seconds.
5. Every cluster is split into its 4-connected components and components smaller than
   ``min_size`` pixels are absorbed by the neighbour they share the longest boundary with.

The result is deterministic given ``seed`` and does not depend on the number of threads.
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt
from tqdm import tqdm

from rgbd_rs import _rgbd_rs, _validate
from rgbd_rs.errors import InvalidArgumentError, ShapeMismatchError
from rgbd_rs.segmentation.features import Features

__all__ = [
    "DEFAULT_FEATURE_WEIGHT",
    "DEFAULT_N_SAMPLES",
    "DEFAULT_N_SEGMENTS",
    "DEFAULT_N_VECTORS",
    "DEFAULT_SIGMA",
    "DEFAULT_SPATIAL_WEIGHT",
    "GROUP_WEIGHTS",
    "MAX_N_SAMPLES",
    "MIN_SIZE_FRACTION",
    "default_channel_weights",
    "oversegment",
]

#: Affinity width sigma of exp(-||p_i - p_j||^2 / sigma^2), the thesis' value (§4.4).
DEFAULT_SIGMA: float = _rgbd_rs.OVERSEG_DEFAULT_SIGMA
#: k-means clusters: the issue compares over-segmentations at ~300 segments.
DEFAULT_N_SEGMENTS: int = _rgbd_rs.OVERSEG_DEFAULT_SEGMENTS
#: Nyström samples m (the thesis does not give it; METHOD_NOTES §6).
DEFAULT_N_SAMPLES: int = _rgbd_rs.OVERSEG_DEFAULT_SAMPLES
#: Most Nyström samples: the eigensolver is cubic in m, so more would run for hours.
MAX_N_SAMPLES: int = _rgbd_rs.OVERSEG_MAX_SAMPLES
#: Embedding dimensions (non-trivial eigenvectors).
DEFAULT_N_VECTORS: int = _rgbd_rs.OVERSEG_DEFAULT_VECTORS
#: Weight of the pixel position against the unit-variance embedding, per grid step.
DEFAULT_SPATIAL_WEIGHT: float = _rgbd_rs.OVERSEG_DEFAULT_SPATIAL_WEIGHT
#: Weight of the input features themselves in k-means, against the unit-variance embedding.
DEFAULT_FEATURE_WEIGHT: float = _rgbd_rs.OVERSEG_DEFAULT_FEATURE_WEIGHT
#: Default ``min_size`` as a fraction of the mean segment size ``n_valid / n_segments``.
MIN_SIZE_FRACTION: float = 0.1

#: Default weights of the eq. 4.1 groups (colour, 3-D position, normal) when ``D`` = 9: the
#: Kinect-class normals are the noisiest channels and, at full weight, break segments into
#: fragments that cost boundary recall (measured on NYUv2, out/notes/nystrom.md).
GROUP_WEIGHTS: tuple[float, float, float] = (1.0, 0.5, 0.15)

F32 = npt.NDArray[np.float32]
I32 = npt.NDArray[np.int32]


#: Most feature channels per pixel :func:`oversegment` takes (eq. 4.1 has 9).
MAX_CHANNELS = 1024


def default_channel_weights(n_channels: int) -> F32:
    """The channel weights :func:`oversegment` applies by default: :data:`GROUP_WEIGHTS`
    repeated over the three channels of each group for the 9-D vectors of eq. 4.1, all ones
    for any other channel count."""
    d = _validate.integer("n_channels", n_channels, minimum=1, maximum=MAX_CHANNELS)
    if d == 9:
        return np.repeat(np.asarray(GROUP_WEIGHTS, np.float32), 3)
    return np.ones(d, np.float32)


def oversegment(
    features: npt.ArrayLike | Features,
    n_segments: int = DEFAULT_N_SEGMENTS,
    *,
    sigma: float = DEFAULT_SIGMA,
    n_samples: int = DEFAULT_N_SAMPLES,
    n_vectors: int = DEFAULT_N_VECTORS,
    seed: int = 0,
    min_size: int | None = None,
    spatial_weight: float = DEFAULT_SPATIAL_WEIGHT,
    feature_weight: float = DEFAULT_FEATURE_WEIGHT,
    fit_points: int = _rgbd_rs.OVERSEG_DEFAULT_FIT_POINTS,
    channel_weights: npt.ArrayLike | None = None,
    quiet: bool = True,
) -> I32:
    """Over-segment an ``H x W x D`` float32 feature image by Nyström normalized cuts.

    Args:
        features: ``H x W x D`` (D = 9 for eq. 4.1), or the
            :class:`~rgbd_rs.segmentation.features.Features` of
            :func:`~rgbd_rs.segmentation.features.features` (its ``vectors``); a pixel with NaN
            on any channel is excluded. Infinite values are refused.
        n_segments: k-means clusters (>= 1, at most the valid pixels). The output has about
            this many segments: splitting disconnected clusters adds some, absorbing fragments
            removes some.
        sigma: affinity width (> 0).
        n_samples: Nyström samples m (2..=:data:`MAX_N_SAMPLES`; capped at the number of valid
            pixels).
        n_vectors: embedding dimensions (>= 1, fewer than the effective m).
        seed: seeds the sample draw and k-means (>= 0).
        min_size: components smaller than this (pixels) are absorbed by their longest-boundary
            neighbour; default ``max(1, round(MIN_SIZE_FRACTION * n_valid / n_segments))``
            (134 px with the defaults on a full 640x480 frame). 1 disables the absorption.
        spatial_weight: weight of the pixel position in k-means (>= 0).
        feature_weight: weight of the input features themselves in k-means (>= 0; 0 = the
            spectral embedding alone).
        fit_points: pixels the k-means centres are fitted on (>= n_segments).
        channel_weights: ``D`` weights (>= 0, not all 0) the channels are multiplied by before
            everything else; default :func:`default_channel_weights` (for the 9-D eq. 4.1
            layout: colour 1, position 0.5, normal 0.15).
        quiet: no progress bar (it shows only on a terminal anyway).

    Returns:
        ``H x W`` int32 labels ``0..K-1`` (contiguous, in raster order of first pixel), -1
        exactly on the excluded pixels.
    """
    if isinstance(features, Features):
        features = features.vectors
    f = _validate.asarray("features", features)
    if f.ndim != 3:
        raise ShapeMismatchError(f"features: got shape {tuple(f.shape)}, expected (H, W, D)")
    if f.dtype.kind != "f":
        raise InvalidArgumentError(
            f"features: got dtype {f.dtype}, expected a float array (NaN marks excluded pixels)"
        )
    f = _validate.array("features", f, shape=(None, None, None))
    h, w, d = f.shape
    _validate.size("features height", h)
    _validate.size("features width", w)
    _validate.integer("features channels", d, maximum=MAX_CHANNELS)
    if np.isinf(f).any():
        raise InvalidArgumentError(
            f"features: got {int(np.isinf(f).sum())} infinite values, expected finite values "
            "or NaN for excluded pixels"
        )
    if channel_weights is None:
        weights = default_channel_weights(d)
    else:
        weights = _validate.array("channel_weights", channel_weights, shape=(d,), finite=True)
        if (weights < 0).any() or not (weights > 0).any():
            raise InvalidArgumentError(
                f"channel_weights: got {weights.tolist()}, expected weights >= 0, not all 0"
            )
    if not (weights == 1).all():
        f = np.ascontiguousarray(f * weights.astype(np.float32))
    k = _validate.integer("n_segments", n_segments, minimum=1)
    s = _validate.real("sigma", sigma, positive=True)
    m = _validate.integer("n_samples", n_samples, minimum=2, maximum=MAX_N_SAMPLES)
    nv = _validate.integer("n_vectors", n_vectors, minimum=1)
    sd = _validate.integer("seed", seed, minimum=0, maximum=2**64 - 1)
    sw = _validate.real("spatial_weight", spatial_weight, nonnegative=True)
    fw = _validate.real("feature_weight", feature_weight, nonnegative=True)
    fp = _validate.integer("fit_points", fit_points, minimum=1)
    n_valid = int(np.count_nonzero(~np.isnan(f).any(axis=2)))
    if n_valid < 2:
        raise InvalidArgumentError(
            f"features: got {n_valid} valid pixels, expected at least 2 pixels whose channels "
            "are all finite (NaN marks excluded pixels)"
        )
    if k > n_valid:
        raise InvalidArgumentError(
            f"n_segments: got {k}, expected at most the {n_valid} valid pixels"
        )
    if nv >= min(m, n_valid):
        raise InvalidArgumentError(
            f"n_vectors: got {nv}, expected fewer than the {min(m, n_valid)} Nyström samples "
            "(n_samples capped at the valid pixels)"
        )
    if fp < k:
        raise InvalidArgumentError(f"fit_points: got {fp}, expected >= n_segments = {k}")
    if not isinstance(quiet, (bool, np.bool_)):
        raise InvalidArgumentError(f"quiet: got {quiet!r}, expected True or False")
    if min_size is None:
        ms = max(1, round(MIN_SIZE_FRACTION * n_valid / k))
    else:
        ms = _validate.integer("min_size", min_size, minimum=1)
    with tqdm(total=1, desc="oversegment", unit="frame", disable=True if quiet else None) as bar:
        labels, _count = _rgbd_rs.oversegment(f, k, s, m, nv, sd, ms, sw, fw, fp)
        bar.update(1)
    return np.asarray(labels, dtype=np.int32)
