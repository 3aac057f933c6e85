"""Furniture, wall items and materials of the synthetic indoor scenes
(:mod:`rgbd_rs.data.synth_indoor`); private to that module.

Every builder returns :class:`Parts` in a local frame: y down (the floor is y = 0, heights are
negative y), the footprint centred on the origin, the back at +z (against a wall) and the front
towards -z. Each part carries its 13-class label (:data:`rgbd_rs.data.nyuv2.LABEL13_NAMES`) and
whether the Kinect tends to miss it (glossy, dark); ``tops`` are the surfaces small objects stand
on. Sizes are those of ordinary furniture (drawn from ranges, never one constant).
"""

from __future__ import annotations

import colorsys
from dataclasses import dataclass, field

import numpy as np

from rgbd_rs.meshes import Mesh, box, cylinder, sphere
from rgbd_rs.render import Material, Texture

# 13-class labels (rgbd_rs.data.nyuv2.LABEL13_NAMES).
BED, BOOKS, CEILING, CHAIR, FLOOR, FURNITURE, OBJECTS = 1, 2, 3, 4, 5, 6, 7
PICTURE, SOFA, TABLE, TV, WALL, WINDOW = 8, 9, 10, 11, 12, 13

Rng = np.random.Generator


@dataclass
class Part:
    """One renderable object: mesh, material, 13-class label, how glossy it is for the Kinect's
    IR pattern (0 = matte; the probability that the part reads as a depth hole), whether it is
    window glass (daylight in colour, no depth) or a lamp (glowing in colour)."""

    mesh: Mesh
    material: Material
    label: int
    glossy: float = 0.0
    glass: bool = False
    emissive: bool = False


@dataclass
class Parts:
    """A piece of furniture in its local frame: parts, footprint ``(width, depth)``, the
    surfaces ``(x0, x1, z0, z1, y)`` objects can stand on and whether they are soft (a bed, a
    sofa seat: clutter, no screens)."""

    parts: list[Part]
    footprint: tuple[float, float]
    tops: list[tuple[float, float, float, float, float]] = field(default_factory=list)
    soft: bool = False


# -- colours and materials ---------------------------------------------------------------------


def _linear(rgb: tuple[float, float, float]) -> tuple[float, float, float]:
    """sRGB in [0, 1] -> linear albedo (the renderer's colours are linear)."""
    c = np.clip(np.asarray(rgb, np.float64), 0.0, 1.0)
    lin = np.where(c <= 0.04045, c / 12.92, ((c + 0.055) / 1.055) ** 2.4)
    return (float(lin[0]), float(lin[1]), float(lin[2]))


def hsv(
    rng: Rng, h: tuple[float, float], s: tuple[float, float], v: tuple[float, float]
) -> tuple[float, float, float]:
    """A linear albedo from hue (degrees), saturation and value ranges of its sRGB colour."""
    rgb = colorsys.hsv_to_rgb(
        (rng.uniform(*h) % 360) / 360, float(rng.uniform(*s)), float(rng.uniform(*v))
    )
    return _linear(rgb)


#: sRGB hue / saturation / value ranges of the material families (ordinary interiors).
PALETTES: dict[str, list[tuple[tuple[float, float], tuple[float, float], tuple[float, float]]]] = {
    "wall": [((15.0, 50.0), (0.02, 0.15), (0.72, 0.95))] * 4
    + [((0, 360), (0.08, 0.35), (0.5, 0.9))],
    "ceiling": [((20, 60), (0.0, 0.08), (0.8, 0.97))],
    "wood": [((18, 38), (0.35, 0.7), (0.25, 0.75))],
    "laminate": [((0, 360), (0.0, 0.08), (0.6, 0.95)), ((20, 45), (0.1, 0.3), (0.6, 0.9))],
    "dark": [((0, 360), (0.0, 0.2), (0.05, 0.25))],
    "metal": [((190, 230), (0.0, 0.1), (0.4, 0.8))],
    "fabric": [((0, 360), (0.1, 0.6), (0.15, 0.8))],
    "linen": [((0, 360), (0.0, 0.12), (0.75, 0.97)), ((0, 360), (0.15, 0.45), (0.5, 0.9))],
    "carpet": [((0, 360), (0.05, 0.4), (0.2, 0.6))],
    "tile": [((20, 60), (0.0, 0.15), (0.55, 0.9))],
    "bright": [((0, 360), (0.4, 0.95), (0.4, 0.95))],
    "any": [((0, 360), (0.0, 0.9), (0.1, 0.95))],
}


