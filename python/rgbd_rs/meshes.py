"""Triangle meshes: a small validated container, primitives for procedural scenes, and readers
for OFF (including ModelNet's fused-header quirk) and PLY files.

Example:
    >>> from rgbd_rs.meshes import box, sphere
    >>> m = box((1.0, 2.0, 0.5)).merged(sphere(0.3, center=(0, 0, 1)))
    >>> m.triangles.shape[1], [round(float(x), 2) for x in m.bounds()[1]]
    (3, [0.5, 1.0, 1.3])
"""

from __future__ import annotations

import re
import warnings
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import numpy.typing as npt

from rgbd_rs import _validate
from rgbd_rs._array_eq import array_eq
from rgbd_rs.errors import InvalidArgumentError, RgbdError

from ._reasons import reason

__all__ = ["Mesh", "box", "concat", "cylinder", "load_mesh", "quad", "sphere"]

F32 = npt.NDArray[np.float32]
U32 = npt.NDArray[np.uint32]


def _vec3(name: str, value: object) -> npt.NDArray[np.float64]:
    """A finite 3-vector."""
    if isinstance(value, (str, bytes)):
        raise InvalidArgumentError(f"{name}: got {value!r}, expected three numbers")
    return _validate.array(name, value, shape=(3,), dtype=np.float64, finite=True)


def _mesh_arg(name: str, value: object) -> Mesh:
    if not isinstance(value, Mesh):
        raise InvalidArgumentError(f"{name}: got {type(value).__name__}, expected a Mesh")
    return value


#: Most segments / rings a primitive accepts (a 4096-segment sphere already has 33 M triangles).
MAX_SEGMENTS = 4096


@array_eq
@dataclass(frozen=True)
class Mesh:
    """``vertices`` (N x 3 float32, metres) and ``triangles`` (M x 3 vertex indices)."""

    vertices: F32
    triangles: U32

    def __post_init__(self) -> None:
        given = self.vertices
        v = _validate.array("vertices", given, shape=(None, 3), finite=True)
        if isinstance(given, np.ndarray) and given.dtype == np.float64:
            centre = _far_centre(given, BLUR_FACTOR)
            if centre is not None:
                warnings.warn(
                    f"vertices: a shape at {np.array2string(centre, precision=4)}, over "
                    f"{BLUR_FACTOR:g} times its size from the origin, where float32 (the mesh's "
                    "vertex type) blurs it; subtract its centre first",
                    RuntimeWarning,
                    stacklevel=3,
                )
        t = _validate.asarray("triangles", self.triangles)
        if t.ndim != 2 or t.shape[1] != 3 or not np.issubdtype(t.dtype, np.integer):
            raise InvalidArgumentError(
                f"triangles: got {t.dtype} array of shape {t.shape}, expected integer (M, 3)"
            )
        if t.size and (t.min() < 0 or t.max() >= len(v)):
            raise InvalidArgumentError(
                f"triangles: got indices in [{t.min()}, {t.max()}], expected 0..{len(v) - 1}"
            )
        object.__setattr__(self, "vertices", v)
        object.__setattr__(self, "triangles", np.ascontiguousarray(t, dtype=np.uint32))

    def bounds(self) -> tuple[F32, F32]:
        """Axis-aligned bounding box ``(min, max)``."""
        return self.vertices.min(axis=0), self.vertices.max(axis=0)

    def transformed(
        self, rotation: npt.ArrayLike | None = None, translation: npt.ArrayLike = (0, 0, 0)
    ) -> Mesh:
        """``R v + t`` applied to every vertex (``rotation`` a proper rotation: orthonormal,
        det +1; a scale or a mirror would turn the triangles' winding inside out)."""
        from rgbd_rs.camera import Pose

        r = np.eye(3) if rotation is None else Pose(rotation=rotation).rotation  # type: ignore[arg-type]
        t = _vec3("translation", translation)
        v = self.vertices.astype(np.float64) @ r.T + t
        return Mesh(v.astype(np.float32), self.triangles)

    def scaled(self, factor: float | Sequence[float]) -> Mesh:
        """Vertices multiplied by ``factor`` (scalar or per axis)."""
        try:
            ndim = np.ndim(factor)
        except ValueError:  # ragged
            ndim = -1
        if isinstance(factor, (str, bytes)) or ndim not in (0, 1):
            raise InvalidArgumentError(
                f"factor: got {factor!r}, expected a number or three numbers (per axis)"
            )
        f = _validate.array("factor", factor, shape=(3,) if ndim else (), finite=True)
        return Mesh(self.vertices * f, self.triangles)

    def normalized(self, size: float = 1.0) -> Mesh:
        """Centred on its bounding-box centre and scaled so the longest side is ``size``."""
        size = _length("size", size)
        lo, hi = self.bounds()
        extent = float((hi - lo).max())
        if not extent > 0:
            raise InvalidArgumentError("mesh: got a zero-size mesh, expected a non-degenerate one")
        return self.transformed(translation=-(lo + hi) / 2).scaled(size / extent)

    def merged(self, *others: Mesh) -> Mesh:
        """One mesh holding this one and ``others``."""
        return concat([self, *(_mesh_arg(f"others[{i}]", m) for i, m in enumerate(others))])


