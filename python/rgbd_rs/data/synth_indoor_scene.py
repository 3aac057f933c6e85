"""Room layout of the synthetic indoor frames (:mod:`rgbd_rs.data.synth_indoor`); private.

World frame: x along the room's width, y down (floor y = 0, ceiling y = -H), z along its depth;
the room spans ``[0, W] x [0, D]``. Furniture stands against walls (back to the wall) or free in
the room, chairs around tables, small objects on tables, cabinets and shelves, pictures, windows
(glass, sometimes with curtains), doors, whiteboards and wall TVs on the walls. The camera is
hand-held inside the room: 1-1.6 m high, looking across the room with some pitch and roll.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from rgbd_rs import _validate
from rgbd_rs.camera import PinholeCamera, Pose
from rgbd_rs.data.nyuv2 import NYUV2_CAMERA
from rgbd_rs.data.synth_indoor_objects import (
    CEILING,
    FLOOR,
    FURNITURE_BUILDERS,
    OBJECTS,
    WALL,
    Part,
    Parts,
    chair,
    material,
    screen,
    small_object,
)
from rgbd_rs.data.synth_indoor_walls import upper_cabinets, wall_items
from rgbd_rs.meshes import box, cylinder, quad
from rgbd_rs.render import PointLight, Scene

Rng = np.random.Generator

#: Room width / depth (m) and height (m); a share of large rooms (offices, shops, halls).
ROOM_SIZE = (2.5, 6.5)
LARGE_ROOM = (6.0, 10.0)
P_LARGE = 0.25
ROOM_HEIGHT = (2.4, 3.1)
#: Camera height above the floor (m), pitch (degrees, negative = looking down: mean, sd, range)
#: and roll sd (degrees).
CAMERA_HEIGHT = (1.0, 1.6)
PITCH = (-6.0, 8.0, (-35.0, 15.0))
ROLL_SD = 3.0
#: Things on the floor per room (range), and the free half-width around the camera (m).
FLOOR_CLUTTER = (10, 34)
KEEP_OUT = 0.5
#: Chance of a monitor / TV on a wide enough top.
P_SCREEN = 0.2
#: Share of views taken from near a wall.
P_AT_WALL = 0.6
#: Share of views aimed at a piece of furniture, and the aim's slack (degrees).
P_AIMED = 0.8
AIM_SD = 12.0
#: Nearest furniture a view is aimed at (m).
MIN_AIM = 1.4
#: Relative spread of the focal length and principal point (pixels, at 640 x 480) around the
#: NYU camera.
FOCAL_SPREAD = 0.06
PRINCIPAL_SD = 8.0
#: Room types and the furniture they hold: kind -> (count range).
ROOMS: dict[str, dict[str, tuple[int, int]]] = {
    "bedroom": {
        "bed": (1, 2),
        "cabinet": (2, 6),
        "shelf": (0, 3),
        "chair": (0, 2),
        "table": (0, 2),
    },
    "living": {
        "sofa": (1, 3),
        "table": (1, 3),
        "cabinet": (2, 5),
        "shelf": (1, 4),
        "chair": (0, 3),
    },
    "office": {
        "table": (2, 5),
        "cabinet": (2, 5),
        "shelf": (1, 4),
        "sofa": (0, 1),
        "chair": (1, 4),
    },
    "kitchen": {"cabinet": (4, 9), "table": (0, 2), "chair": (0, 3), "shelf": (0, 2)},
    "library": {"shelf": (3, 9), "table": (1, 3), "cabinet": (1, 3), "chair": (0, 3)},
}
ROOM_P = {"bedroom": 0.28, "living": 0.24, "office": 0.24, "kitchen": 0.12, "library": 0.12}
#: Inward normals (x, z) of the walls z = 0, z = D, x = 0, x = W.
WALL_NORMALS = ((0.0, 1.0), (0.0, -1.0), (1.0, 0.0), (-1.0, 0.0))


@dataclass
class IndoorScene:
    """A furnished room: the render scene, its parts (object id = position), the camera and its
    world-to-camera pose, and the room type."""

    scene: Scene
    parts: list[Part]
    camera: PinholeCamera
    pose: Pose
    room: str
    boxes: list[tuple[float, float, float, float]] = field(default_factory=list)


def _yaw_matrix(theta: float) -> np.ndarray:
    c, s = np.cos(theta), np.sin(theta)
    return np.array([[c, 0, s], [0, 1, 0], [-s, 0, c]])


def _aabb(
    w: float, d: float, x: float, z: float, theta: float
) -> tuple[float, float, float, float]:
    c, s = abs(np.cos(theta)), abs(np.sin(theta))
    hx, hz = (w * c + d * s) / 2, (w * s + d * c) / 2
    return (x - hx, x + hx, z - hz, z + hz)


def _overlaps(a: tuple[float, ...], b: tuple[float, ...], gap: float = 0.02) -> bool:
    return a[0] < b[1] + gap and b[0] < a[1] + gap and a[2] < b[3] + gap and b[2] < a[3] + gap


class _Room:
    def __init__(self, rng: Rng) -> None:
        self.rng = rng
        self.w, self.d = (float(v) for v in rng.uniform(*ROOM_SIZE, 2))
        if rng.random() < P_LARGE:
            self.d = float(rng.uniform(*LARGE_ROOM))
        self.h = float(rng.uniform(*ROOM_HEIGHT))
        self.parts: list[Part] = []
        self.boxes: list[tuple[float, float, float, float]] = []
        self.wall_spans: list[list[tuple[float, float, float, float]]] = [[], [], [], []]

    def wall_length(self, k: int) -> float:
        return self.w if k < 2 else self.d

    def wall_point(self, k: int, u: float, inset: float) -> tuple[float, float, float]:
        """(x, z, yaw) of a point ``u`` along wall ``k``, ``inset`` into the room, facing in."""
        nx, nz = WALL_NORMALS[k]
        if k < 2:
            x, z = u, (0.0 if k == 0 else self.d)
        else:
            x, z = (0.0 if k == 2 else self.w), u
        return x + nx * inset, z + nz * inset, float(np.arctan2(-nx, -nz))

    def add(self, parts: list[Part], x: float, z: float, theta: float, y: float = 0.0) -> None:
        r = _yaw_matrix(theta)
        for p in parts:
            self.parts.append(
                Part(
                    p.mesh.transformed(r, (x, y, z)),
                    p.material,
                    p.label,
                    p.glossy,
                    p.glass,
                    p.emissive,
                )
            )

    def place(
        self, item: Parts, *, free: bool, keep_out: list[tuple[float, ...]]
    ) -> tuple[float, float, float] | None:
        """Put ``item`` against a wall (or free in the room); None when nothing fits."""
        w, d = item.footprint
        for _ in range(25):
            if free:
                theta = float(self.rng.uniform(0, 2 * np.pi))
                x = float(self.rng.uniform(0.3, self.w - 0.3))
                z = float(self.rng.uniform(0.3, self.d - 0.3))
            else:
                k = int(self.rng.integers(4))
                if self.wall_length(k) < w + 0.1:
                    continue
                u = float(self.rng.uniform(w / 2 + 0.02, self.wall_length(k) - w / 2 - 0.02))
                x, z, theta = self.wall_point(k, u, d / 2 + 0.01)
            bb = _aabb(w, d, x, z, theta)
            if bb[0] < 0 or bb[2] < 0 or bb[1] > self.w or bb[3] > self.d:
                continue
            if any(_overlaps(bb, o) for o in self.boxes + keep_out):
                continue
            self.boxes.append(bb)
            self.add(item.parts, x, z, theta)
            return x, z, theta
        return None

    def on_tops(self, item: Parts, x: float, z: float, theta: float) -> None:
        """Small objects (and monitors / TVs) on the item's top surfaces."""
        r = _yaw_matrix(theta)
        for x0, x1, z0, z1, y in item.tops:
            n = int(self.rng.integers(1, 4 + int((x1 - x0) * (z1 - z0) * 24)))
            if not item.soft and (x1 - x0) > 0.6 and self.rng.random() < P_SCREEN:
                tv = screen(self.rng, monitor=y > 0.6)
                u = float(
                    self.rng.uniform(
                        x0 + tv.footprint[0] / 2,
                        max(x0 + tv.footprint[0] / 2, x1 - tv.footprint[0] / 2),
                    )
                )
                p = r @ np.array([u, -y, (z0 + z1) / 2 + 0.05])
                self.add(tv.parts, float(x + p[0]), float(z + p[2]), theta, float(p[1]))
            for _ in range(n):
                obj = small_object(self.rng)
                lo = np.min([p.mesh.bounds()[0] for p in obj], axis=0)
                hi = np.max([p.mesh.bounds()[1] for p in obj], axis=0)
                if hi[0] - lo[0] > x1 - x0 or hi[2] - lo[2] > z1 - z0:
                    continue
                if y > 1.9 and -lo[1] + y > self.h - 0.05:
                    continue
                u = float(self.rng.uniform(x0 - lo[0], x1 - hi[0]))
                v = float(self.rng.uniform(z0 - lo[2], z1 - hi[2]))
                p = r @ np.array([u, -y, v])
                self.add(obj, float(x + p[0]), float(z + p[2]), theta, float(p[1]))

    def wall_item(self, w: float, bottom: float, parts: list[Part]) -> None:
        """An item ``w`` wide whose bottom is ``bottom`` above the floor, where it overlaps no
        other wall item."""
        lo = min(float(p.mesh.bounds()[0][1]) for p in parts)
        hi = max(float(p.mesh.bounds()[1][1]) for p in parts)
        y0, y1 = bottom - hi, bottom - lo  # heights above the floor
        for _ in range(15):
            k = int(self.rng.integers(4))
            if self.wall_length(k) < w + 0.2:
                continue
            u = float(self.rng.uniform(w / 2 + 0.05, self.wall_length(k) - w / 2 - 0.05))
            if any(
                a < u + w / 2 and u - w / 2 < b and c < y1 and y0 < d
                for a, b, c, d in self.wall_spans[k]
            ):
                continue
            self.wall_spans[k].append((u - w / 2, u + w / 2, y0, y1))
            x, z, theta = self.wall_point(k, u, 0.0)
            self.add(parts, x, z, theta, -bottom)
            return