def color(rng: Rng, family: str) -> tuple[float, float, float]:
    """A linear albedo of ``family`` (a key of :data:`PALETTES`)."""
    options = PALETTES[family]
    h, s, v = options[int(rng.integers(len(options)))]
    return hsv(rng, h, s, v)


def material(rng: Rng, family: str, *, texture: str | None = None) -> Material:
    """A material of ``family`` with a subtle texture (value noise unless ``texture`` says
    ``"wood"``, ``"tiles"``, ``"plain"``, ``"weave"``)."""
    albedo = color(rng, family)
    kind = texture or str(rng.choice(["noise", "noise", "plain"]))
    if kind == "wood":
        tex = Texture.stripes(float(rng.uniform(0.01, 0.06)), float(rng.uniform(-0.2, 0.2)))
        contrast = float(rng.uniform(0.1, 0.35))
    elif kind == "tiles":
        tex, contrast = (
            Texture.checker(float(rng.uniform(0.25, 0.6))),
            float(rng.uniform(0.03, 0.15)),
        )
    elif kind == "weave":
        tex = Texture.noise(float(rng.uniform(0.003, 0.02)), int(rng.integers(2**31)))
        contrast = float(rng.uniform(0.1, 0.4))
    elif kind == "plain":
        tex, contrast = Texture.uniform(), 0.0
    else:
        tex = Texture.noise(float(rng.uniform(0.02, 0.4)), int(rng.integers(2**31)))
        contrast = float(rng.uniform(0.03, 0.25))
    ir = float(np.clip(np.mean(albedo) * rng.uniform(0.8, 1.3), 0.003, 0.95))
    return Material(albedo, ir, tex, contrast)


def image_material(rng: Rng, period: float) -> Material:
    """A random picture ``period`` metres wide: a background with soft blobs (a photo, a
    painting), sharp rectangles (a poster, a chart), fine noise, and often a frame border."""
    n = 64
    yy, xx = np.mgrid[0:n, 0:n] / n
    img = np.ones((n, n, 3)) * np.asarray(color(rng, "any"))
    for _ in range(int(rng.integers(2, 8))):
        c = np.asarray(color(rng, "any"))
        cx, cy, r = rng.uniform(0, 1), rng.uniform(0, 1), rng.uniform(0.05, 0.5)
        wgt = np.clip(1.5 - np.hypot(xx - cx, yy - cy) / r, 0, 1)[..., None]
        img = img * (1 - wgt) + c * wgt
    for _ in range(int(rng.integers(0, 6))):
        x0, y0 = rng.uniform(0, 0.8, 2)
        x1, y1 = x0 + rng.uniform(0.05, 0.5), y0 + rng.uniform(0.02, 0.4)
        img[(xx >= x0) & (xx < x1) & (yy >= y0) & (yy < y1)] = color(rng, "any")
    img = img * (1 + 0.1 * rng.standard_normal((n, n, 1)))
    if rng.random() < 0.7:
        b = int(rng.integers(2, 7))
        frame = np.asarray(color(rng, str(rng.choice(["wood", "dark", "ceiling"]))))
        img[:b], img[-b:], img[:, :b], img[:, -b:] = frame, frame, frame, frame
    return Material((1.0, 1.0, 1.0), 0.5, Texture.image(np.clip(img, 0, 1), period), 1.0)


# -- geometry helpers --------------------------------------------------------------------------


def slab(sx: float, sy: float, sz: float, x: float, y0: float, z: float) -> Mesh:
    """A box of size ``(sx, sy, sz)`` standing on height ``y0`` (its bottom at y = -y0)."""
    return box((sx, sy, sz), (x, -y0 - sy / 2, z))


def _legs(w: float, d: float, h: float, t: float, inset: float = 0.03) -> list[Mesh]:
    return [
        slab(t, h, t, sx * (w / 2 - inset - t / 2), 0.0, sz * (d / 2 - inset - t / 2))
        for sx in (-1, 1)
        for sz in (-1, 1)
    ]


def _merge(meshes: list[Mesh]) -> Mesh:
    return meshes[0].merged(*meshes[1:])


# -- furniture ---------------------------------------------------------------------------------

#: Share of beds and sofas with things lying on them (clothes, bags, books, papers).
P_CLUTTERED = 0.5
#: Share of round (pedestal) dining and coffee tables.
P_ROUND_TABLE = 0.25