def concat(meshes: Sequence[Mesh]) -> Mesh:
    """Concatenate meshes (vertex indices are offset)."""
    if isinstance(meshes, Mesh) or not isinstance(meshes, (list, tuple)):
        raise InvalidArgumentError(
            f"meshes: got {type(meshes).__name__}, expected a list of Mesh objects"
        )
    meshes = [_mesh_arg(f"meshes[{i}]", m) for i, m in enumerate(meshes)]
    if not meshes:
        raise InvalidArgumentError("meshes: got an empty list, expected at least one Mesh")
    offsets = np.cumsum([0] + [len(m.vertices) for m in meshes[:-1]])
    return Mesh(
        np.concatenate([m.vertices for m in meshes]),
        np.concatenate([m.triangles + np.uint32(o) for m, o in zip(meshes, offsets, strict=True)]),
    )


def quad(corners: npt.ArrayLike) -> Mesh:
    """Two triangles over four corners given in order around the quad."""
    c = _validate.array("corners", corners, shape=(4, 3), finite=True)
    return Mesh(c, np.array([[0, 1, 2], [0, 2, 3]], np.uint32))


#: Lengths a primitive may have: float32 (the vertex type) holds them with room to resolve
#: their vertices (a radius of 1e-308 was stored as 0, one of 1e308 as inf).
LENGTH_RANGE = (1e-30, 1e30)


def _length(name: str, value: object) -> float:
    """A primitive's length: a positive real within :data:`LENGTH_RANGE` (float32 vertices)."""
    return _validate.within(name, value, LENGTH_RANGE, "a length")


def _float32(local: npt.NDArray[np.float64], center: npt.NDArray[np.float64]) -> F32:
    """A primitive's vertices (``local``, about the origin) moved to ``center`` as the Mesh stores
    them (float32), refusing a ``center`` so far out that float32 cannot resolve the primitive's
    size there (it would collapse or distort)."""
    v32 = (local + center).astype(np.float32)
    want = np.ptp(local, axis=0)
    got = np.ptp(v32.astype(np.float64), axis=0)
    if not (np.isfinite(v32).all() and np.all(np.abs(got - want) <= 1e-3 * want.max())):
        raise InvalidArgumentError(
            f"center: got {center.tolist()}, where float32 (the mesh's vertex type) cannot hold "
            f"a primitive {want.max():.3g} across; expected a centre nearer the origin"
        )
    return v32


