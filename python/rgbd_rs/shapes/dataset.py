"""Shape datasets and the representation cache of the shape classifier (thesis ch. 5).

**Sources** (:func:`open_shapes`): the shared ModelNet point packs (``modelnet10_1024.npz``,
``modelnet40_1024.npz``: 1024 points per shape, official splits; :class:`PointCloudSet`) and the
Princeton OFF tree ``ROOT/<class>/{train,test}/<name>.off`` of the original meshes
(:class:`OffTree`). Single files: :func:`load_shape` reads meshes (.off, .ply, .obj) and point
clouds (.npy, .npz, .ply without faces, .pcd).

**Inputs** (:class:`InputSpec`, :func:`shape_inputs`, :func:`batch_inputs`): the network's inputs
of one shape are its six depth views (:func:`rgbd_rs.shapes.views.depth_views`), its three voxel
density profiles (:func:`rgbd_rs.shapes.voxels.density_profiles`; meshes voxelized ``solid``,
points by occupancy) and, once the package computes them, its six curvature maps; every map is
locally contrast-normalised on its own (§5.3, :data:`NORMALISATIONS`). :func:`batch_inputs`
computes many shapes in parallel threads (the Rust kernels release the GIL).

**Cache** (:func:`build_cache`, :class:`ShapeCache`): one ``<representation>.npy`` per
representation (``N x ...`` float16, memory-mappable with ``np.load(mmap_mode="r")``) plus
``labels.npy``, ``splits.npy``, ``names.json``, ``meta.json`` and ``done.npy`` (per shape: 0 to do,
1 done, 2 failed). Shapes are computed in chunks; a chunk's rows are flushed before its ``done``
bytes, so a killed run loses at most the chunk in flight and a re-run skips what is done.
``shard=(i, n)`` computes shapes ``i, i + n, ...`` only: n processes (a scheduler's array job) fill
one cache together, each writing its own rows of the shared files (one machine or a filesystem
with coherent shared writes; not NFS). :meth:`ShapeCache.dataset` serves a split to the trainer.
"""

from __future__ import annotations

import concurrent.futures
import dataclasses
import functools
import hashlib
import io
import json
import os
import re
import warnings
from collections.abc import Callable, Iterable, Iterator, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, TypeAlias, Union

import numpy as np
import numpy.typing as npt
import torch
from torch.utils.data import Dataset

from rgbd_rs import _validate
from rgbd_rs.errors import InvalidArgumentError, RgbdError, ShapeMismatchError
from rgbd_rs.io import (
    _bytes_writer,
    _create_once,
    _npy_bytes,
    _npy_writer,
    _reserve,
    read_npy,
    read_npz,
)
from rgbd_rs.meshes import Mesh, _check_ply_vertices
from rgbd_rs.nn.shapes import (
    DEFAULT_REPRESENTATIONS,
    MAX_RESOLUTION,
    MIN_VIEW_RESOLUTION,
    MIN_VOLUME_RESOLUTION,
    REPRESENTATIONS,
    THESIS_VOLUME_RESOLUTION,
    _input_shapes,
    _parse_representations,
)
from rgbd_rs.shapes._cloud import centred_cloud, check_mesh, cloud, far_from_origin

from .._reasons import reason

__all__ = [
    "CACHE_FORMAT",
    "InputSpec",
    "OffTree",
    "PointCloudSet",
    "ShapeCache",
    "ShapeSource",
    "available_representations",
    "batch_inputs",
    "build_cache",
    "load_shape",
    "open_shapes",
    "sample_surface",
    "shape_inputs",
]

#: A mesh or an ``N x 3`` point cloud.
Shape: TypeAlias = Union[Mesh, npt.NDArray[np.float32]]  # noqa: UP007 - runtime alias on 3.10

#: Format tag of a cache's meta.json.
CACHE_FORMAT = "rgbd_rs.shape-cache/1"
#: Split codes of ``splits.npy`` (the ModelNet packs' ``split`` array).
TRAIN, TEST = 0, 1
SPLITS = {"train": TRAIN, "test": TEST}
#: ``done.npy`` codes.
TODO, DONE, FAILED = 0, 1, 2
#: CPU-feasible default view side; the thesis renders 320 x 320 (pass ``view_resolution=320``).
DEFAULT_VIEW_RESOLUTION = 64
#: Per-map normalisations: ``"lcn"`` local contrast normalisation (§5.3, thesis),
#: ``"standardize"`` zero mean and unit variance over the map (a cheap global alternative).
NORMALISATIONS = ("lcn", "standardize")
#: Float16's largest finite value: normalised maps are clipped into it before caching.
_F16_MAX = float(np.finfo(np.float16).max)
#: Points a point-cloud-trained classifier samples on a mesh (the ModelNet packs' count).
MODELNET_POINTS = 1024
#: Shorthand names of the shared ModelNet packs (``open_shapes("modelnet10")``).
PACKS = {"modelnet10": "modelnet10_1024.npz", "modelnet40": "modelnet40_1024.npz"}
MESH_SUFFIXES = (".off", ".ply", ".obj")
POINT_SUFFIXES = (".npy", ".npz", ".pcd", ".ply")


# -- single files -----------------------------------------------------------------------------


def load_shape(path: str | os.PathLike[str]) -> Shape:
    """A :class:`~rgbd_rs.meshes.Mesh` (.off, .obj, or .ply with faces) or an ``N x 3`` float32
    point cloud (.npy, .npz with a ``points`` array or a single array, .ply or .obj without
    faces, .pcd ASCII or binary). A file that is not a mesh or point cloud raises :class:`RgbdError`
    naming it."""
    from rgbd_rs.meshes import load_mesh

    if not isinstance(path, (str, os.PathLike)) or not str(path):
        raise InvalidArgumentError(f"path: got {path!r}, expected a mesh or point-cloud file")
    p = Path(path)
    if not p.is_file():
        raise InvalidArgumentError(f"path: got {p}, expected an existing file")
    suffix = p.suffix.lower()
    if suffix not in MESH_SUFFIXES + POINT_SUFFIXES:
        raise InvalidArgumentError(
            f"path: got a {suffix!r} file ({p}), expected one of "
            f"{sorted(set(MESH_SUFFIXES + POINT_SUFFIXES))}"
        )
    if suffix == ".off":
        return load_mesh(p)  # a face-less OFF is refused there
    if suffix in (".ply", ".obj"):
        return _trimesh_file(p, suffix)
    if suffix == ".pcd":
        return _points(f"{p}", _read_pcd(p), file=True)
    return _points(f"{p}", _read_array(p, suffix), file=True)


