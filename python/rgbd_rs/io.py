"""File I/O on the ground floor (numpy and OpenCV only, no other rgbd_rs module): atomic,
byte-reproducible writes (temp file + rename; npz archives with fixed timestamps) and reads that
raise :class:`~rgbd_rs.RgbdError` naming the file when it is missing, empty, truncated, of the
wrong kind or lacks a key. :mod:`rgbd_rs.viz` and :mod:`rgbd_rs.data` both write through here."""

from __future__ import annotations

import hashlib
import io
import json
import zipfile
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import cv2
import numpy as np
import numpy.typing as npt

from rgbd_rs.errors import RgbdError

#: Timestamp stored in every npz member, so equal arrays give equal bytes.
_ZIP_TIME = (1980, 1, 1, 0, 0, 0)


def _atomic_bytes(path: Path, data: bytes) -> Path:
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(f".{path.name}.tmp")
    tmp.write_bytes(data)
    tmp.replace(path)
    return path


def write_npz(path: str | Path, arrays: Mapping[str, npt.ArrayLike]) -> Path:
    """Write a compressed ``.npz`` atomically; identical arrays give identical bytes."""
    buf = io.BytesIO()
    with zipfile.ZipFile(buf, "w", compression=zipfile.ZIP_DEFLATED) as zf:
        for key, value in arrays.items():
            member = io.BytesIO()
            np.lib.format.write_array(member, np.asarray(value), allow_pickle=False)
            info = zipfile.ZipInfo(f"{key}.npy", date_time=_ZIP_TIME)
            info.compress_type = zipfile.ZIP_DEFLATED
            zf.writestr(info, member.getvalue())
    return _atomic_bytes(Path(path), buf.getvalue())


def read_npz(path: str | Path, keys: Sequence[str]) -> dict[str, np.ndarray]:
    """Read ``keys`` from an npz; a missing, truncated or incomplete file raises RgbdError."""
    path = Path(path)
    if not path.is_file():
        raise RgbdError(f"{path}: file not found")
    try:
        # From memory: np.load leaks its file handle when the archive is corrupt.
        with np.load(io.BytesIO(path.read_bytes()), allow_pickle=False) as z:
            missing = [k for k in keys if k not in z.files]
            if missing:
                raise RgbdError(f"{path}: missing arrays {missing} (has {sorted(z.files)})")
            return {k: z[k] for k in keys}
    except (OSError, ValueError, zipfile.BadZipFile, EOFError) as exc:
        raise RgbdError(f"{path}: corrupt or truncated npz ({exc})") from exc


def write_png(path: str | Path, image: npt.ArrayLike, rgb: bool = True) -> Path:
    """Write an 8/16-bit image as PNG atomically (``rgb``: 3-channel input is RGB)."""
    img = np.asarray(image)
    if rgb and img.ndim == 3:
        img = img[:, :, ::-1]
    ok, buf = cv2.imencode(".png", np.ascontiguousarray(img))
    if not ok:
        raise RgbdError(f"{path}: could not encode the image as PNG")
    return _atomic_bytes(Path(path), buf.tobytes())


def read_png(path: str | Path, rgb: bool = True) -> np.ndarray:
    """Read a PNG unchanged (8/16 bit; 3 channels returned as RGB); bad files raise RgbdError."""
    path = Path(path)
    if not path.is_file():
        raise RgbdError(f"{path}: file not found")
    data = np.frombuffer(path.read_bytes(), np.uint8)
    img = cv2.imdecode(data, cv2.IMREAD_UNCHANGED) if data.size else None
    if img is None:
        raise RgbdError(f"{path}: corrupt or truncated image")
    if rgb and img.ndim == 3:
        img = np.ascontiguousarray(img[:, :, 2::-1])
    return np.asarray(img)


def write_json(path: str | Path, obj: Any) -> Path:
    """Write JSON (sorted keys, indented) atomically."""
    return _atomic_bytes(Path(path), (json.dumps(obj, indent=1, sort_keys=True) + "\n").encode())


def read_json(path: str | Path) -> Any:
    """Read JSON; a missing or malformed file raises RgbdError naming it."""
    path = Path(path)
    if not path.is_file():
        raise RgbdError(f"{path}: file not found")
    try:
        return json.loads(path.read_text())
    except (json.JSONDecodeError, UnicodeDecodeError) as exc:
        raise RgbdError(f"{path}: malformed JSON ({exc})") from exc


def sha256(path: str | Path) -> str:
    """Hex SHA-256 of a file's bytes."""
    return hashlib.sha256(Path(path).read_bytes()).hexdigest()
