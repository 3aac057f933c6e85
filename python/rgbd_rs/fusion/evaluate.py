"""Evaluation of the fusion pipeline (thesis Table 3.2 protocol and Fig. 3.4).

RMS disparity error against ground truth on the pixels that are non-occluded (visible in the
other stereo view) and valid in every compared map, per scene and averaged over scenes, for:
interpolated ToF, SGM, LC uniform, LC heuristic, and LC with given confidences — here the
GT-derived "oracle" confidences ``1 - min(|err|, T) / T`` (the ConvNet's training target, so an
upper bound for a learned confidence; T = ``ORACLE_T``).

Datasets: the synthetic test set (:mod:`rgbd_rs.data.synth`), and the Middlebury pairs of
``../shared/data`` with a ToF frame simulated from their ground truth (:func:`middlebury_sample`).
"""

from __future__ import annotations

from collections.abc import Iterable, Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
import numpy.typing as npt
from tqdm import tqdm

from rgbd_rs.camera import PinholeCamera, Pose, StereoRig, ToFStereoRig
from rgbd_rs.data.middlebury import load_middlebury
from rgbd_rs.data.paths import data_root
from rgbd_rs.data.synth import SynthDataset
from rgbd_rs.errors import InvalidArgumentError, RgbdError
from rgbd_rs.fusion._inputs import F32, U8, views
from rgbd_rs.fusion.clues import _target_confidence
from rgbd_rs.fusion.crosscheck import _warp_to_target
from rgbd_rs.fusion.fuse import fuse
from rgbd_rs.fusion.lc import LcParams, lc_fuse
from rgbd_rs.meshes import Mesh

if TYPE_CHECKING:  # torch is imported only when a ConvNet is evaluated
    from rgbd_rs.nn.confidence import ConfidenceEstimator
from rgbd_rs._array_eq import array_eq
from rgbd_rs.metrics import bad_pixel_rate, edge_band, rms_error
from rgbd_rs.render import Material, Scene, ToFModel
from rgbd_rs.viz import as_bgr, grid, image_panel, map_panel, save_png

METHODS = ("Interpolated ToF", "SGM", "LC uniform", "LC heuristic", "LC oracle confidence")
#: The learned-confidence row, evaluated when an estimator is given (before the oracle).
CONVNET = "LC ConvNet"
#: Band around ground-truth depth edges where the edge measures are taken (px).
EDGE_BAND = 2
#: Bad-pixel thresholds (px).
BAD_THRESHOLDS = (1.0, 2.0)
#: Error (px) at which the oracle confidence reaches 0. Chosen (METHOD_NOTES §3: T unknown).
ORACLE_T = 3.0
#: Middlebury virtual rig: the 2005/2006 sets' focal (3740 px at full size, here scaled with the
#: image width) and 160 mm baseline; the ToF 512x424 sits 4 cm below, as in the synthetic rig.
MIDDLEBURY_FOCAL_PER_WIDTH = 3740.0 / 1390.0
MIDDLEBURY_BASELINE = 0.16
#: The ToF sees slightly more than the colour camera (its focal is this much shorter).
TOF_FOV_MARGIN = 1.1
#: The protocol's ToF camera, (columns, rows): Kinect v2's 512 x 424.
PROTOCOL_TOF_SIZE = (512, 424)
#: The virtual ToF camera sits this far below the left camera (metres).
TOF_OFFSET_Y = 0.04
#: Mesh triangles spanning a depth ratio above this are depth edges and are dropped.
EDGE_RATIO = 1.03


@array_eq
@dataclass(frozen=True)
class Sample:
    """One evaluation input: the pair, the ToF frame, the rig and GT on the reference view."""

    name: str
    left: U8
    right: U8
    tof_depth: F32
    tof_amplitude: F32
    rig: ToFStereoRig
    gt_disparity: F32