def _points(
    name: str, value: object, *, file: bool = False, centre: bool = False
) -> npt.NDArray[np.float32]:
    """``value`` as ``N x 3`` finite points. A file's points that are not finite (an organised
    depth-camera cloud marks its holes with NaN) are dropped with a warning, and a file's cloud
    far from the origin is moved there with a warning (:func:`far_from_origin`); an array given
    in Python must be finite, and with ``centre`` is moved to the origin silently when far out
    (for results that do not depend on where the shape is)."""
    try:
        if file:  # in the file's own dtype: a float64 beyond float32's range is not a hole
            raw = _validate.asarray(name, value)
            if raw.ndim == 2 and raw.shape[1] == 3 and raw.dtype.kind == "f":
                value = far_from_origin(name, _finite_rows(name, raw), stacklevel=3)
        fix = (
            "" if file else "drop the non-finite points first (points[np.isfinite(points).all(1)])"
        )
        pts = centred_cloud(name, value, fix=fix)[0] if centre else cloud(name, value, fix=fix)
    except (InvalidArgumentError, ShapeMismatchError) as exc:
        if file:  # a bad file's content is an RgbdError naming the file
            raise RgbdError(f"not a point cloud: {exc}") from None
        raise
    return pts


def _finite_rows(name: str, points: npt.NDArray[np.float32]) -> npt.NDArray[np.float32]:
    """``points`` without its rows that hold a NaN or infinity (a warning says how many)."""
    keep = np.isfinite(points).all(axis=1)
    if keep.all() or not keep.any():
        return points  # all finite, or none: the caller's check says so
    warnings.warn(
        f"{name}: dropped {int((~keep).sum())} of {len(points)} points that are not finite "
        "(NaN or infinite coordinates)",
        RuntimeWarning,
        stacklevel=4,
    )
    return points[keep]


def _read_array(p: Path, suffix: str) -> np.ndarray:
    if suffix == ".npy":
        return read_npy(p)
    arrays = read_npz(p)
    if "points" in arrays:
        return arrays["points"]
    if len(arrays) == 1:
        return next(iter(arrays.values()))
    raise RgbdError(f"{p}: npz holds {sorted(arrays)}, expected a 'points' array (N x 3)")


def _obj_cut(p: Path) -> str:
    """The last line of an OBJ file when it is a vertex or face line with under three numbers
    (a file cut inside that line, which the parser drops without a word), else ``""``."""
    with open(p, "rb") as fh:
        fh.seek(max(0, fh.seek(0, 2) - 4096))
        tail = fh.read().decode(errors="replace").rstrip("\n\r\t ").splitlines()
    last = tail[-1].split() if tail else []
    return " ".join(last) if last[:1] in (["v"], ["f"]) and len(last) < 4 else ""


#: An OBJ face or line statement holding a negative (relative) or a zero index, searched for in
#: ``b"\n"`` + the file (the literal ``\n`` first makes the search fast).
_OBJ_RELATIVE = re.compile(rb"\n[ \t]*[fl][ \t][^\n#]*?(?<=[ \t/])(?:-|0+(?![^\s/]))")
#: What the indices of an OBJ ``v/vt/vn`` reference count, singular and plural.
_OBJ_REFS = (
    (b"v", "vertex", "vertices"),
    (b"vt", "texture coordinate", "texture coordinates"),
    (b"vn", "normal", "normals"),
)


def _obj_absolute(p: Path, data: bytes) -> bytes:
    """``data``, an OBJ file, with every negative index of its ``f`` and ``l`` statements made
    absolute: ``-1`` is the last vertex (texture coordinate, normal) defined *above* the line.
    trimesh counts it from the file's last one instead, which loads a file of several objects
    with relative indices as the wrong mesh (trimesh issue #2364). A zero index, or one before
    the first vertex, raises :class:`RgbdError` naming the line."""
    seen = dict.fromkeys((key for key, _, _ in _OBJ_REFS), 0)
    lines = data.split(b"\n")
    for n, line in enumerate(lines):
        words = line.split(b"#", 1)[0].split()
        if not words:
            continue
        if words[0] in seen:
            seen[words[0]] += 1
            continue
        if words[0] not in (b"f", b"l"):
            continue
        refs = []
        for word in words[1:]:
            parts = word.split(b"/")
            for k, ((key, one, many), part) in enumerate(zip(_OBJ_REFS, parts, strict=False)):
                try:
                    i = int(part)
                except ValueError:
                    continue  # trimesh's to refuse
                if i > 0:
                    continue
                count = seen[key]
                if i == 0 or i + count < 0:
                    have = (
                        f"1..{count} or -1..-{count}, the {count} {many} defined above it"
                        if count
                        else f"a {one} defined above it, found none"
                    )
                    text = line.strip().decode(errors="replace")[:40]
                    raise RgbdError(
                        f"{p}: not a valid OBJ file (line {n + 1}, {text!r}: {one} index {i}, "
                        f"expected {have})"
                    )
                parts[k] = b"%d" % (i + count + 1)
            refs.append(b"/".join(parts))
        lines[n] = b" ".join([words[0], *refs])
    return b"\n".join(lines)


def _trimesh_file(p: Path, suffix: str) -> Shape:
    import trimesh

    cut = _obj_cut(p) if suffix == ".obj" else ""
    if cut:
        raise RgbdError(f"{p}: the file ends inside the line {cut!r} (truncated file?)")

    source: Path | io.BytesIO = p
    resolver = None  # trimesh's for a path: material files beside it
    if suffix == ".obj" and _OBJ_RELATIVE.search(b"\n" + (data := p.read_bytes())):
        source = io.BytesIO(_obj_absolute(p, data))
        resolver = trimesh.resolvers.FilePathResolver(str(p))  # the same, read from memory
    loaded: Any
    try:
        # fix_texture=False (PLY): per-face texture coordinates would split shared vertices.
        extra: dict[str, Any] = {"fix_texture": False} if suffix == ".ply" else {}
        loaded = trimesh.load(
            source, file_type=suffix[1:], resolver=resolver, process=False, **extra
        )
    except Exception as exc:  # trimesh raises many types for corrupt files
        why = reason(exc)
        raise RgbdError(f"{p}: not a readable {suffix} mesh or point cloud ({why})") from None
    if isinstance(loaded, trimesh.Scene):
        geoms = list(loaded.geometry.values())
        meshes = [g for g in geoms if isinstance(g, trimesh.Trimesh)]
        loaded = trimesh.util.concatenate(meshes) if meshes else (geoms[0] if geoms else None)
    v = np.asarray(getattr(loaded, "vertices", np.zeros((0, 3))))
    f = np.asarray(getattr(loaded, "faces", np.zeros((0, 3))))
    if len(v) == 0:
        raise RgbdError(f"{p}: no vertices or points, expected a mesh or point cloud")
    if v.ndim != 2 or v.shape[1] != 3:  # an OBJ cut inside a vertex line reads as N x 2
        raise RgbdError(
            f"{p}: its vertices have shape {v.shape}, expected three coordinates each "
            "(truncated file?)"
        )
    if suffix == ".ply":
        _check_ply_vertices(p, len(v))
    if len(f) == 0:  # a point cloud: its non-finite points are dropped, as other files' are
        v = _finite_rows(str(p), v)
    if not np.isfinite(v).all():
        bad = int((~np.isfinite(v).all(axis=1)).sum())
        what = "points" if len(f) == 0 else "vertices"
        raise RgbdError(f"{p}: {bad} of {len(v)} {what} have non-finite coordinates")
    if np.abs(v).max() > np.finfo(np.float32).max:
        raise RgbdError(f"{p}: vertex coordinates beyond float32 range")
    v = far_from_origin(str(p), v, stacklevel=3)
    if len(f) == 0:
        return v.astype(np.float32)
    if f.ndim != 2 or f.shape[1] != 3 or f.min() < 0 or f.max() >= len(v):
        raise RgbdError(f"{p}: faces are not triangles indexing its {len(v)} vertices")
    return Mesh(v.astype(np.float32), f.astype(np.uint32))