def box(size: Sequence[float], center: Sequence[float] = (0.0, 0.0, 0.0)) -> Mesh:
    """Closed axis-aligned box of ``size`` (x, y, z) centred at ``center``."""
    s = _vec3("size", size) / 2
    if not (s > 0).all():
        raise InvalidArgumentError(f"size: got {size}, expected three positive lengths")
    for k in range(3):
        _length(f"size[{k}]", 2 * float(s[k]))
    c = _vec3("center", center)
    v = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)], np.float64)
    faces = [[0, 1, 3, 2], [4, 6, 7, 5], [0, 4, 5, 1], [2, 3, 7, 6], [0, 2, 6, 4], [1, 5, 7, 3]]
    tris = [[f[0], f[1], f[2]] for f in faces] + [[f[0], f[2], f[3]] for f in faces]
    return Mesh(_float32(v * s, c), np.array(tris, np.uint32))


def cylinder(
    radius: float,
    height: float,
    center: Sequence[float] = (0.0, 0.0, 0.0),
    segments: int = 32,
    axis: int = 1,
) -> Mesh:
    """Closed cylinder along world ``axis`` (default y, the vertical of a y-down camera world)."""
    radius = _length("radius", radius)
    height = _length("height", height)
    c = _vec3("center", center)
    n = _validate.integer("segments", segments, minimum=3, maximum=MAX_SEGMENTS)
    axis = _validate.integer("axis", axis, maximum=2)
    a = np.linspace(0, 2 * np.pi, n, endpoint=False)
    ring = np.stack([radius * np.cos(a), radius * np.sin(a)], axis=1)
    h = height / 2
    pts = [np.insert(ring, 1, y, axis=1) for y in (-h, h)]
    v = np.concatenate([*pts, [[0, -h, 0], [0, h, 0]]])
    i = np.arange(n)
    j = (i + 1) % n
    side = np.concatenate([np.stack([i, j, i + n], 1), np.stack([j, j + n, i + n], 1)])
    caps = np.concatenate(
        [np.stack([i, np.full(n, 2 * n), j], 1), np.stack([i + n, j + n, np.full(n, 2 * n + 1)], 1)]
    )
    v = np.roll(v, axis - 1, axis=1)  # the cylinder axis lands on `axis`
    return Mesh(_float32(v, c), np.concatenate([side, caps]).astype(np.uint32))


def sphere(
    radius: float, center: Sequence[float] = (0.0, 0.0, 0.0), rings: int = 16, segments: int = 32
) -> Mesh:
    """UV sphere with ``rings`` latitude bands and ``segments`` longitudes."""
    radius = _length("radius", radius)
    c = _vec3("center", center)
    nr = _validate.integer("rings", rings, minimum=2, maximum=MAX_SEGMENTS)
    ns = _validate.integer("segments", segments, minimum=3, maximum=MAX_SEGMENTS)
    th = np.linspace(0, np.pi, nr + 1)[:, None]
    ph = np.linspace(0, 2 * np.pi, ns, endpoint=False)[None, :]
    v = np.stack(
        [np.sin(th) * np.cos(ph), np.cos(th) * np.ones_like(ph), np.sin(th) * np.sin(ph)], -1
    ).reshape(-1, 3)
    r, s = np.meshgrid(np.arange(nr), np.arange(ns), indexing="ij")
    a = (r * ns + s).ravel()
    b = (r * ns + (s + 1) % ns).ravel()
    tris = np.concatenate([np.stack([a, b, a + ns], 1), np.stack([b, b + ns, a + ns], 1)])
    return Mesh(_float32(v * radius, c), tris.astype(np.uint32))


