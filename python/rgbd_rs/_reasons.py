"""Why a file could not be read, in our words.

Loaders catch what numpy, torch, zipfile, json, h5py or OpenCV raise for a bad file and quote
:func:`reason` of it inside their own :class:`~rgbd_rs.errors.RgbdError`: the user learns what
is wrong with the file (it holds Python objects, it is not a zip archive, it ends early), not
which keyword of which library refused it.
"""

from __future__ import annotations

import json
import pickle
import zipfile

_OBJECTS = "it holds Python objects, not plain numeric arrays"

#: (text a library's message contains, lower case) -> what we say instead; first match wins.
_BY_TEXT: tuple[tuple[str, str], ...] = (
    ("allow_pickle", _OBJECTS),
    ("pickled", _OBJECTS),
    ("unsupported global", "it holds Python objects that are unsafe to load"),
    ("weights only load failed", "it is not a torch checkpoint"),
    ("pytorchstreamreader", "it is not a torch checkpoint"),
    ("inline_container", "it is not a torch checkpoint"),
    ("invalid load key", "it is not a torch checkpoint"),
    ("eof: reading array header", "it ends inside an array header: truncated?"),
    ("reading array data", "it ends inside an array's data: truncated?"),
    ("cannot reshape", "it holds fewer values than its header declares: truncated?"),
    ("file signature not found", "it is not an HDF5 file"),
    ("truncated file", "it ends early: truncated?"),
    ("unable to open file", "it cannot be opened as HDF5: corrupt or another format"),
    ("unexpected length", "its data is shorter or longer than its header declares: truncated?"),
    ("out of bounds for axis", "a face refers to a vertex the file does not hold"),
)


def reason(exc: BaseException) -> str:
    """One short clause saying why a file could not be read, from the exception a library raised.

    >>> reason(ValueError("Object arrays cannot be loaded when allow_pickle=False"))
    'it holds Python objects, not plain numeric arrays'
    >>> reason(KeyError("depth is not a file in the archive"))
    "it has no 'depth'"
    """
    if isinstance(exc, KeyError):
        if not exc.args:
            return "a key is missing"
        key = str(exc.args[0]).split(" is not a file in the archive")[0]  # numpy's npz wording
        return f"it has no {key!r}"
    if isinstance(exc, IsADirectoryError):
        return "it is a folder, not a file"
    if isinstance(exc, FileNotFoundError):
        return "no such file"
    if isinstance(exc, PermissionError):
        return "permission denied"
    if isinstance(exc, zipfile.BadZipFile):
        return "it is not a zip archive: corrupt or another format"
    if isinstance(exc, EOFError):
        return "it ends early: truncated or empty?"
    if isinstance(exc, json.JSONDecodeError):
        return f"not valid JSON at line {exc.lineno}, column {exc.colno}: {exc.msg.lower()}"
    if isinstance(exc, UnicodeDecodeError):
        return "it is not UTF-8 text (a binary file?)"
    if isinstance(exc, RecursionError):
        return "it is nested too deeply"
    text = str(exc).strip()
    low = text.lower()
    for needle, said in _BY_TEXT:
        if needle in low:
            return said
    if isinstance(exc, pickle.UnpicklingError):
        return "it is not a torch checkpoint"
    if isinstance(exc, OSError) and exc.strerror:
        return str(exc.strerror).lower()
    if isinstance(exc, AttributeError):
        return "it is not the archive expected"
    if not text:
        return type(exc).__name__
    return text.splitlines()[0][:200]