#: The most values one PCD field may hold per point (PCL's descriptors hold a few hundred).
MAX_PCD_COUNT = 4096


def _read_pcd(p: Path) -> np.ndarray:
    """x, y, z of an ASCII or binary (uncompressed) PCD file."""
    raw = p.read_bytes()
    header: dict[str, list[str]] = {}
    pos = 0
    try:
        while True:
            end = raw.index(b"\n", pos)
            line = raw[pos:end].decode("ascii").strip()
            pos = end + 1
            if not line or line.startswith("#"):
                continue
            key, *vals = line.split()
            header[key.upper()] = vals
            if key.upper() == "DATA":
                break
        fields = header["FIELDS"]
        sizes = [int(s) for s in header["SIZE"]]
        types = header["TYPE"]
        counts = [int(c) for c in header.get("COUNT", ["1"] * len(fields))]
        n = int(header["POINTS"][0]) if "POINTS" in header else int(header["WIDTH"][0])
        mode = header["DATA"][0].lower()
    except (ValueError, KeyError, IndexError, UnicodeDecodeError) as exc:
        raise RgbdError(f"{p}: not a PCD point cloud (bad header: {reason(exc)})") from None
    if missing := [a for a in ("x", "y", "z") if a not in fields]:
        raise RgbdError(
            f"{p}: not a PCD point cloud (its FIELDS {' '.join(fields)} lack {', '.join(missing)})"
        )
    cols = [fields.index(a) for a in ("x", "y", "z")]
    if not (len(sizes) == len(types) == len(counts) == len(fields)):
        raise RgbdError(
            f"{p}: not a PCD point cloud (FIELDS, SIZE, TYPE and COUNT list {len(fields)}, "
            f"{len(sizes)}, {len(types)} and {len(counts)} entries, expected one per field)"
        )
    if any(not 1 <= c <= MAX_PCD_COUNT for c in counts) or any(
        s not in (1, 2, 4, 8) for s in sizes
    ):
        raise RgbdError(
            f"{p}: not a PCD point cloud (SIZE {' '.join(map(str, sizes))}, COUNT "
            f"{' '.join(map(str, counts))}: expected sizes of 1, 2, 4 or 8 bytes and counts of "
            f"1 to {MAX_PCD_COUNT})"
        )
    if n < 0:
        raise RgbdError(f"{p}: not a PCD point cloud (the header says {n} points)")
    if mode == "ascii":
        try:
            table = np.loadtxt(raw[pos:].decode("ascii").splitlines(), ndmin=2)
            offsets = np.cumsum([0, *counts[:-1]])
            xyz = table[:n, [offsets[c] for c in cols]]
        except (ValueError, UnicodeDecodeError, IndexError) as exc:
            raise RgbdError(f"{p}: not a PCD point cloud (bad ASCII data: {reason(exc)})") from None
        if len(table) < n:
            raise RgbdError(
                f"{p}: not a PCD point cloud (the header says {n} points, found {len(table)}: "
                "truncated?)"
            )
        return xyz
    if mode != "binary":
        raise RgbdError(f"{p}: PCD DATA {mode!r} not supported, expected ascii or binary")
    kinds = {"F": "f", "I": "i", "U": "u"}
    try:
        dtype = np.dtype(
            [
                (f"f{i}", f"<{kinds[t]}{s}", (c,) if c > 1 else ())
                for i, (s, t, c) in enumerate(zip(sizes, types, counts, strict=True))
            ]
        )
    except (KeyError, ValueError, TypeError) as exc:
        raise RgbdError(f"{p}: not a PCD point cloud (bad binary data: {reason(exc)})") from None
    if len(raw) - pos < n * dtype.itemsize:
        found = (len(raw) - pos) // max(dtype.itemsize, 1)
        raise RgbdError(
            f"{p}: not a PCD point cloud (the header says {n} points, found {found}: truncated?)"
        )
    try:
        rec = np.frombuffer(raw, dtype=dtype, count=n, offset=pos)
    except (KeyError, ValueError, TypeError) as exc:
        raise RgbdError(f"{p}: not a PCD point cloud (bad binary data: {reason(exc)})") from None
    return np.stack([rec[f"f{c}"].astype(np.float64) for c in cols], axis=1)


def sample_surface(mesh: Mesh, n: int = MODELNET_POINTS, seed: int = 0) -> npt.NDArray[np.float32]:
    """``n`` points drawn uniformly on ``mesh``'s surface (area-weighted triangles, uniform
    barycentric coordinates), deterministic by ``seed``; the ModelNet packs' 1024 by default."""
    if not isinstance(mesh, Mesh):
        raise InvalidArgumentError(f"mesh: got {type(mesh).__name__}, expected a Mesh")
    n = _validate.integer("n", n, minimum=1, maximum=100_000_000)
    seed = _validate.integer("seed", seed, maximum=2**32 - 1)
    check_mesh("mesh", mesh)
    v = mesh.vertices.astype(np.float64)[mesh.triangles.astype(np.int64)]  # M x 3 x 3
    area = 0.5 * np.linalg.norm(np.cross(v[:, 1] - v[:, 0], v[:, 2] - v[:, 0]), axis=1)
    total = float(area.sum())
    rng = np.random.default_rng(seed)
    tri = rng.choice(len(area), size=n, p=area / total)
    r1, r2 = rng.random(n), rng.random(n)
    s = np.sqrt(r1)
    w = np.stack([1 - s, s * (1 - r2), s * r2], axis=1)
    return np.asarray(np.einsum("nk,nkd->nd", w, v[tri]), np.float32)


