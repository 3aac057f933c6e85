"""Procedural indoor scenes for the synthetic ToF + stereo dataset (SYNTH3-like, thesis §3.5).

A room (floor, ceiling, back and side walls) seen from the reference camera, furnished with
boxes, cylinders, spheres, tables (slabs on legs) and real meshes (``../shared/data/meshes``).
Chosen to exercise both sensors' weak spots: textureless walls and repetitive stripes for stereo,
dark low-IR-albedo objects (ToF dropout), concave corners (multipath), depth edges at many
ranges (mixed pixels), depths from ~0.6 m to ~9 m.

World frame = the reference (right) camera's frame: x right, y down, z forward, metres.
Everything is drawn from one ``numpy.random.Generator``, so a seed fixes the scene.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import numpy as np

from rgbd_rs.data.paths import data_root
from rgbd_rs.meshes import Mesh, box, cylinder, load_mesh, quad, sphere
from rgbd_rs.render import Material, PointLight, Scene, Texture

#: Room depth range (back wall distance, m) and camera height above the floor (m).
BACK_WALL_Z = (4.0, 9.0)
CAMERA_HEIGHT = (1.0, 1.7)
#: Furniture count per scene.
N_OBJECTS = (5, 10)
#: Probability that an object is dark (visible and IR albedo < 0.1: ToF dropout, stereo noise).
P_DARK = 0.2
#: Probability that a wall is textureless (stereo's weak spot).
P_PLAIN_WALL = 0.35


def _shared_meshes() -> list[Mesh]:
    """The real meshes of ``../shared/data/meshes`` (empty when the data is absent)."""
    root = data_root()
    if root is None or not (root / "meshes").is_dir():
        return []
    return [
        load_mesh(p)
        for p in sorted(Path(root / "meshes").iterdir())
        if p.suffix in (".off", ".ply")
    ]


def _texture(rng: np.random.Generator, plain_ok: bool) -> tuple[Texture, float]:
    r = rng.random()
    if plain_ok and r < P_PLAIN_WALL:
        return Texture.uniform(), 0.0
    r = rng.random()
    if r < 0.6:
        return Texture.noise(float(rng.uniform(0.01, 0.08)), int(rng.integers(2**31))), float(
            rng.uniform(0.5, 0.9)
        )
    if r < 0.8:
        return Texture.stripes(float(rng.uniform(0.03, 0.2)), float(rng.uniform(0, np.pi))), float(
            rng.uniform(0.4, 0.8)
        )
    return Texture.checker(float(rng.uniform(0.05, 0.3))), float(rng.uniform(0.3, 0.7))


def _material(rng: np.random.Generator, *, dark: bool = False, plain_ok: bool = False) -> Material:
    tex, contrast = _texture(rng, plain_ok)
    if dark:
        base = rng.uniform(0.02, 0.08, 3)
        ir = float(rng.uniform(0.01, 0.06))
    else:
        base = rng.uniform(0.35, 0.9, 3)
        ir = float(np.clip(base.mean() + rng.normal(0, 0.1), 0.15, 0.95))
    return Material(tuple(float(b) for b in base), ir, tex, contrast)  # type: ignore[arg-type]


def _yaw(mesh: Mesh, angle: float) -> Mesh:
    c, s = np.cos(angle), np.sin(angle)
    return mesh.transformed(np.array([[c, 0, s], [0, 1, 0], [-s, 0, c]]))


def _on_floor(mesh: Mesh, x: float, z: float, floor_y: float) -> Mesh:
    lo, hi = mesh.bounds()
    return mesh.transformed(
        translation=(x - (lo[0] + hi[0]) / 2, floor_y - hi[1], z - (lo[2] + hi[2]) / 2)
    )


def _furniture(rng: np.random.Generator, meshes: Sequence[Mesh]) -> Mesh:
    kind = rng.choice(["box", "cylinder", "sphere", "table", "mesh"], p=[0.3, 0.15, 0.15, 0.2, 0.2])
    if kind == "mesh" and meshes:
        m = meshes[int(rng.integers(len(meshes)))].normalized(float(rng.uniform(0.5, 1.3)))
        # Shared meshes are z-up (ModelNet); our world is y-down.
        return m.transformed(np.array([[1, 0, 0], [0, 0, -1], [0, 1, 0]]))
    if kind == "cylinder":
        return cylinder(float(rng.uniform(0.1, 0.4)), float(rng.uniform(0.3, 1.5)), segments=48)
    if kind == "sphere":
        return sphere(float(rng.uniform(0.15, 0.45)), rings=24, segments=48)
    if kind == "table":
        w, d, h = rng.uniform(0.6, 1.6), rng.uniform(0.5, 1.0), rng.uniform(0.45, 0.9)
        t = 0.04
        legs = [
            box(
                (0.05, h - t, 0.05),
                ((sx * (w / 2 - 0.05)), t / 2 + (h - t) / 2, sz * (d / 2 - 0.05)),
            )
            for sx in (-1, 1)
            for sz in (-1, 1)
        ]
        return box((w, t, d)).merged(*legs)
    return box(tuple(float(v) for v in rng.uniform([0.2, 0.2, 0.2], [1.2, 1.4, 1.0])))


def _random_scene(rng: np.random.Generator, meshes: Sequence[Mesh] = ()) -> Scene:
    """A furnished room in the reference camera's frame, drawn from ``rng``."""
    zb = float(rng.uniform(*BACK_WALL_Z))
    cam_h = float(rng.uniform(*CAMERA_HEIGHT))
    ceil = -float(rng.uniform(2.4, 3.0)) + cam_h
    xl, xr = -float(rng.uniform(1.5, 4.0)), float(rng.uniform(1.5, 4.0))
    zn = -0.5
    walls = [
        quad([[xl, cam_h, zn], [xr, cam_h, zn], [xr, cam_h, zb], [xl, cam_h, zb]]),  # floor
        quad([[xl, ceil, zn], [xl, ceil, zb], [xr, ceil, zb], [xr, ceil, zn]]),  # ceiling
        quad([[xl, ceil, zb], [xl, cam_h, zb], [xr, cam_h, zb], [xr, ceil, zb]]),  # back wall
        quad([[xl, ceil, zn], [xl, cam_h, zn], [xl, cam_h, zb], [xl, ceil, zb]]),  # left wall
        quad([[xr, ceil, zn], [xr, ceil, zb], [xr, cam_h, zb], [xr, cam_h, zn]]),  # right wall
    ]
    scene = Scene(ambient=float(rng.uniform(0.1, 0.3)))
    for w in walls:
        scene.add(w, _material(rng, plain_ok=True))
    n = int(rng.integers(N_OBJECTS[0], N_OBJECTS[1] + 1))
    for _ in range(n):
        m = _yaw(_furniture(rng, meshes), float(rng.uniform(0, 2 * np.pi)))
        lo, hi = m.bounds()
        z = float(rng.uniform(0.8, zb - 0.3 - (hi[2] - lo[2]) / 2))
        half = 0.6 * z  # keep objects roughly inside the ~70 degree field of view
        x = float(rng.uniform(max(xl + 0.3, -half), min(xr - 0.3, half)))
        scene.add(_on_floor(m, x, z, cam_h), _material(rng, dark=rng.random() < P_DARK))
    for _ in range(int(rng.integers(1, 3))):
        pos = (
            float(rng.uniform(xl + 0.3, xr - 0.3)),
            ceil + 0.2,
            float(rng.uniform(0.5, zb - 0.5)),
        )
        scene.lights.append(PointLight(pos, float(rng.uniform(2.0, 6.0))))
    return scene
