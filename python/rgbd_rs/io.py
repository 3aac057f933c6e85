"""File I/O on the ground floor (numpy and OpenCV only, no other rgbd_rs module): atomic,
byte-reproducible writes (temp file + rename; npz archives with fixed timestamps) and reads that
raise :class:`~rgbd_rs.RgbdError` naming the file when it is missing, empty, truncated, of the
wrong kind or lacks a key. :mod:`rgbd_rs.viz` and :mod:`rgbd_rs.data` both write through here."""

from __future__ import annotations

import contextlib
import errno
import hashlib
import io
import json
import math
import os
import shutil
import stat
import sys
import tempfile
import threading
import zipfile
import zlib
from collections.abc import Callable, Iterator, Mapping, Sequence
from pathlib import Path
from typing import Any

import cv2
import numpy as np
import numpy.typing as npt

from rgbd_rs import _rgbd_rs, _validate
from rgbd_rs.errors import InvalidArgumentError, RgbdError, ShapeMismatchError

from ._reasons import reason

__all__ = [
    "read_json",
    "read_npy",
    "read_npz",
    "read_png",
    "sha256",
    "write_json",
    "write_npz",
    "write_png",
    "write_text",
]

#: Timestamp stored in every npz member, so equal arrays give equal bytes.
_ZIP_TIME = (1980, 1, 1, 0, 0, 0)
#: PNG sample types and channel counts OpenCV writes.
_PNG_DTYPES = (np.uint8, np.uint16)
_PNG_CHANNELS = (1, 3, 4)


def _path(value: object, name: str = "path") -> Path:
    if isinstance(value, (str, os.PathLike)) and str(value):
        return _validate.path(name, value)  # refuses NUL characters, and bytes paths
    raise InvalidArgumentError(f"{name}: got {value!r}, expected a file path (str or Path)")


def _special(path: Path) -> str | None:
    """What ``path`` is when it exists but is neither a regular file nor a folder (a device, a
    FIFO, a socket), else None."""
    try:
        mode = path.stat().st_mode
    except OSError:
        return None
    if stat.S_ISREG(mode) or stat.S_ISDIR(mode):
        return None
    if stat.S_ISCHR(mode) or stat.S_ISBLK(mode):
        return "a device"
    return "a pipe" if stat.S_ISFIFO(mode) else "a socket" if stat.S_ISSOCK(mode) else "special"


def _file_bytes(path: Path) -> bytes:
    """The file's bytes; a missing, special or unreadable file raises RgbdError naming it."""
    if path.is_dir():
        raise RgbdError(f"{path}: is a folder, expected a file")
    kind = _special(path)
    if kind is not None:
        raise RgbdError(f"{path}: is {kind}, expected a regular file")
    if not path.is_file():
        raise RgbdError(f"{path}: file not found")
    try:
        return path.read_bytes()
    except OSError as exc:
        raise RgbdError(f"{path}: could not be read ({reason(exc)})") from exc


def _read_bytes(path: Path) -> bytes:
    """:func:`_file_bytes`, and an empty file refused too."""
    data = _file_bytes(path)
    if not data:
        raise RgbdError(f"{path}: empty file")
    return data


def _file_above(path: Path) -> Path | None:
    """The nearest existing folder-to-be above ``path`` when it is not a folder (a file where
    ``path`` needs a parent folder), else None."""
    for parent in path.parents:
        if parent.exists():
            return None if parent.is_dir() else parent
    return None


def _atomic_bytes(path: Path, data: bytes) -> Path:
    """Write ``data`` through a temporary file beside ``path`` renamed over it; a folder, a
    device or another special file at ``path`` is refused (the rename would replace it)."""
    if path.is_dir():
        raise RgbdError(f"{path}: is a folder, expected a file path to write")
    kind = _special(path)
    if kind is not None:
        raise RgbdError(f"{path}: is {kind}, expected a regular file path to write")
    blocker = _file_above(path)
    if blocker is not None:
        raise RgbdError(
            f"{path}: could not be written ({blocker} is a file, expected a folder to write in)"
        )
    tmp = path.with_name(f".{path.name}.tmp")
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        tmp.write_bytes(data)
        tmp.replace(path)
    except OSError as exc:
        with contextlib.suppress(OSError):
            tmp.unlink(missing_ok=True)
        raise RgbdError(f"{path}: could not be written ({reason(exc)})") from exc
    return path