# -- sources ----------------------------------------------------------------------------------


class ShapeSource:
    """A labelled set of shapes: ``classes`` (sorted names), per shape ``labels`` (int64 index
    into ``classes``), ``splits`` (0 train, 1 test) and ``names``; :meth:`load` reads one shape.
    ``kind`` is ``"points"`` or ``"mesh"``."""

    kind: str
    path: Path
    classes: tuple[str, ...]
    labels: npt.NDArray[np.int64]
    splits: npt.NDArray[np.uint8]
    names: tuple[str, ...]

    def __len__(self) -> int:
        return len(self.labels)

    def load(self, index: int) -> Shape:
        """Shape ``index`` (a Mesh or an ``N x 3`` float32 array)."""
        raise NotImplementedError

    def _index(self, index: int) -> int:
        if len(self) == 0:
            raise InvalidArgumentError(f"index: got {index!r}, but the source holds no shapes")
        return _validate.integer("index", index, maximum=len(self) - 1)

    def _fingerprint(self) -> str:
        """A digest of what the source holds (classes, names, labels, splits, and where the
        subclass can say it cheaply, the shapes themselves): a cache started from one source
        refuses to be resumed from another of the same file name."""
        h = hashlib.sha256()
        h.update(json.dumps([list(self.classes), list(self.names)]).encode())
        h.update(np.ascontiguousarray(self.labels, np.int64).tobytes())
        h.update(np.ascontiguousarray(self.splits, np.uint8).tobytes())
        self._content_digest(h)
        return h.hexdigest()[:16]

    def _content_digest(self, h: Any) -> None:
        """Feed the shapes' content to ``h`` (default: nothing; names and labels only)."""


def _labels_and_splits(
    where: object, labels: np.ndarray, splits: np.ndarray, n_classes: int
) -> tuple[npt.NDArray[np.int64], npt.NDArray[np.uint8]]:
    """A file's per-shape class labels and split codes, checked: integers, labels in
    ``0..n_classes-1``, splits one of :data:`SPLITS`' codes (0 train, 1 test)."""
    for key, arr in (("labels", labels), ("splits", splits)):
        if arr.ndim != 1 or arr.dtype.kind not in "iu":
            raise RgbdError(
                f"{where}: {key} of dtype {arr.dtype} and shape {arr.shape}, expected one "
                "integer per shape"
            )
    if labels.size and (labels.min() < 0 or labels.max() >= n_classes):
        raise RgbdError(
            f"{where}: labels in [{labels.min()}, {labels.max()}], expected 0..{n_classes - 1} "
            f"({n_classes} classes)"
        )
    codes = sorted(SPLITS.values())
    if splits.size and not np.isin(splits, codes).all():
        bad = sorted(set(np.unique(splits).tolist()) - set(codes))
        raise RgbdError(f"{where}: split codes {bad[:5]}, expected {codes} ({', '.join(SPLITS)})")
    return labels.astype(np.int64), splits.astype(np.uint8)


class PointCloudSet(ShapeSource):
    """A ModelNet point pack (``points`` N x P x 3, ``label``, ``split``, ``classes``, ``name``;
    see the shared data README). A missing array raises :class:`RgbdError` naming the file."""

    kind = "points"

    def __init__(self, path: str | os.PathLike[str]) -> None:
        self.path = _validate.path("path", path)
        d = read_npz(self.path, ["points", "label", "split", "classes", "name"])
        pts = d["points"]
        n = len(pts)
        if pts.ndim != 3 or pts.shape[2] != 3 or pts.shape[1] == 0:
            raise RgbdError(f"{self.path}: points of shape {pts.shape}, expected (N, P, 3)")
        if any(len(d[k]) != n for k in ("label", "split", "name")):
            raise RgbdError(f"{self.path}: label/split/name lengths differ from points ({n})")
        self.points = pts
        self.classes = tuple(str(c) for c in d["classes"])
        self.labels, self.splits = _labels_and_splits(
            self.path, d["label"], d["split"], len(self.classes)
        )
        self.names = tuple(str(x) for x in d["name"])

    def load(self, index: int) -> npt.NDArray[np.float32]:
        return np.asarray(self.points[self._index(index)], np.float32)

    def _content_digest(self, h: Any) -> None:
        h.update(np.ascontiguousarray(self.points).tobytes())


class OffTree(ShapeSource):
    """The Princeton ModelNet directory tree ``ROOT/<class>/{train,test}/*.off`` (classes are the
    sorted folder names; files sorted by name). A folder without that layout raises
    :class:`RgbdError` naming it; unreadable meshes raise when loaded."""

    kind = "mesh"

    def __init__(self, root: str | os.PathLike[str]) -> None:
        self.path = _validate.path("root", root)
        if not self.path.is_dir():
            raise RgbdError(f"{self.path}: not a folder, expected a ModelNet OFF tree")
        classes = sorted(
            d.name
            for d in self.path.iterdir()
            if d.is_dir() and any((d / s).is_dir() for s in SPLITS)
        )
        files: list[Path] = []
        labels: list[int] = []
        splits: list[int] = []
        for k, c in enumerate(classes):
            for split_name, code in SPLITS.items():
                folder = self.path / c / split_name
                found = sorted(folder.glob("*.off")) + sorted(folder.glob("*.OFF"))
                files += found
                labels += [k] * len(found)
                splits += [code] * len(found)
        if not files:
            raise RgbdError(
                f"{self.path}: no <class>/train/*.off or <class>/test/*.off files, expected a "
                "ModelNet OFF tree"
            )
        self.files = tuple(files)
        self.classes = tuple(classes)
        self.labels = np.asarray(labels, np.int64)
        self.splits = np.asarray(splits, np.uint8)
        self.names = tuple(f.stem for f in files)

    def load(self, index: int) -> Mesh:
        from rgbd_rs.meshes import load_mesh

        path = self.files[self._index(index)]
        return load_mesh(path)  # a face-less mesh is refused there

    def _content_digest(self, h: Any) -> None:
        for f in self.files:  # file sizes: reading every mesh would take minutes
            h.update(f"{f.relative_to(self.path).as_posix()}:{f.stat().st_size};".encode())