def _camera(rng: Rng, width: int, height: int) -> PinholeCamera:
    sx, sy = width / NYUV2_CAMERA.width, height / NYUV2_CAMERA.height
    f = float(rng.uniform(1 - FOCAL_SPREAD, 1 + FOCAL_SPREAD))
    aspect = float(rng.uniform(0.995, 1.005))
    return PinholeCamera(
        NYUV2_CAMERA.fx * f * sx,
        NYUV2_CAMERA.fy * f * aspect * sx,
        (NYUV2_CAMERA.cx + rng.normal(0, PRINCIPAL_SD)) * sx,
        (NYUV2_CAMERA.cy + rng.normal(0, PRINCIPAL_SD)) * sy,
        width,
        height,
    )


def _position(rng: Rng, room: _Room) -> tuple[float, float]:
    """Where the operator stands: often near a wall or a doorway, looking into the room (with
    :data:`P_AT_WALL`), else anywhere 0.4 m or more from the walls."""
    m = min(0.4, room.w / 3, room.d / 3)
    x, z = float(rng.uniform(m, room.w - m)), float(rng.uniform(m, room.d - m))
    if rng.random() < P_AT_WALL:
        off = float(rng.uniform(m, max(m, min(1.0, room.w / 3, room.d / 3))))
        k = int(rng.integers(4))
        if k < 2:
            z = off if k == 0 else room.d - off
        else:
            x = off if k == 2 else room.w - off
    return x, z