def load_mesh(path: str | Path) -> Mesh:
    """Read an OFF or PLY triangle mesh (polygons are fan-triangulated).

    OFF files may carry ``#`` comments, per-vertex extras (``COFF``, ``NOFF``, ``STOFF``, ...:
    colours, normals, texture coordinates) and per-face colours, all ignored; ModelNet's files
    whose header is fused with the counts line (``OFF3514 3546 0``) are accepted. Unreadable or
    truncated files raise :class:`RgbdError` naming the file.
    """
    if not isinstance(path, (str, Path)) or not str(path):
        raise InvalidArgumentError(f"path: got {path!r}, expected a mesh file path")
    path = Path(path)
    if not path.is_file():
        raise InvalidArgumentError(f"path: got {path}, expected an existing mesh file")
    suffix = path.suffix.lower()
    if suffix == ".off":
        return _read_off(path)
    if suffix == ".ply":
        return _read_ply(path)
    raise InvalidArgumentError(f"path: got a {suffix!r} file ({path}), expected .off or .ply")


def _fits_float32(v: np.ndarray) -> bool:
    """All finite and within float32's range (the Mesh stores float32)."""
    return bool(np.all(np.abs(v) <= np.finfo(np.float32).max))


#: An OFF header keyword, ``[ST][C][N][4][n]OFF`` (texture coordinates, colours, normals, 4-D
#: or n-D vertices), and the rest of its word: ModelNet fuses the counts with it (``OFF490``).
_OFF_KEYWORD = re.compile(r"(ST)?(C)?(N)?(4)?(n)?OFF(.*)")


def _read_off(path: Path) -> Mesh:
    """An ASCII OFF file (:func:`_parse_off`) as a Mesh; :class:`RgbdError` names the file and
    what is wrong with it."""
    text = path.read_text(errors="replace")
    try:
        try:
            v, tris = _parse_off(text)
        except ValueError as lines_error:  # a free-format file, values wrapped across lines?
            free = _parse_off_stream(text)
            if free is None:
                raise lines_error from None
            v, tris = free
        if not _fits_float32(v):
            raise ValueError("vertex coordinates beyond float32 range or not finite")
        if not len(tris):
            raise ValueError("no faces of three or more vertices: a mesh needs triangles")
    except ValueError as exc:
        raise RgbdError(f"{path}: not a valid OFF mesh ({exc})") from exc
    return Mesh(_near_origin(path, v), tris)


def _fan(idx: list[int]) -> list[list[int]]:
    """The fan triangles ``(0, k, k + 1)`` of one polygon's vertex indices."""
    return [[idx[0], idx[k], idx[k + 1]] for k in range(1, len(idx) - 1)]


def _parse_off_stream(text: str) -> tuple[npt.NDArray[np.float64], U32] | None:
    """A plain ``OFF`` file read as one stream of values (the format allows line breaks
    anywhere but inside a face's colour): its vertices and fan-triangulated faces, or None
    where that reading fails too (then the line-wise reading's error stands). Only for the plain
    header, whose vertices have exactly three values, and faces without colours."""
    tokens = " ".join(line.split("#", 1)[0] for line in text.splitlines()).split()
    if not tokens or not tokens[0].startswith("OFF") or tokens[0][3:4].isalpha():
        return None
    rest = ([tokens[0][3:]] if tokens[0][3:] else []) + tokens[1:]
    try:
        nv, nf = int(rest[0]), int(rest[1])
        vals = rest[3:]
        if nv < 0 or nf < 0 or len(vals) < 3 * nv:
            return None
        v = np.asarray(vals[: 3 * nv], np.float64).reshape(nv, 3)
        pos, tris = 3 * nv, []
        for _ in range(nf):
            k = int(vals[pos])
            idx = [int(x) for x in vals[pos + 1 : pos + 1 + k]]
            if k < 0 or len(idx) != k or any(not 0 <= i < nv for i in idx):
                return None
            tris += _fan(idx)
            pos += 1 + k
    except (IndexError, ValueError):
        return None
    if pos != len(vals):  # values left over: colours, which only the line-wise reading places
        return None
    return v, np.asarray(tris, np.uint32).reshape(-1, 3)