def open_shapes(data: str | os.PathLike[str]) -> ShapeSource:
    """``"modelnet10"`` / ``"modelnet40"`` (the shared packs), a point pack ``.npz`` or an OFF
    tree folder."""
    if not isinstance(data, (str, os.PathLike)) or not str(data):
        raise InvalidArgumentError(f"data: got {data!r}, expected a dataset path or name")
    if isinstance(data, str) and data.lower() in PACKS:
        from rgbd_rs.data.paths import data_root

        root = data_root(required=True)
        assert root is not None
        return PointCloudSet(root / "modelnet" / PACKS[data.lower()])
    p = Path(data)
    if p.is_dir():
        return OffTree(p)
    if p.is_file() and p.suffix.lower() == ".npz":
        return PointCloudSet(p)
    raise InvalidArgumentError(
        f"data: got {str(data)!r}, expected {sorted(PACKS)}, a point pack .npz or an OFF "
        "tree folder"
    )


# -- inputs of one shape ----------------------------------------------------------------------


@functools.cache
def _depth_views() -> Callable[..., np.ndarray] | None:
    """:func:`rgbd_rs.shapes.views.depth_views` when this installation can run it (its Python
    module and native kernels both present), else None."""
    from rgbd_rs.shapes import views

    fn = getattr(views, "depth_views", None)
    if fn is None:
        return None
    try:
        fn(np.zeros((1, 3), np.float32), MIN_VIEW_RESOLUTION, lcn=False)
    except (AttributeError, TypeError):  # the native module predates the views kernels
        return None
    return fn  # type: ignore[no-any-return]


def _curvature_maps() -> Callable[..., np.ndarray] | None:
    """``rgbd_rs.shapes.curvature.curvature_maps(shape, resolution) -> (6, 2, R, R)`` (k1, k2 of
    each depth view) once the package has it, else None."""
    import importlib

    try:
        curvature = importlib.import_module("rgbd_rs.shapes.curvature")
    except ImportError:
        return None
    fn = getattr(curvature, "curvature_maps", None)
    return fn if callable(fn) else None


def _lcn() -> Callable[..., np.ndarray] | None:
    """:func:`rgbd_rs.shapes.views.local_contrast_normalize` (``(image, window)``, per map of a
    stack) when present."""
    from rgbd_rs.shapes import views

    return getattr(views, "local_contrast_normalize", None)


def _lcn_window(resolution: int) -> int:
    from rgbd_rs.shapes import views

    rule = getattr(views, "lcn_window", None)
    if rule is None:
        raise RgbdError(
            "normalisation: 'lcn' needs rgbd_rs.shapes.views.lcn_window; use 'standardize'"
        )
    return int(rule(resolution))


def available_representations() -> tuple[str, ...]:
    """The representations this installation can compute (``volume`` always; ``depth`` with
    :mod:`rgbd_rs.shapes.views`; ``curvature`` once ``rgbd_rs.shapes.curvature`` exists)."""
    have = {"volume": True, "depth": _depth_views() is not None}
    have["curvature"] = _curvature_maps() is not None
    return tuple(r for r in REPRESENTATIONS if have[r])


@dataclass(frozen=True)
class InputSpec:
    """How a shape's inputs are computed; stored in caches and checkpoints so inference repeats
    it. ``representations`` defaults to what :func:`available_representations` offers among
    depth and volume; ``view_resolution`` (thesis 320; default 64, CPU-feasible),
    ``volume_resolution`` (thesis 32), ``normalisation`` one of :data:`NORMALISATIONS`,
    ``volume_fill`` how meshes are voxelized (``"solid"`` counts the inside as §5.3.2's density;
    point clouds are always occupancy). With LCN, ``view_lcn_window`` / ``volume_lcn_window``
    (pixels, odd) default to :func:`rgbd_rs.shapes.views.lcn_window` of the resolution (the
    thesis gives no window) and are recorded, so a checkpoint keeps its windows if the rule
    changes."""

    representations: tuple[str, ...] = field(
        default_factory=lambda: tuple(
            r for r in DEFAULT_REPRESENTATIONS if r in available_representations()
        )
    )
    view_resolution: int = DEFAULT_VIEW_RESOLUTION
    volume_resolution: int = THESIS_VOLUME_RESOLUTION
    normalisation: str = "lcn"
    volume_fill: str = "solid"
    view_lcn_window: int | None = None
    volume_lcn_window: int | None = None

    def __post_init__(self) -> None:
        object.__setattr__(self, "representations", _parse_representations(self.representations))
        for name, lo in (
            ("view_resolution", MIN_VIEW_RESOLUTION),
            ("volume_resolution", MIN_VOLUME_RESOLUTION),
        ):
            v = _validate.integer(name, getattr(self, name), minimum=lo, maximum=MAX_RESOLUTION)
            object.__setattr__(self, name, v)
        _validate.choice("normalisation", self.normalisation, NORMALISATIONS)
        _validate.choice("volume_fill", self.volume_fill, ("surface", "solid"))
        for name, res in (
            ("view_lcn_window", self.view_resolution),
            ("volume_lcn_window", self.volume_resolution),
        ):
            w = getattr(self, name)
            if self.normalisation != "lcn":
                if w is not None:
                    raise InvalidArgumentError(
                        f"{name}: got {w} with normalisation {self.normalisation!r}, expected None"
                    )
                continue
            w = _lcn_window(res) if w is None else _validate.integer(name, w, minimum=1)
            if w % 2 == 0:
                raise InvalidArgumentError(f"{name}: got {w}, expected an odd number of pixels")
            object.__setattr__(self, name, w)

    @property
    def shapes(self) -> dict[str, tuple[int, ...]]:
        """Per-shape array shape of each representation."""
        return _input_shapes(self.representations, self.view_resolution, self.volume_resolution)

    def check_available(self) -> None:
        """Raise :class:`RgbdError` when a representation (or LCN) cannot be computed here."""
        have = available_representations()
        missing = [r for r in self.representations if r not in have]
        if missing:
            raise RgbdError(
                f"representations: {missing} cannot be computed by this installation (it "
                f"computes {list(have)}); choose among those"
            )
        if self.normalisation == "lcn" and _lcn() is None:
            raise RgbdError(
                "normalisation: 'lcn' needs rgbd_rs.shapes.views.local_contrast_normalize, "
                "which this installation lacks; use 'standardize'"
            )

    def to_dict(self) -> dict[str, Any]:
        """Plain values (what caches and checkpoints store)."""
        return {
            "representations": list(self.representations),
            "view_resolution": self.view_resolution,
            "volume_resolution": self.volume_resolution,
            "normalisation": self.normalisation,
            "volume_fill": self.volume_fill,
            "view_lcn_window": self.view_lcn_window,
            "volume_lcn_window": self.volume_lcn_window,
        }

    @classmethod
    def from_dict(cls, data: Mapping[str, Any]) -> InputSpec:
        """Inverse of :meth:`to_dict`; unknown keys raise naming them."""
        known = {f.name for f in dataclasses.fields(cls)}
        if not isinstance(data, Mapping) or set(data) - known:
            got = sorted(data) if isinstance(data, Mapping) else type(data).__name__
            raise InvalidArgumentError(f"spec: got {got}, expected keys among {sorted(known)}")
        args: dict[str, Any] = dict(data)
        if "representations" in args:
            reps = args["representations"]
            if isinstance(reps, str) or not isinstance(reps, (list, tuple)):
                raise InvalidArgumentError(
                    f"spec: representations {reps!r}, expected a list of representation names"
                )
            args["representations"] = tuple(reps)
        return cls(**args)


