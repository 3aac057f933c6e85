"""Real stereo scenes as fusion cases: the 27 Middlebury pairs of ``../shared/data/stereo``
(:mod:`rgbd_rs.data.stereo_scenes`, their train / val / test split) with a ToF frame simulated
from each scene's ground truth under a sensor *law* drawn per case.

A law is drawn the way the synthetic set's sensors are (:mod:`rgbd_rs.data.tof_variation`:
modulation frequency, emitter power, read and shot noise, multipath rays, mixed-pixel
sub-sampling, flying pixels, the amplitude's unit over five orders of magnitude), plus what a
real scene needs beyond it: the ToF resolution, 1/4 to 1/2 of the colour camera's width (a real
ToF sensor is coarser than the colour camera beside it), and dark dropouts (blobs where the
ToF returns nothing, 0-3 % of its pixels, as on dark or glossy surfaces; the scenes' untextured
IR albedo would otherwise never drop a pixel).

For training pools there is also a *dense* family (``dense=True``): the same sensor draws with
the ToF as fine as the colour camera or finer (:data:`DENSE_TOF_SCALE`), the regime of a
Kinect-class ToF beside a stereo pair, where the ToF is often far better than the stereo map.

The rig is virtual (the 2005 sets' focal scaled with the width, 160 mm baseline, the ToF 4 cm
below the left camera, reference = left view, where the ground truth lives), as in
:func:`~rgbd_rs.fusion.evaluate.middlebury_sample`. Validation and test cases use fixed seeds
(law ``k`` of a scene always draws the same sensor); ``epoch=`` draws another sensor per
epoch for training (``tools/train_confidence_real.py`` trains on a fixed pool of laws instead).
"""

from __future__ import annotations

import hashlib
from collections.abc import Iterator, Sequence
from dataclasses import dataclass

import cv2
import numpy as np

from rgbd_rs import _validate
from rgbd_rs.data import tof_variation
from rgbd_rs.data.stereo_scenes import (
    SPLITS,
    StereoScene,
    _right_view_scenes,
    load_stereo_scene,
    scene_names,
)
from rgbd_rs.errors import InvalidArgumentError
from rgbd_rs.fusion._inputs import with_reference
from rgbd_rs.fusion.evaluate import PROTOCOL_TOF_SIZE, Sample, simulate_tof

#: The ToF camera's width as a fraction of the colour camera's (uniform).
TOF_SCALE = (0.25, 0.5)
#: The same for the *dense* laws (``dense=True``): a ToF as fine as the colour camera or finer,
#: as the old three-scene protocol's 512 x 424 sensor on the ~450 px wide images
#: (``rgbd eval fusion --real SPLIT --dense``). Training pools only: the benchmark's laws stay
#: coarse.
DENSE_TOF_SCALE = (0.9, 1.4)
#: The dense *protocol* of ``rgbd eval fusion --real SPLIT --dense`` (the old three-scene protocol's
#: simulation): a ToF of this many (columns, rows) and the default sensor, this seed.
DENSE_PROTOCOL_SIZE = PROTOCOL_TOF_SIZE
DENSE_PROTOCOL_SEED = 0
#: Fraction of ToF pixels lost to dark dropouts (uniform) and the blobs' size (ToF pixels).
DROPOUT_FRACTION = (0.0, 0.03)
DROPOUT_BLOB = 6.0


@dataclass(frozen=True)
class Law:
    """One case's sensor: the simulator's variation, the ToF size and the dropout share."""

    variation: tof_variation.ToFVariation
    tof_size: tuple[int, int]
    dropout: float


def _seed(name: str, law: int, epoch: int | None, dense: bool = False) -> int:
    """A stable seed of (scene, law, epoch): independent of Python's hash randomisation (the
    dense family's keys differ, so its draws are not the coarse laws')."""
    key = f"{name}/{law}/{'fixed' if epoch is None else epoch}{'/dense' if dense else ''}"
    return int.from_bytes(hashlib.sha256(key.encode()).digest()[:8], "little")


def _draw_law(rng: np.random.Generator, width: int, height: int, dense: bool = False) -> Law:
    """A sensor for a ``width x height`` colour camera (``dense``: :data:`DENSE_TOF_SCALE`)."""
    variation = tof_variation.random_variation(rng)
    scale = float(rng.uniform(*(DENSE_TOF_SCALE if dense else TOF_SCALE)))
    tw = max(16, round(width * scale))
    th = max(16, round(height * scale))
    return Law(variation, (tw, th), float(rng.uniform(*DROPOUT_FRACTION)))


def _dropouts(depth: np.ndarray, fraction: float, rng: np.random.Generator) -> np.ndarray:
    """``depth`` with blobs covering ``fraction`` of its pixels set to NaN."""
    if fraction <= 0:
        return depth
    noise = rng.standard_normal(depth.shape).astype(np.float32)
    field = np.asarray(cv2.GaussianBlur(noise, (0, 0), DROPOUT_BLOB), np.float32)
    cut = np.quantile(field, fraction)
    out = depth.copy()
    out[field <= cut] = np.nan
    return out