@array_eq
@dataclass
class SceneResult:
    """Per method: ``rms`` (all compared pixels) and ``measures`` (``rms``, ``bad1``, ``bad2``,
    ``edge_rms``, ``edge_bad1``, ``edge_bad2``: bad-pixel fractions, and the same measures in a
    ``EDGE_BAND``-pixel band around ground-truth depth edges)."""

    name: str
    rms: dict[str, float]
    pixels: int
    maps: dict[str, F32] = field(default_factory=dict, repr=False)
    measures: dict[str, dict[str, float]] = field(default_factory=dict)
    edge_pixels: int = 0

    @property
    def methods(self) -> tuple[str, ...]:
        """The methods evaluated, in table order."""
        return tuple(self.rms)


def _target_columns(
    d: F32, target_sign: int
) -> tuple[npt.NDArray[np.intp], npt.NDArray[np.intp], npt.NDArray[np.int64]]:
    """``(ys, xs, tx)``: every pixel with a disparity and its target column ``x + sign * d``,
    rounded (it may lie outside the image)."""
    ys, xs = np.nonzero(np.isfinite(d))
    return ys, xs, np.rint(xs + target_sign * d[ys, xs]).astype(np.int64)


def outside_target_view(disparity: npt.ArrayLike, target_sign: int) -> npt.NDArray[np.bool_]:
    """Pixels of the reference view whose target column lies outside the target image: the
    other camera cannot see them (never :func:`non_occluded`)."""
    d = np.asarray(disparity, np.float32)
    ys, xs, tx = _target_columns(d, target_sign)
    out = np.zeros(d.shape, bool)
    out[ys, xs] = (tx < 0) | (tx >= d.shape[1])
    return out


def non_occluded(disparity: npt.ArrayLike, target_sign: int) -> npt.NDArray[np.bool_]:
    """Pixels of the reference view visible in the target view: no nearer reference pixel
    (larger disparity) lands on the same target pixel (within 1 px of disparity)."""
    d = np.asarray(disparity, np.float32)
    front, _ = _warp_to_target(d, None, target_sign)  # the nearest disparity per target pixel
    ys, xs, tx = _target_columns(d, target_sign)
    inside = (tx >= 0) & (tx < d.shape[1])
    out = np.zeros(d.shape, bool)
    ys, xs, tx = ys[inside], xs[inside], tx[inside]
    out[ys, xs] = d[ys, xs] >= front[ys, tx] - 1.0
    return out


def _depth_mesh(depth: F32, camera: PinholeCamera) -> Mesh:
    """A triangle mesh of a depth map (two triangles per pixel quad; depth edges dropped)."""
    h, w = depth.shape
    pts = camera.depth_to_points(depth).reshape(-1, 3)
    idx = np.arange(h * w).reshape(h, w)
    quads = [idx[:-1, :-1], idx[:-1, 1:], idx[1:, :-1], idx[1:, 1:]]
    tris = np.concatenate(
        [np.stack([quads[0], quads[2], quads[1]], -1), np.stack([quads[1], quads[2], quads[3]], -1)]
    ).reshape(-1, 3)
    z = depth.reshape(-1)[tris]
    ok = np.isfinite(z).all(1)
    zmin = np.where(ok, z.min(1), 1.0)
    ok &= np.where(ok, z.max(1), 1.0) / zmin < EDGE_RATIO
    return Mesh(np.nan_to_num(pts).astype(np.float32), tris[ok].astype(np.uint32))


def middlebury_sample(folder: str | Path, seed: int = 0, model: ToFModel | None = None) -> Sample:
    """A Middlebury pair with a simulated ToF frame (reference = left view, where GT lives).

    The left GT disparity becomes depth on a virtual rig (f = 3740 px x width / 1390, b = 160 mm,
    the 2005 sets' full-size values scaled), is meshed (depth edges cut), and rendered by the
    ToF simulator (:class:`~rgbd_rs.render.ToFModel` defaults: mixed pixels, multipath, noise,
    dropout) from a 512x424 ToF camera 4 cm below the left camera whose field of view covers it.
    """
    pair = load_middlebury(folder)
    depth, amplitude, rig = simulate_tof(
        pair.disparity_left, PROTOCOL_TOF_SIZE, model or ToFModel(), seed
    )
    return Sample(pair.name, pair.left, pair.right, depth, amplitude, rig, pair.disparity_left)