def write_text(path: str | Path, text: str) -> Path:
    """Write UTF-8 ``text`` to ``path`` atomically (creating parent folders)."""
    if not isinstance(text, str):
        raise InvalidArgumentError(f"text: got {type(text).__name__}, expected str")
    try:
        data = text.encode()
    except UnicodeEncodeError as exc:  # a lone surrogate has no UTF-8 form
        raise InvalidArgumentError(
            f"text: got a lone surrogate {text[exc.start]!r} at position {exc.start}, expected "
            "text UTF-8 can encode"
        ) from None
    return _atomic_bytes(_path(path), data)


def write_npz(path: str | Path, arrays: Mapping[str, npt.ArrayLike]) -> Path:
    """Write a compressed ``.npz`` atomically; identical arrays give identical bytes."""
    out = _path(path)
    if not isinstance(arrays, Mapping):
        raise InvalidArgumentError(
            f"arrays: got {type(arrays).__name__}, expected a mapping of names to arrays"
        )
    buf = io.BytesIO()
    with zipfile.ZipFile(buf, "w", compression=zipfile.ZIP_DEFLATED) as zf:
        for key, value in arrays.items():
            if not isinstance(key, str) or not key:
                raise InvalidArgumentError(f"arrays: got key {key!r}, expected non-empty names")
            arr = _validate.asarray(f"arrays[{key!r}]", value)
            if arr.dtype.kind not in "biuf":
                raise InvalidArgumentError(
                    f"arrays[{key!r}]: got dtype {arr.dtype}, expected a bool/int/float array"
                )
            member = io.BytesIO()
            np.lib.format.write_array(member, arr, allow_pickle=False)
            info = zipfile.ZipInfo(f"{key}.npy", date_time=_ZIP_TIME)
            info.compress_type = zipfile.ZIP_DEFLATED
            zf.writestr(info, member.getvalue())
    return _atomic_bytes(out, buf.getvalue())


def read_npz(path: str | Path, keys: Sequence[str] | None = None) -> dict[str, np.ndarray]:
    """Read ``keys`` (default: every array) from an npz; a missing, truncated or incomplete file
    raises RgbdError."""
    path = _path(path)
    if keys is not None and (
        isinstance(keys, str)
        or not isinstance(keys, Sequence)
        or not all(isinstance(k, str) for k in keys)
    ):
        raise InvalidArgumentError(f"keys: got {keys!r}, expected a sequence of array names")
    data = _read_bytes(path)
    if not data.startswith(b"PK"):
        what = "a single-array .npy" if data.startswith(NPY_MAGIC) else "not a zip archive"
        raise RgbdError(f"{path}: not a readable npz archive ({what})")
    try:
        # From memory: np.load leaks its file handle when the archive is corrupt.
        with np.load(io.BytesIO(data), allow_pickle=False) as z:
            wanted = z.files if keys is None else keys
            missing = [k for k in wanted if k not in z.files]
            if missing:
                raise RgbdError(f"{path}: missing arrays {missing} (has {sorted(z.files)})")
            return {k: z[k] for k in wanted}
    except (OSError, ValueError, zipfile.BadZipFile, EOFError, AttributeError) as exc:
        if isinstance(exc, RgbdError):
            raise
        # AttributeError: np.load returned a plain array (an .npy, not an archive).
        raise RgbdError(f"{path}: not a readable npz archive ({reason(exc)})") from exc


def _npy_shape(path: Path) -> tuple[int, ...] | None:
    """The shape a regular ``.npy`` file's header declares, read without its data; None when
    there is none to read (the full read says why)."""
    if not path.is_file():  # a FIFO or device would block or stream
        return None
    try:
        with path.open("rb") as f:
            version = np.lib.format.read_magic(f)
            if version == (1, 0):
                shape = np.lib.format.read_array_header_1_0(f)[0]
            elif version in ((2, 0), (3, 0)):  # 3.0: 2.0's layout, a UTF-8 header
                shape = np.lib.format.read_array_header_2_0(f)[0]
            else:
                return None
    except (OSError, ValueError, EOFError):
        return None
    return tuple(int(n) for n in shape)


