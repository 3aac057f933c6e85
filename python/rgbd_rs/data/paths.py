"""Where the shared real datasets live: ``$RGBD_DATA`` or ``../shared/data`` beside the repo."""

from __future__ import annotations

import os
from pathlib import Path

from rgbd_rs.errors import InvalidArgumentError


def data_root(required: bool = False) -> Path | None:
    """The dataset directory: ``$RGBD_DATA`` if set, else ``<repo>/../shared/data``.

    Returns None when it does not exist, or raises when ``required``. A ``$RGBD_DATA`` that is
    not a directory always raises (a typo must not fall back to other data).
    """
    if not isinstance(required, bool):
        raise InvalidArgumentError(f"required: got {required!r}, expected True or False")
    env = os.environ.get("RGBD_DATA")
    if env and not Path(env).is_dir():
        what = "a file" if Path(env).exists() else "no such directory"
        raise InvalidArgumentError(
            f"RGBD_DATA: got {env!r} ({what}), expected the directory of the shared datasets "
            "(or unset it to use ../shared/data beside the repository)"
        )
    candidates = [Path(env)] if env else []
    here = Path(__file__).resolve()
    candidates += [p / "shared" / "data" for p in here.parents[3:5]]
    for c in candidates:
        if c.is_dir():
            return c
    if required:
        raise InvalidArgumentError(
            f"RGBD_DATA: got {env!r} and no ../shared/data beside the repository, expected the "
            "directory of the shared datasets (set RGBD_DATA)"
        )
    return None