def simulate_tof(
    gt_left: F32, tof_size: tuple[int, int], model: ToFModel, seed: int
) -> tuple[F32, F32, ToFStereoRig]:
    """``(depth, amplitude, rig)``: the ToF frame a ``tof_size`` ToF camera 4 cm below the left
    camera of the Middlebury virtual rig (f = 3740 px x width / 1390, b = 160 mm; the ToF sees a
    little more than the colour camera) measures of the mesh of the left ground truth
    ``gt_left`` (pixels; depth edges cut), simulated with ``model``."""
    h, w = gt_left.shape
    f = MIDDLEBURY_FOCAL_PER_WIDTH * w
    cam = PinholeCamera(f, f, (w - 1) / 2, (h - 1) / 2, w, h)
    with np.errstate(divide="ignore", invalid="ignore"):
        z = np.where(gt_left > 0, MIDDLEBURY_BASELINE * f / gt_left, np.nan).astype(np.float32)
    tw, th = tof_size
    tof_f = f * tw / w * TOF_FOV_MARGIN
    tof_cam = PinholeCamera(tof_f, tof_f, (tw - 1) / 2, (th - 1) / 2, tw, th)
    to_ref = Pose(np.eye(3), np.array([0.0, TOF_OFFSET_Y, 0.0]))
    scene = Scene().add(_depth_mesh(z, cam), Material(albedo_ir=0.5)).build()
    frame = scene.tof(tof_cam, to_ref.inverse(), model, seed=seed)
    rig = ToFStereoRig(tof_cam, StereoRig(cam, cam, MIDDLEBURY_BASELINE), to_ref, "left")
    return frame.depth, frame.amplitude, rig


def middlebury_samples(seed: int = 0) -> list[Sample]:
    """Every Middlebury pair of the shared data (``$RGBD_DATA`` or ../shared/data), with its ToF
    frame simulated by :func:`middlebury_sample`, sorted by name; an error names the folder when
    the shared data is missing."""
    root = data_root(required=True)
    assert root is not None  # required=True raises instead
    folder = root / "middlebury"
    if not folder.is_dir():
        raise RgbdError(f"{folder}: not found, expected the Middlebury pairs of the shared data")
    return [middlebury_sample(p, seed) for p in sorted(folder.iterdir()) if p.is_dir()]


def synth_samples(root: str | Path, split: str = "test") -> Iterator[Sample]:
    """The synthetic dataset's scenes as evaluation samples."""
    ds = SynthDataset(root, "test" if split == "test" else "train")
    rig = ds.rig
    for i in range(len(ds)):
        s = ds[i]
        yield Sample(
            f"{split}_{i:02d}", s.left, s.right, s.tof_depth, s.tof_amplitude, rig, s.gt_disparity
        )


def _measures(
    d: F32, gt: F32, mask: npt.NDArray[np.bool_], band: npt.NDArray[np.bool_]
) -> dict[str, float]:
    out: dict[str, float] = {"rms": rms_error(d, gt, mask)}
    for t in BAD_THRESHOLDS:
        out[f"bad{t:g}"] = bad_pixel_rate(d, gt, t, mask)
    edge = mask & band
    if edge.any():
        out["edge_rms"] = rms_error(d, gt, edge)
        for t in BAD_THRESHOLDS:
            out[f"edge_bad{t:g}"] = bad_pixel_rate(d, gt, t, edge)
    return out