def table(rng: Rng) -> Parts:
    """A dining table, desk or coffee table (label table)."""
    kind = rng.choice(["dining", "desk", "coffee"], p=[0.4, 0.4, 0.2])
    w = float(rng.uniform(0.8, 1.8) if kind != "coffee" else rng.uniform(0.6, 1.2))
    d = float(rng.uniform(0.5, 0.95) if kind != "coffee" else rng.uniform(0.4, 0.7))
    h = float(rng.uniform(0.68, 0.78) if kind != "coffee" else rng.uniform(0.35, 0.5))
    t = float(rng.uniform(0.02, 0.05))
    fam = str(rng.choice(["wood", "laminate", "dark"], p=[0.5, 0.35, 0.15]))
    mat = material(rng, fam, texture="wood" if fam == "wood" else None)
    if kind != "desk" and rng.random() < P_ROUND_TABLE:  # round top on a pedestal
        r = min(w, 1.2) / 2
        top = cylinder(r, t, (0, -(h - t / 2), 0), segments=40)
        foot = cylinder(r * 0.4, 0.03, (0, -0.015, 0), segments=24)
        post = cylinder(float(rng.uniform(0.03, 0.08)), h - t, (0, -(h - t) / 2, 0), segments=12)
        a = r / np.sqrt(2)
        return Parts(
            [Part(_merge([top, foot, post]), mat, TABLE)], (2 * r, 2 * r), [(-a, a, -a, a, h)]
        )
    meshes = [slab(w, t, d, 0, h - t, 0)]
    if kind == "desk" and rng.random() < 0.6:  # side panels / a drawer block
        pw = float(rng.uniform(0.02, 0.4))
        meshes += [slab(pw, h - t, d * 0.95, sx * (w / 2 - pw / 2), 0, 0) for sx in (-1, 1)]
    else:
        meshes += _legs(w, d, h - t, float(rng.uniform(0.03, 0.07)))
    return Parts([Part(_merge(meshes), mat, TABLE)], (w, d), [(-w / 2, w / 2, -d / 2, d / 2, h)])


def chair(rng: Rng) -> Parts:
    """A four-legged or office chair (label chair)."""
    s = float(rng.uniform(0.4, 0.52))
    h = float(rng.uniform(0.42, 0.5))
    back = float(rng.uniform(0.35, 0.55))
    fam = str(rng.choice(["wood", "fabric", "dark", "metal"]))
    mat = material(rng, fam)
    t = 0.04
    meshes = [slab(s, t, s, 0, h - t, 0), slab(s, back, 0.04, 0, h, s / 2 - 0.02)]
    if rng.random() < 0.4:  # office chair: post and star base
        meshes += [
            cylinder(0.03, h - t - 0.08, (0, -(h - t + 0.08) / 2, 0), segments=12),
            box((s * 1.1, 0.04, 0.06), (0, -0.06, 0)),
            box((0.06, 0.04, s * 1.1), (0, -0.06, 0)),
        ]
    else:
        meshes += _legs(s, s, h - t, 0.035, 0.01)
    return Parts([Part(_merge(meshes), mat, CHAIR)], (s, s))


def sofa(rng: Rng) -> Parts:
    """A sofa with a back, arms and cushions (label sofa; throw pillows are objects)."""
    w, d = float(rng.uniform(1.3, 2.4)), float(rng.uniform(0.8, 0.98))
    seat, top = float(rng.uniform(0.38, 0.46)), float(rng.uniform(0.7, 0.92))
    arm, bt = float(rng.uniform(0.1, 0.25)), float(rng.uniform(0.15, 0.25))
    mat = material(rng, "fabric", texture="weave")
    arm_h = float(rng.uniform(seat + 0.1, top - 0.05))
    meshes = [
        slab(w - 2 * arm, seat, d - bt, 0, 0, -bt / 2),
        slab(w, top, bt, 0, 0, d / 2 - bt / 2),
        slab(arm, arm_h, d, -(w - arm) / 2, 0, 0),
        slab(arm, arm_h, d, (w - arm) / 2, 0, 0),
    ]
    parts = [Part(_merge(meshes), mat, SOFA)]
    for _ in range(int(rng.integers(0, 4))):
        p = float(rng.uniform(0.3, 0.45))
        x = float(rng.uniform(-(w / 2 - arm - p / 2), w / 2 - arm - p / 2))
        pil = slab(p, p, 0.12, x, seat, d / 2 - bt - 0.08)
        parts.append(Part(pil, material(rng, "fabric", texture="weave"), OBJECTS))
    seat_top = (-(w / 2 - arm), w / 2 - arm, -d / 2, d / 2 - bt - 0.2, seat)
    return Parts(parts, (w, d), [seat_top] if rng.random() < P_CLUTTERED else [], soft=True)