def read_npy(path: str | Path) -> np.ndarray:
    """Read one array from an ``.npy`` file (no pickles); a missing, empty, truncated or
    non-``.npy`` file raises RgbdError naming it."""
    path = _path(path)
    size = path.stat().st_size if path.is_file() else 0
    if size > MAX_NPY_BYTES:
        raise RgbdError(f"{path}: a file of {size} bytes, expected at most {MAX_NPY_BYTES}")
    declared = _npy_shape(path)
    if declared is not None and math.prod(declared) > MAX_NPY_ELEMENTS:
        raise RgbdError(
            f"{path}: the .npy header says shape {declared} ({math.prod(declared)} elements), "
            f"expected at most {MAX_NPY_ELEMENTS} elements"
        )
    data = _read_bytes(path)
    if not data.startswith(NPY_MAGIC):
        what = "an npz archive" if data.startswith(b"PK") else "no .npy header"
        raise RgbdError(f"{path}: not a readable .npy array ({what})")
    try:
        arr = np.load(io.BytesIO(data), allow_pickle=False)
    except (OSError, ValueError, EOFError) as exc:
        raise RgbdError(f"{path}: not a readable .npy array ({reason(exc)})") from exc
    if not isinstance(arr, np.ndarray):
        arr.close()
        raise RgbdError(f"{path}: is an npz archive, expected a single-array .npy")
    return arr


def write_png(path: str | Path, image: npt.ArrayLike, rgb: bool = True) -> Path:
    """Write an 8/16-bit image as PNG atomically (``rgb``: 3-channel input is RGB).

    ``image`` is ``H x W`` or ``H x W x C`` (C = 1, 3 or 4) of uint8 or uint16.
    """
    out = _path(path)
    img = _validate.asarray("image", image)
    if not isinstance(rgb, (bool, np.bool_)):
        raise InvalidArgumentError(f"rgb: got {rgb!r}, expected True or False")
    if img.dtype not in _PNG_DTYPES:
        raise InvalidArgumentError(f"image: got dtype {img.dtype}, expected uint8 or uint16")
    if img.ndim not in (2, 3) or (img.ndim == 3 and img.shape[2] not in _PNG_CHANNELS):
        raise ShapeMismatchError(
            f"image: got shape {img.shape}, expected (H, W) or (H, W, C) with C in 1, 3, 4"
        )
    if img.size == 0:
        raise ShapeMismatchError(f"image: got shape {img.shape}, expected at least one pixel")
    if rgb and img.ndim == 3 and img.shape[2] >= 3:
        img = np.concatenate([img[:, :, 2::-1], img[:, :, 3:]], axis=2)
    ok, buf = cv2.imencode(".png", np.ascontiguousarray(img))
    if not ok:
        raise RgbdError(f"{out}: could not encode the image as PNG")
    return _atomic_bytes(out, buf.tobytes())


#: The most pixels :func:`read_png` decodes, checked from the file's header: the most any
#: function of the library takes (``MAX_PIXELS``, 2^28; OpenCV's own limit is 2^30, and a
#: 1.2 MB PNG of 20000 x 20000 pixels took 3.5 GB and 27 s to decode before it was refused).
MAX_PNG_PIXELS: int = _rgbd_rs.MAX_PIXELS
#: The most elements :func:`read_npy` reads, checked from the file's header (a 12 GB cloud of
#: 10^9 points was read whole before anything looked at it): the most any function of the
#: library takes (``MAX_ELEMENTS``, 2^31).
MAX_NPY_ELEMENTS: int = _rgbd_rs.MAX_ELEMENTS
#: The largest ``.npy`` file :func:`read_npy` reads, checked before reading it: MAX_NPY_ELEMENTS
#: float32 values and a header (whatever its header says: a structured dtype, a version 3.0
#: header or data beyond what it declares).
MAX_NPY_BYTES: int = 4 * MAX_NPY_ELEMENTS + (1 << 20)

#: An ``.npy`` file's first 6 bytes.
NPY_MAGIC = b"\x93NUMPY"

#: A PNG file's first 8 bytes.
PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"