def evaluate_sample(
    s: Sample, params: LcParams | None = None, estimator: ConfidenceEstimator | None = None
) -> SceneResult:
    """Every method on one sample, measured on the common valid non-occluded pixels; with an
    ``estimator``, also LC with the ConvNet's confidences (:data:`CONVNET`)."""
    # Every row on the matcher the network was trained on (its clues come from it).
    out = fuse(
        s.left,
        s.right,
        s.tof_depth,
        s.tof_amplitude,
        s.rig,
        confidence="heuristic",
        params=params,
        stereo=None if estimator is None else estimator.matcher,
    )
    ref, tgt, sign = views(s.left, s.right, s.rig.reference)
    tof_d, st_d = out.tof_fused, out.stereo_disparity
    uni, _ = lc_fuse(ref, tgt, [tof_d, st_d], None, target_sign=sign, params=params)
    gt = s.gt_disparity

    def oracle(d: F32) -> F32:
        return np.nan_to_num(_target_confidence(d, gt, ORACLE_T))  # undefined -> weight 0

    orc, _ = lc_fuse(
        ref, tgt, [tof_d, st_d], [oracle(tof_d), oracle(st_d)], target_sign=sign, params=params
    )
    maps = dict(zip(METHODS, (tof_d, st_d, uni, out.disparity, orc), strict=True))
    if estimator is not None:
        p_t, p_s = estimator(ref, tgt, tof_d, out.tof.amplitude, st_d, reference=s.rig.reference)
        net, _ = lc_fuse(ref, tgt, [tof_d, st_d], [p_t, p_s], target_sign=sign, params=params)
        maps = {k: maps[k] for k in METHODS[:4]} | {CONVNET: net, METHODS[4]: orc}
        maps["P_T"], maps["P_S"] = p_t, p_s
    methods = [k for k in maps if k not in ("P_T", "P_S")]
    mask = np.isfinite(gt) & non_occluded(gt, sign)
    for k in methods:
        mask &= np.isfinite(maps[k])
    if not mask.any():
        raise RgbdError(f"{s.name}: no pixel is valid in every map; nothing to evaluate")
    band = edge_band(gt, EDGE_BAND)
    measures = {k: _measures(maps[k], gt, mask, band) for k in methods}
    rms = {k: m["rms"] for k, m in measures.items()}
    maps["gt"] = gt
    maps["mask"] = mask.astype(np.float32)
    return SceneResult(s.name, rms, int(mask.sum()), maps, measures, int((mask & band).sum()))


def markdown_table(results: list[SceneResult], title: str) -> str:
    """Per-scene RMS and the average over scenes (thesis Table 3.2 layout, transposed), then the
    scene-averaged bad-pixel rates and the same measures in the band around depth edges."""
    if not results:
        raise InvalidArgumentError("results: got no scene, expected at least one")
    methods = results[0].methods
    head = "| scene | pixels | " + " | ".join(methods) + " |"
    rule = "|---|---:|" + "---:|" * len(methods)
    rows = [
        f"| {r.name} | {r.pixels} | " + " | ".join(f"{r.rms[k]:.3f}" for k in methods) + " |"
        for r in results
    ]
    avg = {k: float(np.mean([r.rms[k] for r in results])) for k in methods}
    rows.append("| **mean** | | " + " | ".join(f"**{avg[k]:.3f}**" for k in methods) + " |")
    text = f"### {title}\n\nRMS disparity error (px)\n\n" + "\n".join([head, rule, *rows])
    keys = [("rms", "RMS (px)")] + [(f"bad{t:g}", f"> {t:g} px (%)") for t in BAD_THRESHOLDS]
    keys += [(f"edge_{k}", f"edge band {label}") for k, label in keys]
    head2 = "| measure (mean over scenes) | " + " | ".join(methods) + " |"
    rows2 = []
    for key, label in keys:
        vals = [[r.measures[k][key] for r in results if key in r.measures[k]] for k in methods]
        if not all(vals):
            continue
        scale = 100.0 if "bad" in key else 1.0
        cells = " | ".join(f"{scale * float(np.mean(v)):.3f}" for v in vals)
        rows2.append(f"| {label} | {cells} |")
    text += (
        f"\n\nAll compared pixels and a {EDGE_BAND}-px band around ground-truth depth edges "
        f"({sum(r.edge_pixels for r in results)} of {sum(r.pixels for r in results)} pixels)\n\n"
        + "\n".join([head2, "|---|" + "---:|" * len(methods), *rows2])
    )
    return text + "\n"