def _normalise_maps(maps: np.ndarray, how: str, window: int | None) -> npt.NDArray[np.float32]:
    """Each trailing 2-D map normalised on its own: LCN with ``window`` or standardised (zero
    mean, unit variance; a constant map gives zeros). Non-finite input pixels count as 0."""
    x = np.nan_to_num(np.asarray(maps, np.float32), nan=0.0, posinf=0.0, neginf=0.0)
    if how == "lcn":
        lcn = _lcn()
        assert lcn is not None and window is not None  # InputSpec.check_available
        y = np.asarray(lcn(x, window), np.float32)
    else:
        mean = x.mean(axis=(-2, -1), keepdims=True)
        sd = x.std(axis=(-2, -1), keepdims=True)
        y = np.where(sd > 0, (x - mean) / np.where(sd > 0, sd, 1), 0).astype(np.float32)
    y = np.nan_to_num(y, nan=0.0, posinf=0.0, neginf=0.0)
    return np.clip(y, -_F16_MAX, _F16_MAX)


def _shape_arg(name: str, shape: object, *, centre: bool = True) -> Shape:
    """A validated shape. With ``centre`` (for inputs, which do not depend on where the shape
    is) a cloud far from the origin comes back moved there, in float64 before float32 blurs
    it."""
    if isinstance(shape, Mesh):
        check_mesh(name, shape)
        return shape
    return _points(name, shape, centre=centre)


def shape_inputs(shape: Mesh | npt.ArrayLike, spec: InputSpec | None = None) -> dict[str, Any]:
    """The network inputs of one shape: ``{representation: float32 array}`` of the shapes in
    ``spec.shapes`` (depth ``6 x R x R``, volume ``3 x Rv x Rv``, curvature ``6 x 2 x R x R``),
    each map normalised. ``shape``: a Mesh or an ``N x 3`` point cloud, z up (turn another
    up axis with :func:`~rgbd_rs.shapes.classify.to_z_up` first)."""
    s = InputSpec() if spec is None else spec
    if not isinstance(s, InputSpec):
        raise InvalidArgumentError(f"spec: got {type(s).__name__}, expected an InputSpec")
    s.check_available()
    x = _shape_arg("shape", shape)
    return _inputs(x, s)


def _inputs(x: Shape, s: InputSpec) -> dict[str, Any]:
    from rgbd_rs.shapes.voxels import density_profiles, voxelize

    out: dict[str, Any] = {}
    for name, want in s.shapes.items():
        window = s.view_lcn_window
        if name == "depth":  # empty pixels read the far face (1), as a cleared z-buffer
            fn = _depth_views()
            assert fn is not None
            maps = fn(x, s.view_resolution, lcn=False)
        elif name == "volume":
            fill = s.volume_fill if isinstance(x, Mesh) else "surface"
            maps = density_profiles(voxelize(x, s.volume_resolution, fill=fill))
            window = s.volume_lcn_window
        else:
            fn = _curvature_maps()
            assert fn is not None
            maps = fn(x, s.view_resolution)
        maps = np.asarray(maps)
        if maps.shape != want:
            raise ShapeMismatchError(
                f"{name} representation: got shape {maps.shape}, expected {want}"
            )
        out[name] = _normalise_maps(maps, s.normalisation, window)
    return out


def _workers(workers: int | None) -> int:
    if workers is None:
        return max(1, os.cpu_count() or 1)
    return _validate.integer("workers", workers, minimum=1, maximum=1024)


def batch_inputs(
    shapes: Sequence[Mesh | npt.ArrayLike],
    spec: InputSpec | None = None,
    *,
    workers: int | None = None,
) -> dict[str, Any]:
    """:func:`shape_inputs` of many shapes in ``workers`` threads (default: the CPU count):
    ``{representation: N x ... float32}``. The first bad shape raises, naming its index."""
    s = InputSpec() if spec is None else spec
    if not isinstance(s, InputSpec):
        raise InvalidArgumentError(f"spec: got {type(s).__name__}, expected an InputSpec")
    if isinstance(shapes, (Mesh, np.ndarray)) or not isinstance(shapes, Sequence):
        raise InvalidArgumentError(
            f"shapes: got {type(shapes).__name__}, expected a list of meshes or point clouds"
        )
    s.check_available()
    checked = [_shape_arg(f"shapes[{i}]", x) for i, x in enumerate(shapes)]
    w = _workers(workers)
    out = {name: np.empty((len(checked), *want), np.float32) for name, want in s.shapes.items()}
    for i, item in _parallel(checked, lambda x: _inputs(x, s), w):
        for name in out:
            out[name][i] = item[name]
    return out


def _parallel(
    items: Sequence[Any], fn: Callable[[Any], Any], workers: int
) -> Iterator[tuple[int, Any]]:
    """``(i, fn(items[i]))`` in order; exceptions re-raised naming the index."""

    def run(i: int) -> Any:
        try:
            return fn(items[i])
        except RgbdError as exc:
            raise type(exc)(f"shapes[{i}]: {exc}") from None

    if workers == 1 or len(items) <= 1:
        for i in range(len(items)):
            yield i, run(i)
        return
    with concurrent.futures.ThreadPoolExecutor(workers) as pool:
        yield from enumerate(pool.map(run, range(len(items))))


# -- the cache --------------------------------------------------------------------------------


def _shard(shard: object) -> tuple[int, int]:
    return _validate.shard("shard", shard)