def read_png(path: str | Path, rgb: bool = True) -> np.ndarray:
    """Read a PNG (8/16 bit, grey as H x W): with ``rgb``, colour comes back as RGB, a 4-channel
    file without its alpha; with ``rgb=False`` as OpenCV reads it (BGR, BGRA). Bad files raise
    RgbdError."""
    path = _path(path)
    if not isinstance(rgb, (bool, np.bool_)):
        raise InvalidArgumentError(f"rgb: got {rgb!r}, expected True or False")
    raw = _read_bytes(path)
    if raw.startswith(PNG_SIGNATURE):
        bad, raw = _checked_png_chunks(raw)  # a truncated file included (no end chunk)
        if bad:  # caught here: libpng would print its own error line before OpenCV fails
            raise RgbdError(f"{path}: corrupt or truncated image ({bad})")
    if raw.startswith(PNG_SIGNATURE) and len(raw) >= 24 and raw[12:16] == b"IHDR":
        # The header's size, checked before OpenCV allocates (or refuses) the pixels.
        width, height = int.from_bytes(raw[16:20], "big"), int.from_bytes(raw[20:24], "big")
        side = _validate.MAX_SIDE
        if not (0 < width <= side and 0 < height <= side) or width * height > MAX_PNG_PIXELS:
            raise RgbdError(
                f"{path}: the PNG header says {width}x{height} pixels, expected sides "
                f"1..{side} and at most {MAX_PNG_PIXELS} pixels"
            )
    with _decoder_messages() as said:
        try:
            img = cv2.imdecode(np.frombuffer(raw, np.uint8), cv2.IMREAD_UNCHANGED)
        except cv2.error:
            img = None
    why = _decoder_trouble(said())
    if img is None or why:
        raise RgbdError(f"{path}: corrupt or truncated image{f' ({why})' if why else ''}")
    if rgb and img.ndim == 3:
        img = np.ascontiguousarray(img[:, :, 2::-1])
    return np.asarray(img)


#: What libpng or OpenCV print about an image whose pixels cannot be trusted (the others, such
#: as an odd colour profile, are dropped: the pixels are fine).
_CORRUPT_MARKS = ("error", "IDAT", "image data", "CRC", "decompress", "zlib")
#: OpenCV's image-codec sources, which its own log lines name.
_DECODER_SOURCES = ("grfmt", "loadsave", "imgcodecs")
_stderr_lock = threading.Lock()


@contextlib.contextmanager
def _decoder_messages() -> Iterator[Callable[[], str]]:
    """Captures what the image decoder (libpng through OpenCV) prints on the process's stderr
    while the block runs, instead of letting it reach the user's terminal; yields a function
    returning the captured text. Holds a lock: one decode at a time captures."""
    with _stderr_lock, tempfile.TemporaryFile() as sink:
        sys.stderr.flush()
        saved = os.dup(2)
        text = ""
        try:
            os.dup2(sink.fileno(), 2)
            yield lambda: text
        finally:
            os.dup2(saved, 2)
            os.close(saved)
            sink.seek(0)
            text = sink.read().decode(errors="replace")


def _decoder_trouble(text: str) -> str:
    """The first line of the decoder's ``text`` that says the pixels are corrupt, else ``""``.
    Lines that are not the decoder's (another thread's, printed meanwhile) go on to stderr."""
    trouble, others = "", []
    for line in text.splitlines(keepends=True):
        if not line.startswith("libpng") and not any(m in line for m in _DECODER_SOURCES):
            others.append(line)
        elif not trouble and any(mark in line for mark in _CORRUPT_MARKS):
            trouble = line.strip().removeprefix("libpng error: ").removeprefix("libpng warning: ")
    if others:
        sys.stderr.write("".join(others))
    return trouble


def _checked_png_chunks(raw: bytes) -> tuple[str, bytes]:
    """What is wrong with the chunk structure of a PNG's bytes (a chunk running past the end of
    the file, or a critical chunk whose CRC does not match its bytes; ``""`` if nothing is) and
    the bytes to decode: an *ancillary* chunk (text, time, ...) whose CRC fails is left out, as
    libpng would skip it after printing a warning."""
    pos = len(PNG_SIGNATURE)
    kept = [raw[:pos]]
    while pos + 12 <= len(raw):
        length = int.from_bytes(raw[pos : pos + 4], "big")
        kind = raw[pos + 4 : pos + 8]
        name = kind.decode("latin-1")
        end = pos + 8 + length
        if end + 4 > len(raw):
            return f"chunk {name!r} runs past the end of the file", raw
        crc_ok = zlib.crc32(raw[pos + 4 : end]) == int.from_bytes(raw[end : end + 4], "big")
        critical = kind[:1].isupper()
        if not crc_ok and critical:
            return f"chunk {name!r} fails its CRC check", raw
        if crc_ok or critical:
            kept.append(raw[pos : end + 4])
        if kind == b"IEND":
            return "", b"".join(kept)
        pos = end + 4
    return "no PNG end chunk", raw