def figure(samples: list[Sample], results: list[SceneResult]) -> U8:
    """BGR picture in the thesis Fig. 3.4 layout, two rows of four 480-px panels per scene:
    colour, ground truth, ToF, stereo; the fused map (the ConvNet fusion when it was run, else
    the heuristic one) and the |error| of ToF, stereo and fused wherever the map and the ground
    truth have a value (the RMS in the title is over the pixels every compared map shares).
    Disparities share one colour bar in px, errors one of 0..``ORACLE_T`` px (larger errors in
    its top colour); pixels without a value are the "no data" grey."""
    panels = []
    for s, r in zip(samples, results, strict=True):
        gt = r.maps["gt"]
        lo, hi = float(np.nanpercentile(gt, 1)), float(np.nanpercentile(gt, 99))
        ref = s.right if s.rig.reference == "right" else s.left
        fused = CONVNET if CONVNET in r.maps else "LC heuristic"
        shown = (
            ("Interpolated ToF", "Interpolated ToF"),
            ("SGM", "SGM"),
            (fused, f"fused ({fused})"),
        )
        panels += [
            image_panel(as_bgr(ref), f"{s.name}: colour ({s.rig.reference} camera)"),
            map_panel(gt, "ground-truth disparity", unit="px", vmin=lo, vmax=hi),
        ]
        panels += [
            map_panel(r.maps[k], f"{short} disparity", unit="px", vmin=lo, vmax=hi)
            for k, short in shown[:2]
        ]
        panels.append(map_panel(r.maps[fused], shown[2][1], unit="px", vmin=lo, vmax=hi))
        for key, short in shown:
            err = np.abs(r.maps[key] - gt)
            name = short.split(" (")[0]
            title = f"{name} |error| (RMS {r.rms[key]:.2f} px shared; red >= {ORACLE_T:g})"
            panels.append(map_panel(err, title, unit="px", vmin=0.0, vmax=ORACLE_T))
    return grid(panels, columns=4)


def confidence_figure(samples: list[Sample], results: list[SceneResult]) -> U8:
    """BGR picture in the thesis Fig. 3.5 layout: colour view, estimated ToF confidence, estimated
    stereo confidence (1 = reliable), beside the GT-derived targets for comparison; one row of
    five 480-px panels per scene, "no data" grey."""
    panels = []
    for s, r in zip(samples, results, strict=True):
        ref = views(s.left, s.right, s.rig.reference)[0]
        gt = r.maps["gt"]
        panels.append(image_panel(as_bgr(ref), f"{s.name}: colour"))
        for key, src, short in (("P_T", "Interpolated ToF", "ToF"), ("P_S", "SGM", "stereo")):
            target = _target_confidence(r.maps[src], gt, ORACLE_T)
            panels += [
                map_panel(r.maps[key], f"{short} confidence (ConvNet)", unit="", vmin=0, vmax=1),
                map_panel(target, f"{short} target (GT)", unit="", vmin=0, vmax=1),
            ]
    return grid(panels, columns=5)


def evaluate(
    samples: Iterable[Sample],
    out: str | Path | None,
    *,
    title: str,
    figure_rows: int = 5,
    params: LcParams | None = None,
    estimator: ConfidenceEstimator | None = None,
    quiet: bool = False,
) -> list[SceneResult]:
    """Evaluate every sample; with ``out``, write ``OUT/table.md`` and ``OUT/figure.png`` (and,
    with an ``estimator``, ``OUT/confidence.png``: thesis Fig. 3.5's colour, P_T, P_S)."""
    results: list[SceneResult] = []
    shown: list[Sample] = []
    for s in tqdm(list(samples), desc=title, disable=quiet, unit="scene"):
        r = evaluate_sample(s, params, estimator)
        if len(shown) < figure_rows:
            shown.append(s)
        else:
            r.maps = {}
        results.append(r)
    if out is not None:
        folder = Path(out)
        folder.mkdir(parents=True, exist_ok=True)
        (folder / "table.md").write_text(markdown_table(results, title))
        save_png(folder / "figure.png", figure(shown, results[: len(shown)]))
        if estimator is not None:
            save_png(folder / "confidence.png", confidence_figure(shown, results[: len(shown)]))
    return results