def _view(rng: Rng, room: _Room, x: float, z: float) -> Pose:
    """The world-to-camera pose of a camera at (x, z): aimed at a piece of furniture (with some
    slack), as people film a room, else across the room; pitch mostly slightly down."""
    height = float(rng.uniform(*CAMERA_HEIGHT))
    targets = [
        b for b in room.boxes if np.hypot((b[0] + b[1]) / 2 - x, (b[2] + b[3]) / 2 - z) > MIN_AIM
    ]
    mean, sd, (lo, hi) = PITCH
    pitch_deg = float(rng.normal(mean, sd))
    if targets and rng.random() < P_AIMED:
        b = targets[int(rng.integers(len(targets)))]
        tx, tz = (b[0] + b[1]) / 2 - x, (b[2] + b[3]) / 2 - z
        yaw = float(np.arctan2(tx, tz) + rng.normal(0, np.radians(AIM_SD)))
        look = float(rng.uniform(0.5, 1.3))  # height looked at
        pitch_deg = float(-np.degrees(np.arctan2(height - look, np.hypot(tx, tz))))
        pitch_deg += float(rng.normal(0, AIM_SD / 2))
    else:
        need = max(1.6, float(rng.uniform(0.3, 0.7)) * max(room.w, room.d))
        for attempt in range(200):
            yaw = float(rng.uniform(0, 2 * np.pi))
            s, c = np.sin(yaw), np.cos(yaw)
            # Distance to the wall ahead (ray against the room rectangle).
            ax = (room.w - x) / s if s > 1e-6 else (-x / s if s < -1e-6 else np.inf)
            az = (room.d - z) / c if c > 1e-6 else (-z / c if c < -1e-6 else np.inf)
            if min(ax, az) > (need if attempt < 100 else 1.0):
                break
    pitch = np.radians(float(np.clip(pitch_deg, lo, hi)))
    roll = np.radians(float(rng.normal(0, ROLL_SD)))
    cp, sp, cr, sr = np.cos(pitch), np.sin(pitch), np.cos(roll), np.sin(roll)
    rx = np.array([[1, 0, 0], [0, cp, -sp], [0, sp, cp]])
    rz = np.array([[cr, -sr, 0], [sr, cr, 0], [0, 0, 1]])
    r_cw = _yaw_matrix(yaw) @ rx @ rz  # camera axes in the world
    centre = np.array([x, -height, z])
    return Pose(r_cw.T, -r_cw.T @ centre)