def build_cache(
    source: ShapeSource | str | os.PathLike[str],
    out: str | os.PathLike[str],
    *,
    spec: InputSpec | None = None,
    shard: tuple[int, int] = (0, 1),
    workers: int | None = None,
    chunk: int = 32,
    quiet: bool = False,
) -> ShapeCache:
    """Compute the inputs of every shape of ``source`` (or of shard ``i`` of ``n``) into the cache
    folder ``out`` (layout in the module docstring), skipping shapes already done; returns the
    opened cache. An existing cache made with another source or spec raises :class:`RgbdError`.
    A shape whose inputs cannot be computed is marked failed (warning naming it) and skipped by
    the datasets. Progress bar on stderr unless ``quiet``."""
    from tqdm import tqdm

    quiet = _validate.flag("quiet", quiet)
    out = _validate.out_folder("out", out)

    if not isinstance(source, (ShapeSource, str, os.PathLike)):
        raise InvalidArgumentError(
            f"source: got {type(source).__name__}, expected a ShapeSource, a dataset name "
            "(modelnet10, modelnet40) or a path"
        )
    src = source if isinstance(source, ShapeSource) else open_shapes(source)
    s = InputSpec() if spec is None else spec
    if not isinstance(s, InputSpec):
        raise InvalidArgumentError(f"spec: got {type(s).__name__}, expected an InputSpec")
    i_shard, n_shard = _shard(shard)
    w = _workers(workers)
    chunk = _validate.integer("chunk", chunk, minimum=1, maximum=1_000_000)
    if not isinstance(out, (str, os.PathLike)) or not str(out):
        raise InvalidArgumentError(f"out: got {out!r}, expected a folder path")
    s.check_available()
    root = Path(out)
    root.mkdir(parents=True, exist_ok=True)
    n = len(src)
    base = getattr(src, "base", src)
    meta = {
        "format": CACHE_FORMAT,
        "kind": src.kind,
        "source": src.path.name,
        "classes": list(src.classes),
        "count": n,
        "spec": s.to_dict(),
        "dtype": "float16",
        "points_per_shape": int(base.points.shape[1]) if isinstance(base, PointCloudSet) else None,
    }
    # Scaled copies (rgbd_rs.shapes.scaling.ScaledCopies) are part of what the cache holds;
    # plain sources keep the meta.json of caches made before the option existed.
    augmentation = getattr(src, "augmentation", None)
    if augmentation is not None:
        meta["augmentation"] = augmentation
    meta["fingerprint"] = src._fingerprint()
    if (root / "meta.json").is_file():
        _check_meta(root, meta)
    _create_once(root / "labels.npy", _bytes_writer(_npy_bytes(src.labels.astype(np.int16))))
    _create_once(root / "splits.npy", _bytes_writer(_npy_bytes(src.splits)))
    _create_once(root / "names.json", _bytes_writer(json.dumps(list(src.names)).encode()))
    for name, shape in s.shapes.items():
        _create_once(root / f"{name}.npy", _npy_writer((n, *shape), np.float16))
        _reserve(root / f"{name}.npy")
    _create_once(root / "done.npy", _npy_writer((n,), np.uint8))
    _create_once(root / "meta.json", _bytes_writer(json.dumps(meta, indent=1).encode()))
    _check_meta(root, meta)
    arrays = {
        name: np.load(root / f"{name}.npy", mmap_mode="r+", allow_pickle=False) for name in s.shapes
    }
    done = np.load(root / "done.npy", mmap_mode="r+", allow_pickle=False)
    mine = np.arange(i_shard, n, n_shard)
    todo = mine[done[mine] == TODO]
    desc = f"cache {src.path.name}" + (f" {i_shard}/{n_shard}" if n_shard > 1 else "")
    bar = tqdm(
        total=len(mine),
        initial=len(mine) - len(todo),
        desc=desc,
        unit="shape",
        disable=quiet,
        dynamic_ncols=True,
    )
    with bar:
        for start in range(0, len(todo), chunk):
            idx = todo[start : start + chunk]
            results = _compute_chunk(src, idx, s, w)
            failed: list[int] = []
            for k, res in zip(idx, results, strict=True):
                if isinstance(res, str):
                    failed.append(int(k))
                    warnings.warn(
                        f"shape {k} ({src.names[k]}): {res}; marked failed, skipped",
                        stacklevel=2,
                    )
                    continue
                for name, arr in arrays.items():
                    arr[k] = res[name]
            for arr in arrays.values():
                arr.flush()
            ok = np.asarray([k for k in idx if k not in failed], np.int64)
            done[ok] = DONE
            done[np.asarray(failed, np.int64)] = FAILED
            done.flush()
            bar.update(len(idx))
    del arrays, done
    return ShapeCache(root)


def _check_meta(root: Path, meta: dict[str, Any]) -> None:
    cache = ShapeCache(root)
    if "fingerprint" not in cache.meta:  # a cache made before sources were fingerprinted
        meta = {k: v for k, v in meta.items() if k != "fingerprint"}
    if cache.meta != meta or len(cache) != meta["count"]:
        keys = sorted(k for k in set(meta) | set(cache.meta) if meta.get(k) != cache.meta.get(k))
        differ = ", ".join(f"{k}: {cache.meta.get(k)!r} there, {meta.get(k)!r} now" for k in keys)
        why = (
            " (the source's shapes, names or labels differ: another file or folder of the same "
            "name?)"
            if keys == ["fingerprint"]
            else ""
        )
        raise RgbdError(
            f"{root}: a cache of other data or settings ({differ or 'its row count differs'})"
            f"{why}; repeat the first run's settings and data or choose another output folder"
        )


def _compute_chunk(
    src: ShapeSource, idx: npt.NDArray[np.int64], spec: InputSpec, workers: int
) -> list[dict[str, Any] | str]:
    """Inputs of shapes ``idx`` (loaded and computed in threads); a failure becomes its message."""

    def one(k: int) -> dict[str, Any] | str:
        try:
            return _inputs(_shape_arg("shape", src.load(int(k))), spec)
        except RgbdError as exc:
            return str(exc)

    return [r for _, r in _parallel(list(idx), one, workers)]