def write_json(path: str | Path, obj: Any) -> Path:
    """Write JSON (sorted keys, indented) atomically; NaN and infinities are refused (JSON has
    no such numbers)."""
    out = _path(path)
    try:
        text = json.dumps(obj, indent=1, sort_keys=True, allow_nan=False)
    except (TypeError, ValueError) as exc:
        raise InvalidArgumentError(f"obj: got a value JSON cannot hold ({exc})") from None
    return _atomic_bytes(out, (text + "\n").encode())


def read_json(path: str | Path) -> Any:
    """Read JSON; a missing or malformed file (NaN and Infinity included: JSON has no such
    numbers) raises RgbdError naming it."""
    path = _path(path)
    data = _read_bytes(path)
    try:
        return json.loads(data.decode(), parse_constant=_no_constant)
    except (json.JSONDecodeError, UnicodeDecodeError, RecursionError, ValueError) as exc:
        raise RgbdError(f"{path}: malformed JSON ({reason(exc)})") from exc


def _no_constant(name: str) -> Any:
    raise ValueError(f"{name} is not a JSON number")


def sha256(path: str | Path) -> str:
    """Hex SHA-256 of a file's bytes."""
    return hashlib.sha256(_file_bytes(_path(path))).hexdigest()


# -- create-once files (package-internal: shared by the resumable, sharded dataset jobs) --------


def _create_once(path: Path, write: Callable[[Path], None]) -> None:
    """Write ``path`` through ``write(tmp)`` unless it exists; concurrent callers (the shards of
    one job) race safely: a hard link cannot overwrite, so the first one wins."""
    if path.exists():
        return
    fd, name = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=".tmp")
    os.close(fd)
    tmp = Path(name)
    try:
        write(tmp)
        os.chmod(tmp, 0o644)
        with contextlib.suppress(FileExistsError):  # another shard made it first
            os.link(tmp, path)
    finally:
        tmp.unlink(missing_ok=True)


def _npy_writer(shape: tuple[int, ...], dtype: npt.DTypeLike) -> Callable[[Path], None]:
    """A :func:`_create_once` writer of a zero-filled ``.npy`` of ``shape`` (memory-mappable)."""

    def write(tmp: Path) -> None:
        arr = np.lib.format.open_memmap(tmp, mode="w+", dtype=dtype, shape=shape)
        arr.flush()
        del arr

    return write


#: posix_fallocate errors that mean "this filesystem cannot reserve", not "no room".
_NO_RESERVE = {errno.EOPNOTSUPP, errno.ENOSYS, errno.EINVAL}


def _reserve(path: Path) -> None:
    """Allocate the disk blocks of the (sparse) array file ``path`` now: a memory-mapped write
    to a block the full disk cannot give kills the process with SIGBUS, with no message; this
    raises :class:`RgbdError` up front instead (where the OS can reserve blocks). Called on the
    final file, once :func:`_create_once` made it: concurrent shards reserve it once, and again
    at no cost."""
    if not hasattr(os, "posix_fallocate"):
        return
    size = path.stat().st_size
    fd = os.open(path, os.O_RDWR)
    try:
        os.posix_fallocate(fd, 0, size)
    except OSError as exc:
        if exc.errno in _NO_RESERVE:
            return
        free = shutil.disk_usage(path.parent).free
        raise RgbdError(
            f"{path}: could not reserve {size / 1e6:.1f} MB on disk ({exc.strerror}; "
            f"{free / 1e6:.1f} MB free): free some room or choose another output folder"
        ) from None
    finally:
        os.close(fd)


def _bytes_writer(data: bytes) -> Callable[[Path], None]:
    """A :func:`_create_once` writer of ``data``."""

    def write(tmp: Path) -> None:
        tmp.write_bytes(data)

    return write


def _npy_bytes(arr: np.ndarray) -> bytes:
    """``arr`` as the bytes of a ``.npy`` file."""
    buf = io.BytesIO()
    np.lib.format.write_array(buf, arr, allow_pickle=False)
    return buf.getvalue()