def _parse_off(text: str) -> tuple[npt.NDArray[np.float64], U32]:
    """Vertices and fan-triangulated faces of an ASCII OFF file's ``text``; a ValueError says
    what is wrong with it.

    A ``#`` starts a comment that runs to the end of its line; blank lines are skipped. The
    header keyword (``OFF``, ``COFF``, ``NOFF``, ``STOFF``, ...) is followed by the counts
    ``vertices faces [edges]``: on the next line, on the keyword's line, or fused with the
    keyword as ModelNet writes ``OFF490 518 0``. Then one vertex per line, its first three values
    the coordinates (colours, normals or texture coordinates after them are ignored), and one
    face per line: its vertex count ``n`` and ``n`` indices, anything after them (a colour)
    ignored. 4-D and n-D vertices (``4OFF``, ``nOFF``) and binary files are refused.
    """
    lines = text.splitlines()
    if "#" in text:
        lines = [line.split("#", 1)[0] for line in lines]
    rows = list(filter(str.strip, lines))  # the lines with content
    head = rows[0].split() if rows else []
    key = _OFF_KEYWORD.fullmatch(head[0]) if head else None
    if key is None:
        got = f"it begins {rows[0].strip()[:40]!r}" if rows else "the file is empty"
        raise ValueError(f"no OFF header: {got}, expected OFF, COFF, NOFF, STOFF or the like")
    if key[4] or key[5]:
        raise ValueError(
            f"the header {head[0]!r} declares {'4-D' if key[4] else 'n-D'} vertices, which are "
            "not supported: expected 3-D ones, as in OFF, COFF, NOFF, STOFF or the like"
        )
    counts = ([key[6]] if key[6] else []) + head[1:]
    if counts[:1] == ["BINARY"]:
        raise ValueError("a binary OFF file, which is not supported; expected an ASCII one")
    first = 1  # the row after the counts
    if not counts and len(rows) > 1:
        counts, first = rows[1].split(), 2
    if len(counts) > 3:
        raise ValueError(
            f"the counts line {' '.join(counts)[:40]!r} holds {len(counts)} values, expected "
            "'vertices faces edges', then one vertex or face per line"
        )
    try:
        nv, nf = int(counts[0]), int(counts[1])
    except (IndexError, ValueError):
        got = f", got {' '.join(counts)!r}" if counts else ""
        raise ValueError(f"no 'vertices faces edges' counts after the OFF header{got}") from None
    if nv < 0 or nf < 0:
        raise ValueError(f"the header gives negative counts ({nv} vertices, {nf} faces)")
    vrows = rows[first : first + nv]
    if len(vrows) < nv:
        raise ValueError(f"the header says {nv} vertices, found {len(vrows)} (truncated file?)")
    v = _off_vertices(vrows, last=first + nv == len(rows))
    frows = rows[first + nv : first + nv + nf]
    if len(frows) < nf:
        raise ValueError(f"the header says {nf} faces, found {len(frows)} (truncated file?)")
    return v, _off_faces(frows, nv, last=first + nv + nf == len(rows))


def _off_vertices(rows: list[str], last: bool) -> npt.NDArray[np.float64]:
    """The first three values of each of ``rows`` (vertex lines) as an ``N x 3`` array;
    ``last``: the final row is the file's last line (cut short there, the file is truncated)."""
    if not rows:
        return np.zeros((0, 3))
    try:  # the common case, at C speed
        return np.loadtxt(rows, np.float64, comments=None, usecols=(0, 1, 2), ndmin=2)
    except ValueError:
        pass  # row by row, to say which is at fault
    out = np.empty((len(rows), 3))
    for i, row in enumerate(rows):
        xyz = row.split()[:3]
        if len(xyz) < 3 and last and i == len(rows) - 1:
            raise ValueError(f"the header says {len(rows)} vertices, found {i} (truncated file?)")
        if len(xyz) < 3:
            raise ValueError(
                f"vertex {i} ({row.strip()[:40]!r}) has {len(xyz)} values, expected x y z"
            )
        try:
            out[i] = [float(x) for x in xyz]
        except ValueError:
            raise ValueError(
                f"a vertex coordinate is not a number (vertex {i}: {row.strip()[:40]!r})"
            ) from None
    return out