class ShapeCache:
    """An opened cache folder written by :func:`build_cache` (read-only memory maps)."""

    def __init__(self, path: str | os.PathLike[str]) -> None:
        if not isinstance(path, (str, os.PathLike)) or not str(path):
            raise InvalidArgumentError(f"path: got {path!r}, expected a shape-cache folder")
        self.path = Path(path)
        meta_path = self.path / "meta.json"
        if not meta_path.is_file():
            raise RgbdError(
                f"{self.path}: "
                + ("no such folder" if not self.path.exists() else "no meta.json")
                + ", expected a cache written by build_cache (`rgbd shapes cache`)"
            )
        try:
            meta = json.loads(meta_path.read_text())
        except (ValueError, UnicodeDecodeError) as exc:
            raise RgbdError(f"{meta_path}: not valid JSON ({reason(exc)})") from None
        if not isinstance(meta, dict) or meta.get("format") != CACHE_FORMAT:
            tag = meta.get("format") if isinstance(meta, dict) else None
            raise RgbdError(f"{meta_path}: format {tag!r}, expected {CACHE_FORMAT!r}")
        self.meta: dict[str, Any] = meta
        try:
            self.spec = InputSpec.from_dict(meta["spec"])
            self.classes = tuple(str(c) for c in meta["classes"])
            self.kind = str(meta["kind"])
            n = int(meta["count"])
        except (KeyError, TypeError, ValueError, RgbdError) as exc:
            raise RgbdError(f"{meta_path}: incomplete or invalid cache metadata ({exc})") from None
        self.labels, self.splits = _labels_and_splits(
            self.path,
            read_npy(self.path / "labels.npy"),
            read_npy(self.path / "splits.npy"),
            len(self.classes),
        )
        names = json.loads((self.path / "names.json").read_text())
        self.names = tuple(str(x) for x in names)
        if not (len(self.labels) == len(self.splits) == len(self.names) == n):
            raise RgbdError(f"{self.path}: labels, splits and names do not all hold {n} shapes")

    def __len__(self) -> int:
        return len(self.labels)

    @property
    def done(self) -> npt.NDArray[np.uint8]:
        """Per shape: 0 to do, 1 done, 2 failed (a fresh read of ``done.npy``)."""
        return read_npy(self.path / "done.npy")

    @property
    def complete(self) -> bool:
        """Every shape is done or failed."""
        return bool((self.done != TODO).all())

    def array(self, representation: str) -> np.ndarray:
        """``N x ...`` float16 read-only memory map of one representation."""
        rep = _validate.choice("representation", representation, self.spec.representations)
        file = self.path / f"{rep}.npy"
        try:
            arr = np.load(file, mmap_mode="r", allow_pickle=False)
        except (OSError, ValueError) as exc:
            raise RgbdError(f"{file}: unreadable cache array ({reason(exc)})") from None
        want = (len(self), *self.spec.shapes[rep])
        if arr.shape != want:
            raise RgbdError(f"{file}: shape {arr.shape}, expected {want}")
        return np.asarray(arr) if not isinstance(arr, np.ndarray) else arr

    def _rows(self, split: str) -> npt.NDArray[np.bool_]:
        """Which rows belong to ``split`` (``"train"``, ``"test"`` or ``"all"``)."""
        sp = _validate.choice("split", split, (*SPLITS, "all"))
        return np.ones(len(self), bool) if sp == "all" else self.splits == SPLITS[sp]

    def require_complete(self, split: str = "all") -> None:
        """Raise :class:`RgbdError` if any shape of ``split`` (``"train"``, ``"test"`` or
        ``"all"``) is still to compute; shapes that failed count as done."""
        rows = self._rows(split)
        todo = int((rows & (self.done == TODO)).sum())
        if todo:
            raise RgbdError(
                f"{self.path}: {todo} of the {int(rows.sum())} shapes of split {split!r} not "
                "computed yet (the cache build was interrupted, is still running or misses a "
                "shard), expected a complete cache: finish it with `rgbd shapes cache` and the "
                "same settings"
            )

    def indices(self, split: str = "train") -> npt.NDArray[np.int64]:
        """Done shapes of ``split`` (``"train"``, ``"test"`` or ``"all"``), in order."""
        return np.flatnonzero(self._rows(split) & (self.done == DONE)).astype(np.int64)

    def dataset(
        self,
        split: str = "train",
        representations: Iterable[str] | str | None = None,
        *,
        indices: npt.ArrayLike | None = None,
        partial: bool = False,
    ) -> CachedShapes:
        """A torch Dataset of ``split``'s done shapes (or of ``indices``) yielding
        ``(packed float32 inputs, int64 label)`` (:func:`rgbd_rs.nn.shapes.pack` layout) for the
        chosen ``representations`` (default: every cached one).

        A split with shapes still to compute (a build interrupted, still running, or missing a
        shard) raises :class:`RgbdError` saying how many, unless ``partial=True``: training or
        scoring on part of a dataset without a word would report a figure about other data.
        Shapes that failed (``done == 2``) are left out either way; the build reported them."""
        reps = (
            self.spec.representations
            if representations is None
            else _parse_representations(representations)
        )
        absent = [r for r in reps if r not in self.spec.representations]
        if absent:
            raise InvalidArgumentError(
                f"representations: got {absent} not in the cache {self.path} (it holds "
                f"{list(self.spec.representations)})"
            )
        partial = _validate.flag("partial", partial)
        if indices is None:
            idx = self.indices(split)
            if not partial:
                self.require_complete(split)
        else:
            idx = _validate.array("indices", indices, shape=(None,), dtype=np.int64)
            if idx.min() < 0 or idx.max() >= len(self):
                raise InvalidArgumentError(
                    f"indices: got values in [{idx.min()}, {idx.max()}], expected "
                    f"0..{len(self) - 1}"
                )
        if len(idx) == 0:
            if not self._rows(split).any():  # nothing to build: the data has no such shapes
                counts = ", ".join(f"{int(self._rows(s).sum())} {s}" for s in ("train", "test"))
                raise InvalidArgumentError(
                    f"split: got {split!r}, which has no shape in {self.path} ({counts}), "
                    "expected a split with shapes"
                )
            raise RgbdError(f"{self.path}: no computed shapes in split {split!r}; build the cache")
        return CachedShapes(self, reps, idx)


class CachedShapes(Dataset[tuple[torch.Tensor, torch.Tensor]]):
    """Items ``(inputs, label)`` of a :class:`ShapeCache` (see :meth:`ShapeCache.dataset`);
    the memory maps open lazily in each process (picklable for worker processes)."""

    def __init__(
        self, cache: ShapeCache, representations: tuple[str, ...], indices: np.ndarray
    ) -> None:
        self.cache_path = cache.path
        self.representations = representations
        self.shapes = {r: cache.spec.shapes[r] for r in representations}
        self.indices = np.asarray(indices, np.int64)
        self.labels = cache.labels[self.indices]
        self._cache = cache
        self._arrays: dict[str, np.ndarray] | None = None

    def __len__(self) -> int:
        return len(self.indices)

    def __getstate__(self) -> dict[str, Any]:
        state = self.__dict__.copy()
        state["_arrays"] = None
        return state

    def __getitem__(self, i: int) -> tuple[torch.Tensor, torch.Tensor]:
        if self._arrays is None:
            self._arrays = {r: self._cache.array(r) for r in self.representations}
        k = int(self.indices[i])
        parts = [np.asarray(self._arrays[r][k], np.float32).ravel() for r in self.representations]
        x = torch.from_numpy(np.concatenate(parts))
        return x, torch.tensor(int(self.labels[i]), dtype=torch.int64)
