"""Things on the walls of the synthetic indoor rooms (:mod:`rgbd_rs.data.synth_indoor`);
private: doors (label wall), windows with frames, glass and sometimes curtains (window),
pictures (picture), papers, whiteboards, clocks, fixtures, radiators and hanging clothes
(objects), wall shelves with books, upper cabinets (furniture, books) and wall-mounted TVs
(tv)."""

from __future__ import annotations

from typing import TYPE_CHECKING

from rgbd_rs.data.synth_indoor_objects import (
    BOOKS,
    FURNITURE,
    OBJECTS,
    PICTURE,
    WALL,
    WINDOW,
    Part,
    color,
    image_material,
    material,
    screen,
    slab,
)
from rgbd_rs.meshes import cylinder
from rgbd_rs.render import Material, Texture

if TYPE_CHECKING:
    from rgbd_rs.data.synth_indoor_scene import _Room


def wall_items(room: _Room) -> None:
    rng = room.rng
    if rng.random() < 0.9:  # a door
        w, h = float(rng.uniform(0.75, 0.95)), float(rng.uniform(1.95, 2.1))
        m = material(rng, str(rng.choice(["wood", "laminate", "wall"])), texture="wood")
        room.wall_item(w, 0.0, [Part(slab(w, h, 0.04, 0, 0, 0), m, WALL)])
    for _ in range(int(rng.choice([0, 1, 1, 2, 2, 3]))):  # windows
        w, h = float(rng.uniform(0.6, 2.6)), float(rng.uniform(0.8, 1.8))
        bottom = float(rng.uniform(0.5, 1.0))
        frame = material(rng, str(rng.choice(["laminate", "wood", "metal"])))
        f = 0.05
        meshes = [slab(w, f, 0.06, 0, 0, 0), slab(w, f, 0.06, 0, h - f, 0)]
        meshes += [slab(f, h, 0.06, sx * (w - f) / 2, 0, 0) for sx in (-1, 1)]
        parts = [
            Part(meshes[0].merged(*meshes[1:]), frame, WINDOW),
            Part(
                slab(w - 2 * f, h - 2 * f, 0.01, 0, f, -0.01),
                material(rng, "ceiling"),
                WINDOW,
                0.9,
                True,
            ),
        ]
        if rng.random() < 0.35:  # curtains (or blinds) also count as window
            cw = float(rng.uniform(0.2, 0.6)) * w
            cm = material(rng, "fabric", texture="weave")
            ch = min(h + 0.5, room.h - bottom - 0.05)
            for sx in (-1, 1):
                parts.append(
                    Part(
                        slab(cw, ch, 0.05, sx * (w - cw) / 2, -0.3 if ch > h + 0.3 else 0, -0.06),
                        cm,
                        WINDOW,
                    )
                )
        if bottom > 0.6 and rng.random() < 0.5:  # a radiator below the window
            rw = min(w, float(rng.uniform(0.5, 1.5)))
            rad = slab(rw, bottom - 0.2, 0.08, 0, -(bottom - 0.1), -0.06)
            ribs = Texture.stripes(float(rng.uniform(0.04, 0.08)), 0.0)
            parts.append(Part(rad, Material(color(rng, "tile"), 0.5, ribs, 0.3), OBJECTS))
        room.wall_item(w, bottom, parts)
    for _ in range(int(rng.integers(3, 15))):  # pictures, papers, boards, clocks, shelves, TVs
        kind = str(
            rng.choice(
                ["picture", "paper", "board", "clock", "shelf", "tv", "coat", "fixture"],
                p=[0.36, 0.17, 0.07, 0.05, 0.12, 0.03, 0.1, 0.1],
            )
        )
        if kind == "tv":
            tv = screen(rng, monitor=False)
            w = tv.footprint[0]
            room.wall_item(w, float(rng.uniform(0.9, 1.4)), tv.parts)
        elif kind == "shelf":
            _wall_shelf(room)
        elif kind == "fixture":  # a switch box, speaker, air conditioner, extinguisher
            w, h, t = (float(v) for v in rng.uniform([0.08, 0.08, 0.03], [0.9, 0.5, 0.3]))
            box_ = slab(w, h, t, 0, 0, -t / 2)
            fam = str(rng.choice(["ceiling", "dark", "any"]))
            room.wall_item(
                w,
                float(rng.uniform(0.3, max(0.4, room.h - h - 0.1))),
                [Part(box_, material(rng, fam), OBJECTS)],
            )
        elif kind == "coat":  # clothes, bags or a towel hanging on the wall
            w, h, t = (float(v) for v in rng.uniform([0.3, 0.4, 0.05], [0.7, 1.1, 0.25]))
            coat = slab(w, h, t, 0, 0, -t / 2)
            room.wall_item(
                w,
                float(rng.uniform(0.6, 1.2)),
                [Part(coat, material(rng, "fabric", texture="weave"), OBJECTS)],
            )
        elif kind == "clock":
            r = float(rng.uniform(0.1, 0.2))
            face = cylinder(r, 0.04, (0, -r, -0.02), segments=24, axis=2)
            room.wall_item(
                2 * r, float(rng.uniform(1.5, 2.1)), [Part(face, material(rng, "any"), OBJECTS)]
            )
        else:
            w, h = {
                "picture": (rng.uniform(0.2, 1.2), rng.uniform(0.2, 1.0)),
                "paper": (rng.uniform(0.15, 0.45), rng.uniform(0.2, 0.6)),
                "board": (rng.uniform(0.9, 2.0), rng.uniform(0.6, 1.2)),
            }[kind]
            w, h = float(w), float(h)
            if kind == "picture":
                m, label = image_material(rng, max(w, h)), PICTURE
            else:
                m, label = material(rng, "ceiling", texture="plain"), OBJECTS
            bottom = float(rng.uniform(0.8, max(0.9, room.h - h - 0.3)))
            depth = float(rng.uniform(0.003, 0.04))
            room.wall_item(w, bottom, [Part(slab(w, h, depth, 0, 0, -depth / 2), m, label)])