def _lights(rng: Rng, room: _Room) -> tuple[list[PointLight], tuple[float, float, float]]:
    """Ceiling lamps (a panel or a pendant shade, glowing, label objects, each with a point light
    just below it) and the ambient light standing for the light bounced around the room."""
    warm = float(rng.uniform(-0.15, 0.25))  # colour temperature of the lamps
    tint = np.array([1 + warm, 1.0, 1 - warm])
    n = int(rng.integers(1, 5))
    lights = []
    for _ in range(n):
        x, z = float(rng.uniform(0.4, room.w - 0.4)), float(rng.uniform(0.4, room.d - 0.4))
        glow = material(rng, "ceiling", texture="plain")
        if rng.random() < 0.6:  # a flush panel
            sx, sz = float(rng.uniform(0.2, 1.2)), float(rng.uniform(0.2, 0.6))
            mesh, low = box((sx, 0.04, sz), (x, -room.h + 0.02, z)), room.h - 0.04
        else:  # a pendant with a shade
            drop, r = float(rng.uniform(0.2, 0.9)), float(rng.uniform(0.1, 0.3))
            mesh = cylinder(0.006, drop, (x, -room.h + drop / 2, z), segments=6).merged(
                cylinder(r, r * 0.8, (x, -room.h + drop + r * 0.4, z), segments=20)
            )
            low = room.h - drop - r * 0.8
        room.parts.append(Part(mesh, glow, OBJECTS, emissive=True))
        power = float(rng.uniform(1.0, 4.0)) * room.h**2 / n
        lights.append(PointLight((x, -low + 0.05, z), tuple(float(v) for v in power * tint)))  # type: ignore[arg-type]
    # Light bounced off the floor and walls: a weak lamp low in the room lights the ceiling.
    fill = float(rng.uniform(0.1, 0.4)) * sum(float(np.mean(li.intensity)) for li in lights)
    pos = (
        float(rng.uniform(0, room.w)),
        -float(rng.uniform(0.2, 1.0)),
        float(rng.uniform(0, room.d)),
    )
    lights.append(PointLight(pos, tuple(float(v) for v in fill * tint)))  # type: ignore[arg-type]
    amb = float(rng.uniform(0.08, 0.35))
    return lights, (float(amb * tint[0]), float(amb * tint[1]), float(amb * tint[2]))