def bed(rng: Rng) -> Parts:
    """A bed: frame, mattress and cover, headboard (label bed) and pillows (objects)."""
    w, length = float(rng.uniform(0.9, 1.9)), float(rng.uniform(1.9, 2.15))
    top = float(rng.uniform(0.4, 0.65))
    frame = material(rng, str(rng.choice(["wood", "dark", "laminate"])), texture="wood")
    cover = material(rng, str(rng.choice(["linen", "fabric"])), texture="weave")
    head_h = float(rng.uniform(0.8, 1.3))
    parts = [
        Part(
            _merge([slab(w, top - 0.25, length, 0, 0, 0), slab(w, head_h, 0.06, 0, 0, length / 2)]),
            frame,
            BED,
        ),
        Part(slab(w + 0.04, 0.25, length - 0.1, 0, top - 0.25, -0.03), cover, BED),
    ]
    n = 1 if w < 1.2 else 2
    for k in range(n):
        pw = w / n - 0.1
        x = -w / 2 + (k + 0.5) * w / n
        pil = slab(pw, 0.14, 0.4, x, top, length / 2 - 0.3)
        parts.append(Part(pil, material(rng, "linen", texture="weave"), OBJECTS))
    cover_top = (-w / 2, w / 2, -length / 2, length / 2 - 0.55, top)
    return Parts(parts, (w, length), [cover_top] if rng.random() < P_CLUTTERED else [], soft=True)


def cabinet(rng: Rng) -> Parts:
    """A cabinet, dresser, night stand, counter or fridge (label furniture) with drawer fronts."""
    kind = rng.choice(
        ["night", "dresser", "counter", "tall", "fridge"], p=[0.25, 0.3, 0.2, 0.15, 0.1]
    )
    dims = {
        "night": ((0.35, 0.6), (0.35, 0.5), (0.45, 0.7)),
        "dresser": ((0.7, 1.6), (0.4, 0.6), (0.7, 1.2)),
        "counter": ((1.2, 2.8), (0.55, 0.65), (0.85, 0.95)),
        "tall": ((0.5, 1.1), (0.35, 0.6), (1.5, 2.1)),
        "fridge": ((0.55, 0.8), (0.6, 0.75), (1.4, 1.9)),
    }[str(kind)]
    w, d, h = (float(rng.uniform(*r)) for r in dims)
    fam = "metal" if kind == "fridge" else str(rng.choice(["wood", "laminate", "dark"]))
    body = material(rng, fam, texture="wood" if fam == "wood" else None)
    meshes = [slab(w, h, d, 0, 0, 0)]
    fronts = []
    rows = int(rng.integers(1, 5))
    cols = int(rng.integers(1, 3)) if w > 0.8 else 1
    for r in range(rows):
        for c in range(cols):
            fw, fh = w / cols - 0.02, (h - 0.08) / rows - 0.02
            fronts.append(
                slab(
                    fw,
                    fh,
                    0.015,
                    -w / 2 + (c + 0.5) * w / cols,
                    0.06 + r * (h - 0.08) / rows,
                    -d / 2 - 0.007,
                )
            )
    front = material(rng, fam) if rng.random() < 0.5 else body
    parts = [Part(_merge(meshes), body, FURNITURE), Part(_merge(fronts), front, FURNITURE)]
    return Parts(parts, (w, d), [(-w / 2, w / 2, -d / 2, d / 2, h)])