def upper_cabinets(room: _Room) -> None:
    """A row of wall cabinets (furniture) high on a wall, as in kitchens and offices."""
    rng = room.rng
    w, d = float(rng.uniform(1.0, 3.0)), float(rng.uniform(0.3, 0.4))
    h = float(rng.uniform(0.5, 0.9))
    body = material(rng, str(rng.choice(["wood", "laminate"])), texture="wood")
    n = max(1, round(w / 0.6))
    parts = [Part(slab(w, h, d, 0, 0, -d / 2), body, FURNITURE)]
    fronts = [
        slab(w / n - 0.01, h - 0.02, 0.015, -w / 2 + (k + 0.5) * w / n, 0.01, -d - 0.008)
        for k in range(n)
    ]
    parts.append(Part(fronts[0].merged(*fronts[1:]), material(rng, "laminate"), FURNITURE))
    room.wall_item(w, float(rng.uniform(1.4, max(1.45, room.h - h - 0.05))), parts)


def _wall_shelf(room: _Room) -> None:
    """A board on the wall (furniture) with upright books (books) and objects."""
    rng = room.rng
    w, d = float(rng.uniform(0.6, 1.6)), float(rng.uniform(0.18, 0.3))
    parts = [
        Part(slab(w, 0.025, d, 0, 0, -d / 2), material(rng, "wood", texture="wood"), FURNITURE)
    ]
    x = -w / 2
    while x < w / 2 - 0.06:
        bw = float(rng.uniform(0.015, 0.06))
        if rng.random() < 0.15:
            x += float(rng.uniform(0.05, 0.3))
            continue
        bh, bd = float(rng.uniform(0.15, 0.3)), float(rng.uniform(0.12, d - 0.02))
        mesh = slab(bw, bh, bd, x + bw / 2, 0.025, -bd / 2 - 0.01)
        parts.append(Part(mesh, material(rng, "bright" if rng.random() < 0.6 else "any"), BOOKS))
        x += bw + 0.002
    room.wall_item(w, float(rng.uniform(1.0, min(2.0, room.h - 0.5))), parts)
