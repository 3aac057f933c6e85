"""The camera models of the synthetic indoor frames (:mod:`rgbd_rs.data.synth_indoor`); private.

Colour: the renderer's linear radiance, windows glowing with daylight, auto-exposure, white
balance, blur, vignetting, sRGB gamma, noise, 8 bits.

Depth: a Kinect v1 (structured light). The depth of a pixel comes from the disparity
``d = f b / z`` of the projected pattern, measured to 1/8 pixel; its standard deviation is
``sigma_z = k z^2`` with ``k`` around 1.425e-3 / m (Khoshelham & Elberink 2012; the noise added
before quantisation is set so noise and quantisation together give ``k z^2``), the noise partly
spatially correlated, edges jagged by a pixel. Holes: surfaces too dark for the IR pattern (low
IR albedo, far, grazing), glossy surfaces (screens) in blobs, window glass, grazing angles, the
projector's shadow beside depth edges (a second render from the projector, ``b`` to the side),
thin bands along depth edges, and ranges below ~0.5 m and beyond ~4-6 m. Every constant is
drawn per frame from a range.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import cv2
import numpy as np
import numpy.typing as npt
from scipy.special import ndtr

from rgbd_rs.camera import Pose
from rgbd_rs.render import GBuffer, RenderScene

if TYPE_CHECKING:
    from rgbd_rs.data.synth_indoor_scene import IndoorScene

F32 = npt.NDArray[np.float32]
Rng = np.random.Generator

#: Colour camera: mid-grey level the auto-exposure aims the scene's mean log luminance at
#: (linear), and the white-balance gains of red and blue (green = 1; indoor light is warm).
EXPOSURE = (0.045, 0.18)
GAIN_R = (1.0, 1.4)
GAIN_B = (0.75, 1.1)
#: Radiance of window glass and of lamps relative to the room's mean (overexposed mostly).
WINDOW_GLOW = (2.5, 14.0)
LAMP_GLOW = (6.0, 25.0)
#: Share of frames with motion blur, and its length (pixels at 640 x 480).
P_MOTION_BLUR = 0.2
MOTION_BLUR = (2.0, 9.0)
#: Kinect v1 depth noise: sigma_z = k z^2, k in m^-1 (Khoshelham & Elberink 2012), drawn from
#: this range around 1.425e-3.
NOISE_K = (1.0e-3, 1.85e-3)
#: Disparity sub-pixel step of the Kinect v1 (pixels).
DISPARITY_STEP = 1.0 / 8.0
#: IR focal length (pixels) and projector-camera baseline (m) of the Kinect v1.
IR_FOCAL = (570.0, 600.0)
BASELINE = (0.07, 0.08)
#: Nearest measurable depth, and the start and width (m) of the far dropout ramp.
NEAR = (0.45, 0.6)
FAR_START = (4.5, 6.5)
FAR_RAMP = (0.5, 2.0)
#: IR albedo x cos(incidence) / z^2 (m^-2) below which the pattern is lost (black surfaces).
WEAK_SIGNAL = (0.0005, 0.003)
#: Cosine of the incidence angle below which holes appear.
GRAZING_COS = (0.08, 0.25)


def _smooth_normal(rng: Rng, h: int, w: int, cell: float) -> F32:
    """Unit-variance Gaussian noise correlated over ~``cell`` pixels."""
    sh, sw = max(2, int(h / cell) + 2), max(2, int(w / cell) + 2)
    low = rng.standard_normal((sh, sw)).astype(np.float32)
    up = cv2.resize(low, (w, h), interpolation=cv2.INTER_CUBIC)
    sd = float(up.std())
    return np.asarray(up / (sd if sd > 0 else 1.0), np.float32)


def _field(rng: Rng, h: int, w: int, cell: float, white: float) -> F32:
    """Uniform [0, 1] values, blob-like (correlated over ``cell``) with ``white`` speckle."""
    g = np.sqrt(1 - white**2) * _smooth_normal(rng, h, w, cell)
    g += white * rng.standard_normal((h, w)).astype(np.float32)
    return np.asarray(ndtr(g), np.float32)


def _rays(scene: IndoorScene) -> F32:
    cam = scene.camera
    u = (np.arange(cam.width, dtype=np.float32) - cam.cx) / cam.fx
    v = (np.arange(cam.height, dtype=np.float32) - cam.cy) / cam.fy
    d = np.stack(np.broadcast_arrays(u[None, :], v[:, None], np.ones((1, 1), np.float32)), -1)
    return np.asarray(d / np.linalg.norm(d, axis=-1, keepdims=True), np.float32)


def _kinect_color(
    rng: Rng, linear: F32, obj: npt.NDArray[np.int32], scene: IndoorScene
) -> npt.NDArray[np.uint8]:
    """8-bit sRGB from the linear radiance (windows replaced by daylight)."""
    h, w = obj.shape
    img = np.asarray(linear, np.float32).copy()
    glass = np.array([p.glass for p in scene.parts] + [False])[obj]
    lamp = np.array([p.emissive for p in scene.parts] + [False])[obj]
    lum = img @ np.array([0.2126, 0.7152, 0.0722], np.float32)
    lit = ~(glass | lamp)
    key = float(np.exp(np.mean(np.log((lum[lit] if lit.any() else lum.ravel()) + 1e-4))))
    if glass.any():  # daylight through the windows
        sky = np.array(
            [rng.uniform(0.75, 1.0), rng.uniform(0.85, 1.0), rng.uniform(0.85, 1.1)], np.float32
        )
        level = key * float(rng.uniform(*WINDOW_GLOW))
        tex = 1 + float(rng.uniform(0.05, 0.4)) * (_field(rng, h, w, 12.0, 0.2) - 0.5)
        img[glass] = (level * sky)[None, :] * tex[glass][:, None]
    if lamp.any():  # glowing lamps
        shade = np.array([1.0, rng.uniform(0.85, 1.0), rng.uniform(0.6, 0.95)], np.float32)
        img[lamp] = key * float(rng.uniform(*LAMP_GLOW)) * shade
    exposure = float(rng.uniform(*EXPOSURE)) / key
    gains = np.array([rng.uniform(*GAIN_R), 1.0, rng.uniform(*GAIN_B)], np.float32)
    img *= exposure * gains
    sigma = float(rng.uniform(0.3, 1.0)) * w / 640
    img = np.asarray(cv2.GaussianBlur(img, (0, 0), max(sigma, 0.2)), np.float32)
    if rng.random() < P_MOTION_BLUR:  # a hand-held camera moving during the exposure
        n = max(2, round(float(rng.uniform(*MOTION_BLUR)) * w / 640))
        kernel = np.zeros((n | 1, n | 1), np.float32)
        kernel[(n | 1) // 2, :] = 1
        rot = cv2.getRotationMatrix2D(
            ((n | 1) / 2 - 0.5, (n | 1) / 2 - 0.5), float(rng.uniform(0, 180)), 1
        )
        kernel = np.asarray(cv2.warpAffine(kernel, rot, kernel.shape[::-1]), np.float32)
        kernel /= max(float(kernel.sum()), 1e-6)
        img = np.asarray(cv2.filter2D(img, -1, kernel), np.float32)
    yy, xx = np.mgrid[0:h, 0:w].astype(np.float32)
    r2 = ((xx - w / 2) ** 2 + (yy - h / 2) ** 2) / ((w / 2) ** 2 + (h / 2) ** 2)
    img *= (1 - float(rng.uniform(0.0, 0.35)) * r2)[..., None]
    img = np.clip(img, 0, None)
    srgb = np.where(img <= 0.0031308, 12.92 * img, 1.055 * np.power(img, 1 / 2.4) - 0.055)
    noise = float(rng.uniform(0.003, 0.015))
    srgb = srgb + noise * np.sqrt(np.clip(srgb, 0.05, 1)) * rng.standard_normal(srgb.shape).astype(
        np.float32
    )
    return np.asarray(np.clip(np.round(srgb * 255), 0, 255), np.uint8)


def _kinect_depth(rng: Rng, gb: GBuffer, built: RenderScene, scene: IndoorScene) -> F32:
    """Kinect-v1-like depth (metres, NaN = hole) from the true first-hit depth."""
    cam = scene.camera
    h, w = gb.depth.shape
    z = np.asarray(gb.depth, np.float32)
    obj = gb.object
    valid = np.isfinite(z)
    zf = np.where(valid, z, 0.0).astype(np.float32)
    baseline = float(rng.uniform(*BASELINE))
    fb = float(rng.uniform(*IR_FOCAL)) * baseline  # disparity in the IR camera's pixels
    scale = cam.width / 640.0  # pattern features and correlation windows scale with the image

    # Jagged edges: each pixel may take a neighbour's depth (lateral noise of the correlation).
    p_jag = float(rng.uniform(0.1, 0.4))
    dy = np.where(rng.random((h, w)) < p_jag, rng.integers(-1, 2, (h, w)), 0)
    dx = np.where(rng.random((h, w)) < p_jag, rng.integers(-1, 2, (h, w)), 0)
    yy, xx = np.mgrid[0:h, 0:w]
    src_y, src_x = np.clip(yy + dy, 0, h - 1), np.clip(xx + dx, 0, w - 1)
    zj, vj, oj = zf[src_y, src_x], valid[src_y, src_x], obj[src_y, src_x]

    # Noise in disparity, then quantisation to DISPARITY_STEP: together sigma_z = k z^2.
    k = float(rng.uniform(*NOISE_K))
    sd_d = fb * np.sqrt(max(k**2 - DISPARITY_STEP**2 / (12 * fb**2), 1e-12))
    white = float(rng.uniform(0.5, 0.9))
    g = white * rng.standard_normal((h, w)).astype(np.float32)
    g += np.sqrt(1 - white**2) * _smooth_normal(rng, h, w, 6.0 * scale)
    disp = fb / np.where(vj, zj, 1.0) + sd_d * g
    disp = np.round(disp / DISPARITY_STEP) * DISPARITY_STEP
    depth = np.where(vj & (disp > 0), fb / np.maximum(disp, 1e-6), np.nan).astype(np.float32)

    holes = ~vj
    # Range limits.
    holes |= zj < float(rng.uniform(*NEAR))
    far = np.clip((zj - float(rng.uniform(*FAR_START))) / float(rng.uniform(*FAR_RAMP)), 0, 1)
    holes |= _field(rng, h, w, 10.0 * scale, 0.5) < far
    # Weak IR return: dark, far, grazing surfaces.
    ir = np.array([p.material.albedo_ir for p in scene.parts] + [1.0], np.float32)[oj]
    cos = np.abs(np.sum(np.asarray(gb.normal)[src_y, src_x] * _rays(scene), axis=-1))
    signal = ir * np.maximum(cos, 0.05) / np.maximum(zj, 0.5) ** 2
    weak = np.clip(1 - signal / float(rng.uniform(*WEAK_SIGNAL)), 0, 1)
    holes |= _field(rng, h, w, 5.0 * scale, 0.6) < weak
    c0 = float(rng.uniform(*GRAZING_COS))
    holes |= rng.random((h, w)) < np.clip(1 - cos / c0, 0, 1)
    # Glossy parts (screens) in blobs; window glass: the pattern passes through, no return.
    glossy = np.array([p.glossy for p in scene.parts] + [0.0], np.float32)[oj]
    holes |= _field(rng, h, w, 8.0 * scale, 0.3) < glossy * float(rng.uniform(0.3, 1.0))
    lost = np.array([p.glass and rng.random() < 0.85 for p in scene.parts] + [False])
    holes |= lost[oj]
    # Projector shadow: points the projector (b to the side) does not see.
    holes |= _shadow(rng, built, scene, zf, valid, baseline)
    # Thin bands along depth edges.
    edge = np.zeros((h, w), bool)
    jump = np.abs(np.diff(zf, axis=1)) > 0.04 * np.maximum(zf[:, 1:], zf[:, :-1])
    edge[:, 1:] |= jump
    edge[:, :-1] |= jump
    jump = np.abs(np.diff(zf, axis=0)) > 0.04 * np.maximum(zf[1:], zf[:-1])
    edge[1:] |= jump
    edge[:-1] |= jump
    holes |= edge & (rng.random((h, w)) < float(rng.uniform(0.1, 0.6)))
    depth[holes] = np.nan
    return depth


def _shadow(
    rng: Rng, built: RenderScene, scene: IndoorScene, z: F32, valid: np.ndarray, baseline: float
) -> np.ndarray:
    """Pixels the projector, ``baseline`` to the side of the camera, does not light."""
    cam = scene.camera
    b = baseline if rng.random() < 0.8 else -baseline
    pose = Pose(scene.pose.rotation, scene.pose.translation - np.array([b, 0.0, 0.0]))
    zp = built.depth(cam, pose)
    h, w = z.shape
    u = np.arange(w, dtype=np.float32)[None, :]
    x = (u - cam.cx) / cam.fx * z - b
    up = np.round(cam.fx * x / np.maximum(z, 1e-6) + cam.cx).astype(np.int64)
    inside = (up >= 0) & (up < w)
    rows = np.broadcast_to(np.arange(h)[:, None], (h, w))
    seen = zp[rows, np.clip(up, 0, w - 1)]
    occluded = np.isfinite(seen) & (seen < z - (0.01 + 0.01 * z))
    # The projector's field of view is wider than the camera's: outside it counts as lit.
    return np.asarray(valid & inside & occluded, bool)