def _off_faces(rows: list[str], nv: int, last: bool) -> U32:
    """The fan-triangulated faces of ``rows`` (face lines: a count ``n``, then ``n`` indices
    into ``nv`` vertices, then anything) as ``M x 3`` indices; ``last``: the final row is the
    file's last line (cut short there, the file is truncated)."""
    idx = _same_size_faces(rows)
    if idx is None:  # faces of several sizes, or a bad face: row by row
        return _off_faces_by_row(rows, nv, last)
    bad = (idx < 0) | (idx >= nv)
    if bad.any():
        f = int(np.flatnonzero(bad.any(axis=1))[0])
        raise ValueError(f"face {f} has vertex index {idx[f][bad[f]][0]}, expected 0..{nv - 1}")
    j = np.arange(1, idx.shape[1] - 1)  # fans (0, j, j + 1), face by face
    fan = np.stack([np.broadcast_to(idx[:, :1], (len(idx), len(j))), idx[:, j], idx[:, j + 1]], -1)
    return fan.reshape(-1, 3).astype(np.uint32)


def _same_size_faces(rows: list[str]) -> npt.NDArray[np.int64] | None:
    """``F x n`` vertex indices when all ``rows`` (face lines) are well-formed faces of the same
    size ``n``, read at C speed; None otherwise."""
    if not rows:
        return np.zeros((0, 3), np.int64)
    words = rows[0].split()
    n = int(words[0]) if words[0].isdecimal() else -1
    if not 0 <= n < len(words):
        return None
    try:
        table = np.loadtxt(rows, np.int64, comments=None, usecols=range(n + 1), ndmin=2)
    except ValueError:
        return None
    return table[:, 1:] if (table[:, 0] == n).all() else None


def _off_faces_by_row(rows: list[str], nv: int, last: bool) -> U32:
    """:func:`_off_faces` row by row (faces of several sizes), saying which face is at fault."""
    tris: list[list[int]] = []
    for f, row in enumerate(rows):
        words = row.split()
        try:
            n = int(words[0])
            idx = [int(x) for x in words[1 : 1 + max(n, 0)]]
        except ValueError:
            raise ValueError(
                f"face {f} has a vertex count or index that is not a whole number "
                f"({row.strip()[:40]!r})"
            ) from None
        if n < 0:
            raise ValueError(f"face {f} has a negative vertex count ({n})")
        if len(idx) < n and last and f == len(rows) - 1:
            raise ValueError(f"the file ends inside face {f} (truncated file?)")
        if len(idx) < n:
            raise ValueError(
                f"face {f} ({row.strip()[:40]!r}) lists {len(idx)} vertices, expected {n}"
            )
        bad = [i for i in idx if not 0 <= i < nv]
        if bad:
            raise ValueError(f"face {f} has vertex index {bad[0]}, expected 0..{nv - 1}")
        tris += _fan(idx)
    return np.asarray(tris, np.uint32).reshape(-1, 3)


def _ply_vertex_count(path: Path) -> int | None:
    """The vertex count a PLY header declares (``element vertex N``), None if it has none."""
    with open(path, "rb") as fh:
        head = fh.read(1 << 16)
    for raw in head.split(b"end_header")[0].splitlines():
        words = raw.split()
        if len(words) == 3 and words[0] == b"element" and words[1] == b"vertex":
            try:
                return int(words[2])
            except ValueError:
                return None
    return None


def _check_ply_vertices(path: Path, found: int) -> None:
    """Refuses a PLY whose body holds fewer vertices than its header declares (a truncated
    ASCII file that the parser reads short without a word)."""
    declared = _ply_vertex_count(path)
    if declared is not None and found < declared:
        raise RgbdError(
            f"{path}: not a valid PLY file (the header says {declared} vertices, found {found}: "
            "truncated file?)"
        )