def _random_indoor_scene(rng: Rng, width: int, height: int) -> IndoorScene:
    """A furnished room and a camera in it, drawn from ``rng``; the camera's image is
    ``width x height`` pixels."""
    width = _validate.size("width", width)
    height = _validate.size("height", height)
    room = _Room(rng)
    w, d, h = room.w, room.d, room.h
    shell: list[list[list[float]]] = [
        [[0, 0, 0], [w, 0, 0], [w, 0, d], [0, 0, d]],  # floor
        [[0, -h, 0], [0, -h, d], [w, -h, d], [w, -h, 0]],  # ceiling
        [[0, 0, 0], [0, -h, 0], [w, -h, 0], [w, 0, 0]],  # walls z = 0, z = D, x = 0, x = W
        [[0, 0, d], [w, 0, d], [w, -h, d], [0, -h, d]],
        [[0, 0, 0], [0, 0, d], [0, -h, d], [0, -h, 0]],
        [[w, 0, 0], [w, -h, 0], [w, -h, d], [w, 0, d]],
    ]
    floor_tex = str(rng.choice(["wood", "tiles", "weave", "noise"]))
    floor_fam = {"wood": "wood", "tiles": "tile", "weave": "carpet", "noise": "carpet"}[floor_tex]
    wall_m = material(rng, "wall", texture=str(rng.choice(["plain", "noise"])))
    shells = [
        (
            quad(shell[0]),
            material(rng, floor_fam, texture=floor_tex),
            FLOOR,
        ),
        (
            quad(shell[1]),
            material(rng, "ceiling", texture=str(rng.choice(["plain", "tiles"]))),
            CEILING,
        ),
        *((quad(c), wall_m, WALL) for c in shell[2:]),
    ]
    if rng.random() < 0.3:  # one accent wall
        k = int(rng.integers(2, 6))
        shells[k] = (shells[k][0], material(rng, "wall"), WALL)
    room.parts += [Part(m, mat, lab) for m, mat, lab in shells]
    cx, cz = _position(rng, room)
    keep_out: list[tuple[float, ...]] = [
        (cx - KEEP_OUT, cx + KEEP_OUT, cz - KEEP_OUT, cz + KEEP_OUT)
    ]
    kind = str(rng.choice(list(ROOM_P), p=list(ROOM_P.values())))
    if kind in ("kitchen", "office") and rng.random() < 0.6:
        upper_cabinets(room)
    wall_items(room)
    for name, (least, most) in ROOMS[kind].items():
        for _ in range(int(rng.integers(least, most + 1))):
            item = FURNITURE_BUILDERS[name](rng)
            free = name in ("table", "chair") and rng.random() < 0.6
            where = room.place(item, free=free, keep_out=keep_out)
            if where is None:
                continue
            room.on_tops(item, *where)
            if name == "table":
                _chairs_around(room, item, *where, keep_out)
    for _ in range(int(rng.integers(*FLOOR_CLUTTER))):  # boxes, bags, bins, lamps on the floor
        obj = small_object(rng, floor=True)
        lo = np.min([p.mesh.bounds()[0] for p in obj], axis=0)
        hi = np.max([p.mesh.bounds()[1] for p in obj], axis=0)
        centred = [
            Part(
                p.mesh.transformed(translation=-(lo + hi) * [0.5, 0, 0.5]),
                p.material,
                p.label,
                p.glossy,
            )
            for p in obj
        ]
        item = Parts(centred, (float(hi[0] - lo[0]), float(hi[2] - lo[2])))
        room.place(item, free=rng.random() < 0.35, keep_out=keep_out)
    pose = _view(rng, room, cx, cz)
    lights, ambient = _lights(rng, room)
    scene = Scene(lights=lights, ambient=ambient)
    for p in room.parts:
        scene.add(p.mesh, p.material)
    return IndoorScene(scene, room.parts, _camera(rng, width, height), pose, kind, room.boxes)


def _chairs_around(
    room: _Room, table: Parts, x: float, z: float, theta: float, keep_out: list[tuple[float, ...]]
) -> None:
    rng = room.rng
    w, d = table.footprint
    r = _yaw_matrix(theta)
    own = room.boxes[-1]  # the table's (chairs may stand under its edge)
    for _ in range(int(rng.integers(0, 5))):
        c = chair(rng)
        side = int(rng.integers(4))
        s = c.footprint[0]
        off = float(rng.uniform(-0.1, 0.45)) * s
        local = [
            (float(rng.uniform(-w / 3, w / 3)), -d / 2 - off),
            (float(rng.uniform(-w / 3, w / 3)), d / 2 + off),
            (-w / 2 - off, float(rng.uniform(-d / 4, d / 4))),
            (w / 2 + off, float(rng.uniform(-d / 4, d / 4))),
        ][side]
        p = r @ np.array([local[0], 0.0, local[1]])
        cxw, czw = x + p[0], z + p[2]
        yaw = float(np.arctan2(-(x - cxw), -(z - czw)) + rng.normal(0, 0.25))
        bb = _aabb(s, s, cxw, czw, yaw)
        if bb[0] < 0 or bb[2] < 0 or bb[1] > room.w or bb[3] > room.d:
            continue
        if any(_overlaps(bb, o, 0.0) for o in room.boxes + keep_out if o is not own):
            continue
        room.boxes.append(bb)
        room.add(c.parts, float(cxw), float(czw), yaw)