def shelf(rng: Rng) -> Parts:
    """A bookshelf (furniture) filled with books (books) and a few objects."""
    w, d, h = (
        float(rng.uniform(0.6, 1.4)),
        float(rng.uniform(0.25, 0.4)),
        float(rng.uniform(0.8, 2.1)),
    )
    t = 0.02
    body = material(rng, str(rng.choice(["wood", "laminate", "dark"])), texture="wood")
    n = max(2, round(h / float(rng.uniform(0.3, 0.42))))
    pitch = (h - t) / n
    meshes = [slab(t, h, d, sx * (w / 2 - t / 2), 0, 0) for sx in (-1, 1)]
    meshes.append(slab(w, h, t, 0, 0, d / 2 - t / 2))
    meshes += [slab(w - 2 * t, t, d, 0, k * pitch, 0) for k in range(n + 1)]
    parts = [Part(_merge(meshes), body, FURNITURE)]
    fill = float(rng.uniform(0.4, 1.0))
    for k in range(n):
        x = -w / 2 + t
        while x < w / 2 - t - 0.05:
            bw = float(rng.uniform(0.015, 0.06))
            if rng.random() > fill:  # a gap or a small object
                x += float(rng.uniform(0.05, 0.25))
                continue
            bh = float(min(pitch - t - 0.01, rng.uniform(0.15, 0.32)))
            bd = float(min(d - t - 0.01, rng.uniform(0.12, 0.3)))
            mesh = slab(bw, bh, bd, x + bw / 2, k * pitch + t, d / 2 - t - bd / 2)
            parts.append(
                Part(mesh, material(rng, "bright" if rng.random() < 0.6 else "any"), BOOKS)
            )
            x += bw + 0.002
    return Parts(parts, (w, d), [(-w / 2, w / 2, -d / 2, d / 2, h)])


def screen(rng: Rng, *, monitor: bool) -> Parts:
    """A monitor or TV on a stand (label tv): a dark glossy screen in a frame."""
    w = float(rng.uniform(0.4, 0.65) if monitor else rng.uniform(0.7, 1.4))
    sh = w * float(rng.uniform(0.56, 0.75))
    lift = float(rng.uniform(0.05, 0.2) if monitor else rng.uniform(0.03, 0.1))
    frame = material(rng, "dark")
    stand = [slab(w * 0.3, 0.02, 0.18, 0, 0, 0), slab(0.05, lift, 0.03, 0, 0, 0.03)]
    body = slab(w, sh, 0.05, 0, lift, 0)
    on = rng.random() < 0.3  # a screen showing a picture
    face = slab(w - 0.03, sh - 0.03, 0.005, 0, lift + 0.015, -0.027)
    fm = image_material(rng, w) if on else material(rng, "dark", texture="plain")
    parts = [Part(_merge([body, *stand]), frame, TV), Part(face, fm, TV, glossy=0.5)]
    return Parts(parts, (w, 0.2))