def real_sample(
    scene: StereoScene | str,
    law: int = 0,
    *,
    epoch: int | None = None,
    dense: bool = False,
    view: str = "left",
) -> Sample:
    """Scene ``scene`` (a :class:`~rgbd_rs.data.stereo_scenes.StereoScene`, or a scene's name,
    read by :func:`~rgbd_rs.data.stereo_scenes.load_stereo_scene`) with the ToF frame of its law
    ``law`` (``epoch=None``: the fixed law of validation and test; an epoch number: that epoch's
    training draw). ``dense`` draws from the dense family instead (:data:`DENSE_TOF_SCALE`; its
    own seeds). The sample's name is ``<scene>_law<k>`` (``<scene>_dense<k>``).

    ``view="right"`` fuses on the right camera instead, the one farther from the ToF (the same ToF
    frame; the ground truth of the right view; ``_right`` appended to the name): what a user gets
    who fuses on the camera not beside the ToF. Scenes without right-view ground truth are
    refused."""
    if isinstance(scene, str):
        scene = load_stereo_scene(scene)
    elif not isinstance(scene, StereoScene):
        raise InvalidArgumentError(
            f"scene: got {type(scene).__name__}, expected a StereoScene or a scene's name"
        )
    law = _validate.integer("law", law, minimum=0)
    if epoch is not None:
        epoch = _validate.integer("epoch", epoch, minimum=0)
    dense = _validate.flag("dense", dense)
    side = _validate.choice("view", view, ("left", "right"))
    if side == "right" and scene.disparity_right is None:
        raise InvalidArgumentError(
            f"view: got 'right' for {scene.name}, expected a scene with right-view ground truth"
        )
    rng = np.random.default_rng(_seed(scene.name, law, epoch, dense))
    h, w = scene.left.shape[:2]
    drawn = _draw_law(rng, w, h, dense)
    gt = scene.disparity_left
    depth, amplitude, rig = simulate_tof(
        gt, drawn.tof_size, drawn.variation.model, int(rng.integers(2**31))
    )
    depth, amplitude = tof_variation.apply(depth, amplitude, drawn.variation, rng)
    depth = _dropouts(depth, drawn.dropout, rng)
    kind = "dense" if dense else "law"
    name = f"{scene.name}_{kind}{law}"
    if side == "right":
        assert scene.disparity_right is not None  # checked above
        rig, gt, name = with_reference(rig, "right"), scene.disparity_right, f"{name}_right"
    return Sample(name, scene.left, scene.right, depth, amplitude, rig, gt)


def real_samples(
    split: str,
    laws: int = 2,
    *,
    epoch: int | None = None,
    root: str | None = None,
    dense_laws: int = 0,
    view: str = "left",
    scenes: Sequence[str] | None = None,
) -> Iterator[Sample]:
    """Every scene of ``split`` (or only ``scenes``, names of that split, in the split's order)
    under ``laws`` sensor laws each, then ``dense_laws`` laws of the dense family (scene-major
    order; at least one law in all). The arguments are checked at the call, the scenes read as
    the iterator is consumed. ``view``: as :func:`real_sample`; with ``"right"`` the scenes
    without right-view ground truth are left out."""
    _validate.choice("split", split, SPLITS)
    laws = _validate.integer("laws", laws, minimum=0, maximum=64)
    dense_laws = _validate.integer("dense_laws", dense_laws, minimum=0, maximum=64)
    if laws + dense_laws == 0:
        raise InvalidArgumentError(
            "laws: got 0 laws and 0 dense_laws, expected at least one law per scene"
        )
    if epoch is not None:
        epoch = _validate.integer("epoch", epoch, minimum=0)
    side = _validate.choice("view", view, ("left", "right"))
    names = _chosen_scenes(split, root, scenes)
    if side == "right":  # the manifest says which scenes have right-view ground truth
        seen = set(_right_view_scenes(root))
        blind = [n for n in names if n not in seen]
        if blind and scenes is not None:
            raise InvalidArgumentError(
                f"scenes: got {blind[0]!r} with view='right', expected scenes with right-view "
                "ground truth"
            )
        names = [n for n in names if n in seen]

    def cases() -> Iterator[Sample]:
        for name in names:
            scene = load_stereo_scene(name, root)
            for k in range(laws):
                yield real_sample(scene, k, epoch=epoch, view=side)
            for k in range(dense_laws):
                yield real_sample(scene, k, epoch=epoch, dense=True, view=side)

    return cases()


def _chosen_scenes(split: str, root: str | None, scenes: Sequence[str] | None) -> list[str]:
    """The scene names of ``split``, or those of ``scenes`` (each a scene of that split; at least
    one) in the split's order."""
    names = scene_names(split, root)
    if scenes is None:
        return names
    if isinstance(scenes, str) or not isinstance(scenes, Sequence):
        raise InvalidArgumentError(
            f"scenes: got {scenes!r}, expected a list of scene names (or None for all)"
        )
    unknown = [n for n in scenes if n not in names]
    if unknown or not scenes:
        got = repr(unknown[0]) if unknown else "no scene"
        raise InvalidArgumentError(
            f"scenes: got {got}, expected scenes of the {split} split: {', '.join(names)}"
        )
    return [n for n in names if n in scenes]


def dense_protocol_samples(
    split: str, *, root: str | None = None, scenes: Sequence[str] | None = None
) -> Iterator[Sample]:
    """Every scene of ``split`` (or only ``scenes``, as in :func:`real_samples`) with the dense
    protocol's ToF frame (:data:`DENSE_PROTOCOL_SIZE` of the default
    :class:`~rgbd_rs.render.ToFModel`, seed :data:`DENSE_PROTOCOL_SEED`): finer than the ~450 px
    wide colour images and far more precise than the stereo map. Named ``<scene>_dense``;
    ``split`` and ``scenes`` are checked at the call."""
    from rgbd_rs.render import ToFModel

    _validate.choice("split", split, SPLITS)
    names = _chosen_scenes(split, root, scenes)

    def cases() -> Iterator[Sample]:
        for name in names:
            scene = load_stereo_scene(name, root)
            gt = scene.disparity_left
            depth, amplitude, rig = simulate_tof(
                gt, DENSE_PROTOCOL_SIZE, ToFModel(), DENSE_PROTOCOL_SEED
            )
            yield Sample(f"{name}_dense", scene.left, scene.right, depth, amplitude, rig, gt)

    return cases()