def _read_ply(path: Path) -> Mesh:
    import trimesh

    try:
        # fix_texture=False: per-face texture coordinates would split shared vertices.
        m = trimesh.load(path, file_type="ply", force="mesh", process=False, fix_texture=False)
        v, f = np.asarray(getattr(m, "vertices", [])), np.asarray(getattr(m, "faces", []))
    except Exception as exc:  # trimesh raises many types for corrupt files
        raise RgbdError(f"{path}: not a valid PLY mesh ({reason(exc)})") from exc
    if len(v) == 0 or len(f) == 0:
        raise RgbdError(f"{path}: PLY mesh has no vertices or faces")
    _check_ply_vertices(path, len(v))
    if f.ndim != 2 or f.shape[1] != 3 or f.min() < 0 or f.max() >= len(v):
        raise RgbdError(f"{path}: PLY faces are not triangles indexing its {len(v)} vertices")
    if not _fits_float32(v):
        raise RgbdError(f"{path}: PLY vertex coordinates beyond float32 range or not finite")
    return Mesh(_near_origin(path, v), f.astype(np.uint32))


def _near_origin(path: Path, vertices: np.ndarray) -> F32:
    """A file's vertices as float32, moved to the origin first (with a warning) when float32
    could not hold the shape's detail where it lies (map coordinates)."""
    # Reached from load_mesh through its reader: the warning points at load_mesh's caller.
    return np.asarray(_far_from_origin(str(path), vertices, stacklevel=4), np.float32)


#: Where a shape's results do not depend on its position (its class, views, voxels), a shape
#: whose bounding-box centre lies farther from the origin than this many times its largest side
#: is moved to the origin in float64 before it becomes float32 (float32 resolves 6e-8 of a
#: coordinate; ModelNet's shapes, in the unit sphere, are never moved).
FAR_FACTOR = 100.0
#: A mesh or cloud *file* is moved (with a warning) only where float32 would blur it by over
#: 1e-3 of its size: farther than this many times its size from the origin (map coordinates).
#: Nearer, the reader keeps the file's coordinates.
BLUR_FACTOR = 8e3


def _far_centre(
    points: npt.NDArray[np.floating], factor: float = FAR_FACTOR
) -> npt.NDArray[np.float64] | None:
    """The bounding-box centre of ``points`` (``N x 3``, finite) when it lies more than
    ``factor`` times the box's largest side from the origin, else None (and None for a box of
    no size: a single point is not blurred, it is refused elsewhere)."""
    if len(points) == 0:
        return None
    p = np.asarray(points, np.float64)
    lo, hi = p.min(axis=0), p.max(axis=0)
    centre: npt.NDArray[np.float64] = (lo + hi) / 2
    size = float((hi - lo).max())
    if size > 0 and np.abs(centre).max() > factor * size:
        return centre
    return None


def _far_from_origin(
    name: str, points: npt.NDArray[np.floating], stacklevel: int = 2
) -> npt.NDArray[np.floating]:
    """``points`` as read from a file, moved to the origin (in float64) with a warning when they
    lie over :data:`BLUR_FACTOR` times their size from it, where float32, the type they are kept
    in, would blur them; otherwise unchanged. ``stacklevel``: the warning's, counted from the
    caller of this function."""
    if points.ndim != 2 or points.shape[1:] != (3,) or not np.isfinite(points).all():
        return points  # the caller's checks name what is wrong
    centre = _far_centre(points, BLUR_FACTOR)
    if centre is None:
        return points
    warnings.warn(
        f"{name}: its shape lies at {np.array2string(centre, precision=4)}, over "
        f"{BLUR_FACTOR:g} times its size from the origin, where float32 (the type shapes are "
        "kept in) would blur it: moved to the origin",
        RuntimeWarning,
        stacklevel=stacklevel + 1,
    )
    return np.asarray(points, np.float64) - centre