def small_object(rng: Rng, *, floor: bool = False) -> list[Part]:
    """Clutter (label objects unless books): boxes, bottles, cups, balls, lamps, papers, book
    stacks, laptops, bins, bags and clothes, pot plants. ``floor``: sizes of things standing on
    the floor."""
    kinds = [
        "box",
        "bottle",
        "cup",
        "ball",
        "lamp",
        "paper",
        "books",
        "laptop",
        "bin",
        "bag",
        "plant",
    ]
    weights = (
        [0.35, 0.02, 0.0, 0.05, 0.08, 0.0, 0.06, 0.0, 0.14, 0.22, 0.08]
        if floor
        else [0.17, 0.15, 0.13, 0.04, 0.03, 0.12, 0.15, 0.08, 0.0, 0.05, 0.08]
    )
    kind = str(rng.choice(kinds, p=np.asarray(weights) / sum(weights)))
    mat = material(rng, "any")
    glossy = float(rng.uniform(0, 0.4))
    if kind in ("bottle", "cup", "bin"):
        r_range, h_range = {
            "bottle": ((0.03, 0.05), (0.15, 0.32)),
            "cup": ((0.03, 0.06), (0.07, 0.13)),
            "bin": ((0.1, 0.2), (0.25, 0.45)),
        }[kind]
        rr, hh = float(rng.uniform(*r_range)), float(rng.uniform(*h_range))
        return [Part(cylinder(rr, hh, (0, -hh / 2, 0), segments=16), mat, OBJECTS, glossy)]
    if kind == "ball":
        r = float(rng.uniform(0.04, 0.13))
        return [Part(sphere(r, (0, -r, 0), rings=10, segments=16), mat, OBJECTS, glossy)]
    if kind == "bag":  # a bag or a heap of clothes: a squashed sphere
        r = float(rng.uniform(0.12, 0.35) if floor else rng.uniform(0.08, 0.18))
        sq = float(rng.uniform(0.3, 0.8))
        m = sphere(r, rings=10, segments=16).scaled((1.0, sq, float(rng.uniform(0.6, 1.0))))
        return [
            Part(
                m.transformed(translation=(0, -r * sq, 0)),
                material(rng, "fabric", texture="weave"),
                OBJECTS,
            )
        ]
    if kind == "lamp":
        h = float(rng.uniform(1.2, 1.7) if floor else rng.uniform(0.3, 0.6))
        r = float(rng.uniform(0.1, 0.25))
        lamp = cylinder(0.015, h, (0, -h / 2, 0), segments=8).merged(
            cylinder(r, r * 1.1, (0, -h - r * 0.4, 0), segments=20),
            box((r, 0.03, r), (0, -0.015, 0)),
        )
        return [Part(lamp, material(rng, "linen"), OBJECTS)]
    if kind == "paper":
        w, d = float(rng.uniform(0.15, 0.35)), float(rng.uniform(0.2, 0.35))
        m = slab(w, float(rng.uniform(0.002, 0.03)), d, 0, 0, 0)
        return [Part(m, material(rng, "ceiling", texture="plain"), OBJECTS)]
    if kind == "books":  # a stack of books lying flat
        parts, y = [], 0.0
        for _ in range(int(rng.integers(1, 6))):
            t = float(rng.uniform(0.015, 0.05))
            m = slab(float(rng.uniform(0.14, 0.25)), t, float(rng.uniform(0.2, 0.3)), 0, y, 0)
            parts.append(
                Part(m.transformed(_yaw(float(rng.normal(0, 0.1)))), material(rng, "bright"), BOOKS)
            )
            y += t
        return parts
    if kind == "laptop":
        w, d = float(rng.uniform(0.3, 0.4)), float(rng.uniform(0.22, 0.28))
        base = slab(w, 0.02, d, 0, 0, 0)
        lid = slab(w, d, 0.01, 0, 0.02, d / 2)
        return [
            Part(base.merged(lid), material(rng, str(rng.choice(["dark", "metal"]))), OBJECTS, 0.3)
        ]
    if kind == "plant":  # a pot plant
        r = float(rng.uniform(0.1, 0.2) if floor else rng.uniform(0.05, 0.1))
        ph = r * float(rng.uniform(1.0, 1.8))
        pot = cylinder(r, ph, (0, -ph / 2, 0), segments=16)
        leaf_r = r * float(rng.uniform(1.2, 2.0))
        leaves = sphere(leaf_r, rings=8, segments=12).scaled(
            (1.0, float(rng.uniform(0.8, 1.5)), 1.0)
        )
        top = float(leaves.bounds()[1][1])
        leaves = leaves.transformed(translation=(0, -ph - top + 0.02, 0))
        green = Material(
            hsv(rng, (70, 140), (0.3, 0.8), (0.15, 0.55)),
            0.4,
            Texture.noise(float(rng.uniform(0.01, 0.04)), int(rng.integers(2**31))),
            float(rng.uniform(0.3, 0.7)),
        )
        return [
            Part(pot, material(rng, str(rng.choice(["wood", "any", "ceiling"]))), OBJECTS),
            Part(leaves, green, OBJECTS),
        ]
    lo, hi = (
        ([0.2, 0.15, 0.2], [0.7, 0.6, 0.6]) if floor else ([0.06, 0.04, 0.06], [0.35, 0.3, 0.3])
    )
    parts, y = [], 0.0
    for _ in range(int(rng.integers(1, 4)) if floor else 1):  # a stack of boxes
        sz = rng.uniform(lo, hi)
        brown = rng.random() < 0.5  # cardboard
        m = slab(float(sz[0]), float(sz[1]), float(sz[2]), 0, y, 0).transformed(
            _yaw(float(rng.normal(0, 0.15)))
        )
        parts.append(
            Part(
                m,
                material(rng, "wood", texture="plain") if brown else material(rng, "any"),
                OBJECTS,
            )
        )
        y += float(sz[1])
        lo, hi = [0.15, 0.1, 0.15], [float(sz[0]), 0.4, float(sz[2])]
    return parts


def _yaw(theta: float) -> np.ndarray:
    c, s = np.cos(theta), np.sin(theta)
    return np.array([[c, 0, s], [0, 1, 0], [-s, 0, c]])


#: Builders of floor-standing furniture by kind.
FURNITURE_BUILDERS = {
    "table": table,
    "chair": chair,
    "sofa": sofa,
    "bed": bed,
    "cabinet": cabinet,
    "shelf": shelf,
}
