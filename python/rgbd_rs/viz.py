"""Small picture helpers: colourised depth, labelled tiles, PNG output (OpenCV, BGR)."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import cv2
import numpy as np
import numpy.typing as npt

from rgbd_rs import _validate
from rgbd_rs.errors import InvalidArgumentError, ShapeMismatchError
from rgbd_rs.io import write_png

__all__ = [
    "NO_DATA_BGR",
    "NO_DATA_RGB",
    "as_bgr",
    "class_legend",
    "class_picture",
    "colorize",
    "colorize_with_bar",
    "grid",
    "image_panel",
    "map_panel",
    "outline_segments",
    "paint_segments",
    "save_png",
    "tile",
]

U8 = npt.NDArray[np.uint8]

#: OpenCV's colour maps are numbered 0..COLORMAP_LAST.
COLORMAP_LAST = max(getattr(cv2, n) for n in dir(cv2) if n.startswith("COLORMAP_"))
#: Largest tile width accepted by :func:`tile` (pixels).
MAX_TILE_WIDTH = 8192
#: Most columns :func:`tile` lays out.
MAX_TILE_COLUMNS = 64


def _range(finite: np.ndarray, vmin: float | None, vmax: float | None) -> tuple[float, float]:
    """The colour range: ``vmin`` / ``vmax``, else the 1st / 99th percentile of the ``finite``
    values (0 / 1 when there are none)."""
    lo = vmin if vmin is not None else float(np.percentile(finite, 1)) if finite.size else 0.0
    hi = vmax if vmax is not None else float(np.percentile(finite, 99)) if finite.size else 1.0
    return lo, hi


def _given_range(vmin: object, vmax: object) -> tuple[float | None, float | None]:
    """The validated ``vmin`` / ``vmax`` (None = from the data); refuses ``vmin > vmax``."""
    lo = None if vmin is None else _validate.real("vmin", vmin)
    hi = None if vmax is None else _validate.real("vmax", vmax)
    if lo is not None and hi is not None and lo > hi:
        raise InvalidArgumentError(f"vmax: got {hi}, expected a value >= vmin ({lo})")
    return lo, hi


def colorize(
    values: npt.ArrayLike,
    vmin: float | None = None,
    vmax: float | None = None,
    colormap: int = cv2.COLORMAP_TURBO,
) -> U8:
    """Map an ``H x W`` float map to a BGR image (NaN -> black). Range defaults to the 1st-99th
    percentile of the finite values."""
    v = _validate.array("values", values, shape=(None, None))
    vmin, vmax = _given_range(vmin, vmax)
    colormap = _validate.integer("colormap", colormap, maximum=COLORMAP_LAST)
    finite = np.isfinite(v)
    if not finite.any():
        return np.zeros((*v.shape, 3), np.uint8)
    lo, hi = _range(v[finite], vmin, vmax)
    scaled = np.clip((np.nan_to_num(v, nan=lo) - lo) / max(hi - lo, 1e-12), 0, 1)
    out = cv2.applyColorMap((scaled * 255).astype(np.uint8), colormap)
    out[~finite] = 0
    return np.asarray(out, dtype=np.uint8)


#: Colour of "no data" pixels in :func:`colorize_with_bar` (BGR, mid grey: distinct from every
#: TURBO colour and from black image content).
NO_DATA_BGR = (128, 128, 128)
#: The same grey in RGB order (class colours, classes.json).
NO_DATA_RGB = (NO_DATA_BGR[2], NO_DATA_BGR[1], NO_DATA_BGR[0])


def colorize_with_bar(
    values: npt.ArrayLike,
    vmin: float | None = None,
    vmax: float | None = None,
    unit: str = "px",
    colormap: int = cv2.COLORMAP_TURBO,
    title: str = "",
) -> U8:
    """:func:`colorize` with "no data" in grey and a colour bar below the map: the range's ends
    and middle labelled in ``unit``, and a grey swatch labelled "no data"; ``title`` (if any)
    is written in a strip above the map."""
    v = np.asarray(_validate.array("values", values, shape=(None, None)), np.float32)
    vmin, vmax = _given_range(vmin, vmax)
    for name, text in (("unit", unit), ("title", title)):
        if not isinstance(text, str):
            raise InvalidArgumentError(f"{name}: got {type(text).__name__}, expected str")
    finite = np.isfinite(v)
    lo, hi = _range(v[finite], vmin, vmax)
    if hi <= lo:
        hi = lo + 1.0
    img = colorize(v, lo, hi, colormap)
    img[~finite] = NO_DATA_BGR
    h, w = v.shape
    bar_h, text_h = max(10, h // 30), 22
    ramp = np.linspace(0, 255, max(w - 110, 16)).astype(np.uint8)[None, :]
    bar = cv2.applyColorMap(np.repeat(ramp, bar_h, axis=0), colormap)
    panel = np.full((bar_h + text_h + 6, max(w, bar.shape[1] + 110), 3), 255, np.uint8)
    panel[3 : 3 + bar_h, 5 : 5 + bar.shape[1]] = bar
    sw = panel.shape[1] - 100
    panel[3 : 3 + bar_h, sw : sw + bar_h] = NO_DATA_BGR
    font, y = cv2.FONT_HERSHEY_SIMPLEX, 3 + bar_h + 17
    cv2.putText(panel, "no data", (sw - 2, y), font, 0.45, (0, 0, 0), 1, cv2.LINE_AA)
    for frac in (0.0, 0.5, 1.0):
        label = f"{lo + frac * (hi - lo):.3g} {unit}"
        x = 5 + int(frac * (bar.shape[1] - 1)) - int(frac * 9 * len(label))
        cv2.putText(panel, label, (max(0, x), y), font, 0.45, (0, 0, 0), 1, cv2.LINE_AA)
    if panel.shape[1] > w:
        img = np.pad(img, ((0, 0), (0, panel.shape[1] - w), (0, 0)), constant_values=255)
    parts = [img, panel]
    if title:
        parts.insert(0, _title_strip(title, panel.shape[1]))
    return np.ascontiguousarray(np.vstack(parts))


#: Panel width of the figures (pixels): readable at 960x540 inputs, four to a 1920-px row.
PANEL_WIDTH = 480
_FONT = cv2.FONT_HERSHEY_SIMPLEX


def _title_strip(title: str, width: int) -> U8:
    """``title`` on white, word-wrapped to ``width`` pixels (22 px a line after the first)."""
    lines: list[str] = []
    for word in title.split(" "):
        if lines and cv2.getTextSize(f"{lines[-1]} {word}", _FONT, 0.55, 1)[0][0] <= width - 10:
            lines[-1] = f"{lines[-1]} {word}"
        else:
            lines.append(word)
    strip = np.full((28 + 22 * (len(lines) - 1), width, 3), 255, np.uint8)
    for k, line in enumerate(lines):
        cv2.putText(strip, line, (5, 20 + 22 * k), _FONT, 0.55, (0, 0, 0), 1, cv2.LINE_AA)
    return strip


#: The narrowest panel (its title must fit).
MIN_PANEL_WIDTH = 16


def _width(width: object) -> int:
    return _validate.integer("width", width, minimum=MIN_PANEL_WIDTH, maximum=MAX_TILE_WIDTH)


def map_panel(
    values: npt.ArrayLike,
    title: str,
    *,
    unit: str,
    vmin: float | None = None,
    vmax: float | None = None,
    width: int = PANEL_WIDTH,
    colormap: int = cv2.COLORMAP_TURBO,
) -> U8:
    """A titled panel of an ``H x W`` float map at ``width`` pixels: the map in colour (NaN in
    the "no data" grey, :data:`NO_DATA_BGR`) over a colour bar labelled in ``unit`` with a
    "no data" swatch. Range: ``vmin`` / ``vmax``, else the 1st / 99th percentile."""
    v = np.asarray(_validate.array("values", values, shape=(None, None)), np.float32)
    w = _width(width)
    h = max(1, round(v.shape[0] * w / v.shape[1]))
    small = cv2.resize(v, (w, h), interpolation=cv2.INTER_NEAREST)
    return colorize_with_bar(small, vmin, vmax, unit=unit, colormap=colormap, title=title)


def image_panel(image: npt.ArrayLike, title: str, *, width: int = PANEL_WIDTH) -> U8:
    """A titled panel of a BGR (or grey) uint8 image at ``width`` pixels."""
    img = _u8_image("image", image)
    if img.ndim == 2:
        img = np.repeat(img[:, :, None], 3, axis=2)
    if not isinstance(title, str):
        raise InvalidArgumentError(f"title: got {type(title).__name__}, expected str")
    w = _width(width)
    h = max(1, round(img.shape[0] * w / img.shape[1]))
    cell = cv2.resize(img, (w, h), interpolation=cv2.INTER_AREA)
    return np.ascontiguousarray(np.vstack([_title_strip(title, w), cell]))


def grid(panels: Sequence[U8], columns: int) -> U8:
    """Panels (BGR uint8, any sizes) in rows of ``columns``, each cell padded with white to the
    largest panel, a white gutter between cells."""
    if not isinstance(panels, Sequence) or len(panels) == 0:
        raise InvalidArgumentError(
            f"panels: got {type(panels).__name__}, expected a non-empty list of BGR images"
        )
    columns = _validate.integer("columns", columns, minimum=1, maximum=MAX_TILE_COLUMNS)
    cells = [_u8_image(f"panels[{i}]", p) for i, p in enumerate(panels)]
    cells = [np.repeat(c[:, :, None], 3, axis=2) if c.ndim == 2 else c for c in cells]
    hmax, wmax = max(c.shape[0] for c in cells) + 8, max(c.shape[1] for c in cells) + 8
    padded = [
        cv2.copyMakeBorder(
            c,
            4,
            hmax - c.shape[0] - 4,
            4,
            wmax - c.shape[1] - 4,
            cv2.BORDER_CONSTANT,
            value=(255, 255, 255),
        )
        for c in cells
    ]
    blank = np.full_like(padded[0], 255)
    rows = []
    for i in range(0, len(padded), columns):
        row = padded[i : i + columns]
        rows.append(np.hstack(row + [blank] * (columns - len(row))))
    return np.ascontiguousarray(np.vstack(rows))


def class_legend(names: Sequence[str], colors: Sequence[tuple[int, int, int]], width: int) -> U8:
    """A white strip of ``width`` pixels with one swatch (RGB ``colors``) and name per class,
    wrapped into as many rows as needed."""
    names, colors = _names_colors(names, colors)
    if len(names) != len(colors) or not names:
        raise InvalidArgumentError(
            f"names/colors: got {len(names)} names and {len(colors)} colours, expected as many"
        )
    w = _width(width)
    items, x, y, rows = [], 5, 0, 1
    for name in names:
        tw = cv2.getTextSize(name, _FONT, 0.45, 1)[0][0] + 30
        if x + tw > w and x > 5:
            x, y, rows = 5, y + 22, rows + 1
        items.append((x, y))
        x += tw
    strip = np.full((rows * 22 + 6, w, 3), 255, np.uint8)
    for (x, y), name, rgb in zip(items, names, colors, strict=True):
        cv2.rectangle(strip, (x, y + 6), (x + 14, y + 20), tuple(int(c) for c in rgb[::-1]), -1)
        cv2.rectangle(strip, (x, y + 6), (x + 14, y + 20), (0, 0, 0), 1)
        cv2.putText(strip, name, (x + 19, y + 18), _FONT, 0.45, (0, 0, 0), 1, cv2.LINE_AA)
    return strip


def _names_colors(names: object, colors: object) -> tuple[list[str], list[tuple[int, int, int]]]:
    """Class names (str) and their RGB colours (three integers 0..255 each), checked."""
    if isinstance(names, str) or not isinstance(names, Sequence):
        raise InvalidArgumentError(f"names: got {type(names).__name__}, expected a list of str")
    if not all(isinstance(n, str) for n in names):
        raise InvalidArgumentError("names: got a name that is not a str, expected class names")
    if isinstance(colors, (str, bytes)) or not isinstance(colors, (Sequence, np.ndarray)):
        raise InvalidArgumentError(
            f"colors: got {type(colors).__name__}, expected a list of (r, g, b) triples"
        )
    out: list[tuple[int, int, int]] = []
    for i, c in enumerate(colors):
        ok = isinstance(c, (Sequence, np.ndarray)) and not isinstance(c, str) and len(c) == 3
        if not ok or not all(
            isinstance(v, (int, np.integer)) and not isinstance(v, bool) and 0 <= v <= 255
            for v in c
        ):
            raise InvalidArgumentError(
                f"colors[{i}]: got {c!r}, expected three integers 0..255 (r, g, b)"
            )
        out.append((int(c[0]), int(c[1]), int(c[2])))
    if len(names) != len(out) or not names:
        raise InvalidArgumentError(
            f"names/colors: got {len(names)} names and {len(out)} colours, expected as many "
            "(at least one)"
        )
    return list(names), out


def class_picture(
    labels: npt.ArrayLike,
    names: Sequence[str],
    colors: Sequence[tuple[int, int, int]],
    title: str,
    *,
    width: int = PANEL_WIDTH,
) -> U8:
    """A titled panel of a class-label image (``H x W`` ints indexing ``names`` / RGB
    ``colors``; negative = no data, in :data:`NO_DATA_BGR`) with a legend of the classes."""
    lab = _label_image("labels", labels)
    names, colors = _names_colors(names, colors)
    if lab.size and int(lab.max()) >= len(names):
        raise InvalidArgumentError(
            f"labels: got label {int(lab.max())}, expected < {len(names)} (one name per class)"
        )
    lut = np.array([c[::-1] for c in colors], np.uint8)
    img = lut[np.clip(lab, 0, None)]
    img[lab < 0] = NO_DATA_BGR
    panel = image_panel(img, title, width=width)
    legend = class_legend([*names, "no data"], [*colors, NO_DATA_BGR[::-1]], panel.shape[1])
    return np.ascontiguousarray(np.vstack([panel, legend]))


def _u8_image(name: str, value: object) -> U8:
    img = _validate.asarray(name, value)
    if img.dtype != np.uint8:
        raise InvalidArgumentError(f"{name}: got dtype {img.dtype}, expected uint8")
    if img.ndim not in (2, 3) or (img.ndim == 3 and img.shape[2] != 3) or img.size == 0:
        raise ShapeMismatchError(
            f"{name}: got shape {img.shape}, expected a non-empty (H, W) or (H, W, 3) image"
        )
    return img


def as_bgr(image: npt.ArrayLike) -> U8:
    """Any ``H x W`` / ``H x W x 3`` uint8 image (RGB assumed for 3 channels) as BGR."""
    img = _u8_image("image", image)
    if img.ndim == 2:
        img = np.repeat(img[:, :, None], 3, axis=2)
    return np.ascontiguousarray(img[:, :, ::-1]).astype(np.uint8)


def tile(images: Sequence[U8], labels: Sequence[str], columns: int = 3, width: int = 480) -> U8:
    """Resize BGR images to a common ``width`` and tile them with captions."""
    if not isinstance(images, (Sequence, np.ndarray)) or len(images) == 0:
        raise InvalidArgumentError(
            f"images: got {type(images).__name__}, expected a non-empty list of BGR images"
        )
    if isinstance(labels, str) or not isinstance(labels, Sequence) or len(labels) != len(images):
        raise InvalidArgumentError(
            f"labels: got {labels!r}, expected {len(images)} captions (one per image)"
        )
    if not all(isinstance(label, str) for label in labels):
        raise InvalidArgumentError(f"labels: got {labels!r}, expected strings")
    columns = _validate.integer("columns", columns, minimum=1, maximum=MAX_TILE_COLUMNS)
    width = _validate.integer("width", width, minimum=1, maximum=MAX_TILE_WIDTH)
    checked = [_u8_image(f"images[{i}]", img) for i, img in enumerate(images)]
    cells = []
    for img, label in zip(checked, labels, strict=True):
        if img.ndim == 2:
            img = np.repeat(img[:, :, None], 3, axis=2)
        h = max(1, round(img.shape[0] * width / img.shape[1]))
        cell = cv2.resize(img, (width, h), interpolation=cv2.INTER_AREA)
        cell = cv2.copyMakeBorder(cell, 24, 0, 0, 0, cv2.BORDER_CONSTANT, value=(255, 255, 255))
        cv2.putText(cell, label, (6, 17), cv2.FONT_HERSHEY_SIMPLEX, 0.5, (0, 0, 0), 1, cv2.LINE_AA)
        cells.append(cell)
    hmax = max(c.shape[0] for c in cells)
    cells = [cv2.copyMakeBorder(c, 0, hmax - c.shape[0], 0, 0, cv2.BORDER_CONSTANT) for c in cells]
    blank = np.zeros_like(cells[0])
    rows = []
    for i in range(0, len(cells), columns):
        row = cells[i : i + columns]
        row += [blank] * (columns - len(row))
        rows.append(np.hstack(row))
    return np.ascontiguousarray(np.vstack(rows))


def _label_image(name: str, value: object, shape: tuple[int, ...] | None = None) -> np.ndarray:
    raw = _validate.asarray(name, value)
    if raw.dtype.kind not in "iu":
        raise InvalidArgumentError(f"{name}: got dtype {raw.dtype}, expected an integer array")
    want = (None, None) if shape is None else shape
    return _validate.array(name, raw, shape=want, dtype=np.int64)


def _boundaries(labels: np.ndarray, width: int) -> npt.NDArray[np.bool_]:
    """Pixels with a right or lower neighbour of another label, thickened to ``width``."""
    e = np.zeros(labels.shape, bool)
    e[:, :-1] |= labels[:, :-1] != labels[:, 1:]
    e[:-1, :] |= labels[:-1, :] != labels[1:, :]
    if width > 1:
        e = cv2.dilate(e.astype(np.uint8), np.ones((width, width), np.uint8)).astype(bool)
    return e


def outline_segments(
    image: npt.ArrayLike,
    labels: npt.ArrayLike,
    color: tuple[int, int, int] = (255, 255, 0),
    width: int = 2,
) -> U8:
    """The RGB ``image`` (``H x W x 3`` uint8) as BGR with the boundaries of ``labels``
    (``H x W`` int) drawn ``width`` pixels wide in the RGB ``color`` (yellow)."""
    img = as_bgr(image)
    lab = _label_image("labels", labels, img.shape[:2])
    if not (
        isinstance(color, tuple)
        and len(color) == 3
        and all(isinstance(c, int) and 0 <= c <= 255 for c in color)
    ):
        raise InvalidArgumentError(f"color: got {color!r}, expected an (r, g, b) tuple of 0..255")
    w = _validate.integer("width", width, minimum=1, maximum=64)
    img[_boundaries(lab, w)] = color[::-1]
    return img


def _hsv_bgr(hue: np.ndarray, sat: np.ndarray, val: np.ndarray) -> U8:
    """BGR uint8 of hue, saturation and value in [0, 1] (per pixel, the same for any image
    size: OpenCV's conversion rounds differently in its vector and scalar paths)."""
    sector = np.floor(hue * 6) % 6
    f = hue * 6 - np.floor(hue * 6)
    p, q, t = val * (1 - sat), val * (1 - sat * f), val * (1 - sat * (1 - f))
    r = np.select([sector == k for k in range(6)], [val, q, p, p, t, val])
    g = np.select([sector == k for k in range(6)], [t, val, val, q, p, p])
    b = np.select([sector == k for k in range(6)], [p, p, t, val, val, q])
    return np.ascontiguousarray(np.round(np.stack([b, g, r], axis=-1) * 255).astype(np.uint8))


def paint_segments(labels: npt.ArrayLike, boundaries: bool = True) -> U8:
    """A BGR picture of ``labels`` (``H x W`` int): one colour per label (a hash of the label,
    so the same label has the same colour in every frame of a merge animation; saturated and
    bright, hue, saturation 60-100 % and value 70-100 % drawn from the hash, so no segment is
    grey and none passes for no data), negative labels (no data) in the "no data" grey
    :data:`NO_DATA_BGR`, boundaries white unless ``boundaries=False``."""
    lab = _label_image("labels", labels)
    if not isinstance(boundaries, bool):
        raise InvalidArgumentError(f"boundaries: got {boundaries!r}, expected True or False")
    ids, where = np.unique(lab, return_inverse=True)  # one colour computed per label
    h = (ids.astype(np.uint64) * np.uint64(2654435761)) & np.uint64(0xFFFFFFFF)
    byte = [((h >> np.uint64(s)) & np.uint64(255)).astype(np.float64) / 255 for s in (0, 8, 16)]
    colours = _hsv_bgr(byte[0], 0.6 + 0.4 * byte[1], 0.7 + 0.3 * byte[2])
    colours[ids < 0] = NO_DATA_BGR
    img = colours[where.reshape(lab.shape)]
    if boundaries:
        img[_boundaries(lab, 1)] = 255
    return np.ascontiguousarray(img)


def save_png(path: str | Path, image: npt.NDArray[np.uint8] | npt.NDArray[np.uint16]) -> Path:
    """Write a BGR/grey 8-bit (or 16-bit grey) image as PNG (creating parent folders),
    atomically."""
    return write_png(path, image, rgb=False)
