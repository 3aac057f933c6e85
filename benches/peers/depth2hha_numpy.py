"""A plain numpy/scipy HHA, written for this benchmark as the peer of rgbd_rs' HHA.

It follows the same steps, with the same array primitives, as the Depth2HHA-python port
(charlesCXK/Depth2HHA-python, ``getHHA.py`` / ``utils/rgbd_util.py`` / ``utils/util.py``), which
is what the issue's ~5.3 s per frame refers to: per-channel ``scipy.signal.convolve2d`` box
filters for the window sums of both normal fields, a vectorised cofactor solve, ``np.linalg.eig``
for each gravity iteration, a Python-level ``math.acos`` per pixel for the angle channel, and
``np.rint`` + clipping for uint8. It is our own code (not a copy of the port, which does not run
on NumPy >= 1.24 here); its output is checked against the MATLAB reference in the benchmark.

Steps (METHOD_NOTES §7): depth in cm, 1-based pixel coordinates, normals by least-squares planes
in (2R+1)^2 windows (R = 3 for the angle, 10 for gravity) with missing pixels contributing 0,
normals oriented N_z >= 0 then N.P >= 0, gravity by 5 iterations at 45° and 5 at 15°, Rodrigues
rotation, height above the lowest point (-130 cm if that is above -90 cm), angle + 128 - 90,
disparity 31000 / max(z_cm, 100).
"""

from __future__ import annotations

import math

import numpy as np
from scipy import signal


def _cloud(z_cm: np.ndarray, k: tuple[float, float, float, float]) -> tuple[np.ndarray, ...]:
    fx, fy, cx, cy = k
    h, w = z_cm.shape
    u, v = np.meshgrid(np.arange(w) + 1.0, np.arange(h) + 1.0)
    return (u - cx) * z_cm / fx, (v - cy) * z_cm / fy, z_cm


def _normals(z_cm: np.ndarray, missing: np.ndarray, k: tuple, r: int) -> np.ndarray:
    x, y, z = _cloud(z_cm, k)
    pts = np.stack([x, y, z], axis=2)
    x, y, z = (np.where(missing, np.nan, c) for c in (x, y, z))
    a, b, iz = x / z, y / z, 1.0 / z
    one = np.where(np.isnan(z), np.nan, 1.0)
    chans = [a * a, a * b, a, b * b, b, one, a * iz, b * iz, iz]
    box = np.ones((2 * r + 1, 2 * r + 1))
    s = [signal.convolve2d(np.nan_to_num(c, nan=0.0), box, mode="same") for c in chans]
    saa, sab, sa, sbb, sb, s1, ta, tb, t1 = s
    c0 = sbb * s1 - sb * sb
    c1 = -sab * s1 + sa * sb
    c2 = sab * sb - sa * sbb
    c3 = saa * s1 - sa * sa
    c4 = -saa * sb + sab * sa
    c5 = saa * sbb - sab * sab
    n = np.stack(
        [c0 * ta + c1 * tb + c2 * t1, c1 * ta + c3 * tb + c4 * t1, c2 * ta + c4 * tb + c5 * t1],
        axis=2,
    )
    with np.errstate(invalid="ignore", divide="ignore"):
        n = n / np.sqrt((n * n).sum(axis=2, keepdims=True))
    sz = np.sign(n[:, :, 2:3])
    sz[sz == 0] = 1
    n = n * sz
    sp = np.sign((n * pts).sum(axis=2, keepdims=True))
    sp[np.isnan(sp) | (sp == 0)] = 1
    return n * sp


def _gravity(n: np.ndarray) -> np.ndarray:
    nn = n.reshape(-1, 3)
    nn = nn[~np.isnan(nn[:, 0])].T
    y = np.array([0.0, 1.0, 0.0])
    for deg, iters in ((45.0, 5), (15.0, 5)):
        t = math.radians(deg)
        for _ in range(iters):
            sim = np.abs(y @ nn)
            nf, nw = nn[:, sim > math.cos(t)], nn[:, sim < math.sin(t)]
            w, v = np.linalg.eig(nw @ nw.T - nf @ nf.T)
            e = np.real(v[:, np.argmin(np.real(w))])
            y = e * np.sign(y @ e)
    return y


def _rotation(yf: np.ndarray) -> np.ndarray:
    y0 = np.array([0.0, 1.0, 0.0])
    phi = math.degrees(math.acos(float(np.clip(y0 @ yf, -1, 1))))
    if abs(phi) <= 0.1:
        return np.eye(3)
    ax = np.cross(y0, yf)
    ax /= np.linalg.norm(ax)
    s = np.array([[0, -ax[2], ax[1]], [ax[2], 0, -ax[0]], [-ax[1], ax[0], 0]])
    p = math.radians(phi)
    return np.eye(3) + math.sin(p) * s + (1 - math.cos(p)) * s @ s


def hha(depth_m: np.ndarray, raw_m: np.ndarray, k: tuple[float, float, float, float]) -> np.ndarray:
    """HHA (H x W x 3 uint8: disparity, height, angle) of filled depth ``depth_m`` (metres) with
    the holes of ``raw_m`` (== 0) left out of the normals; ``k`` = MATLAB-style (1-based)
    ``fx, fy, cx, cy``."""
    z_cm = depth_m.astype(np.float64) * 100
    missing = raw_m == 0
    n1 = _normals(z_cm, missing, k, 3)
    n2 = _normals(z_cm, missing, k, 10)
    g = _gravity(n2)
    rot = _rotation(g)
    x, y, z = _cloud(z_cm, k)
    pts = np.stack([x, y, z], axis=2).reshape(-1, 3)
    h = -(pts @ rot)[:, 1].reshape(z_cm.shape)  # (R^T p).y = (column 1 of R) . p
    y_min = float(np.nanmin(h))
    if y_min > -90:
        y_min = -130.0
    h = h - y_min
    cosines = np.clip((n1 * g).sum(axis=2), -1, 1)
    angle = np.array([math.degrees(math.acos(c)) for c in cosines.ravel()]).reshape(h.shape)
    angle[np.isnan(angle)] = 180
    disp = 31000 / np.maximum(z_cm, 100)
    out = np.rint(np.stack([disp, h, angle + 128 - 90], axis=2))
    return np.clip(out, 0, 255).astype(np.uint8)
