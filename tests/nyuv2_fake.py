"""A small fabricated ``nyu_depth_v2_labeled.mat`` for tests/test_nyuv2_mat.py and
tests/test_bad_input_nyuv2_mat.py (not a test module itself): MATLAB v7.3 layout, i.e. HDF5 with
a 512-byte MATLAB header as user block, each array stored transposed as MATLAB's column-major
order makes h5py see it (``images`` N x 3 x W x H, the others N x W x H), gzip-chunked per frame
as MATLAB writes large arrays."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import h5py
import numpy as np

#: Frame size of the fabricated file (a tenth of the Kinect's 640x480).
H, W = 48, 64
N = 5
#: Raw classes used, with their hand-looked-up 40- and 13-class values (classMapping40.mat:
#: allClassName / mapClass; class13Mapping.mat: labels13):
#: 1 book -> 40 otherprop -> 7 objects, 3 cabinet -> 3 cabinet -> 6 furniture,
#: 4 ceiling -> 22 ceiling -> 3 ceiling, 5 chair -> 5 chair -> 4 chair,
#: 11 floor -> 2 floor -> 5 floor, 19 table -> 7 table -> 10 table.
RAW = (0, 1, 3, 4, 5, 11, 19)
TO40 = {0: 0, 1: 40, 3: 3, 4: 22, 5: 5, 11: 2, 19: 7}
TO13 = {0: 0, 1: 7, 3: 6, 4: 3, 5: 4, 11: 5, 19: 10}
#: The MATLAB v7.3 header that fills the HDF5 user block.
HEADER = (
    b"MATLAB 7.3 MAT-file, Platform: GLNXA64, Created on: Mon Nov 30 12:00:00 2026 "
    b"HDF5 schema 1.00 ."
)


@dataclass(frozen=True)
class Fake:
    """What was written, in rgbd_rs's layout (N x H x W [x 3])."""

    path: Path
    rgb: np.ndarray
    depth: np.ndarray
    raw_depth: np.ndarray
    labels: np.ndarray
    instances: np.ndarray


def arrays(seed: int = 0) -> tuple[np.ndarray, ...]:
    rng = np.random.default_rng(seed)
    rgb = rng.integers(0, 256, (N, H, W, 3), dtype=np.uint8)
    depth = rng.uniform(0.5, 5.0, (N, H, W)).astype(np.float32)
    raw = depth.copy()
    raw[:, 10:20, 30:40] = 0.0  # Kinect holes
    raw[:, 0, :] = 0.0
    labels = rng.choice(np.array(RAW, np.uint16), (N, H, W)).astype(np.uint16)
    instances = rng.integers(0, 4, (N, H, W), dtype=np.uint8)
    instances[labels == 0] = 0
    return rgb, depth, raw, labels, instances


def write(
    path: Path,
    *,
    skip: tuple[str, ...] = (),
    replace: dict[str, np.ndarray] | None = None,
    seed: int = 0,
) -> Fake:
    """Write the fabricated file; ``skip`` leaves datasets out, ``replace`` stores the given
    arrays as they are (already in the file's transposed layout)."""
    rgb, depth, raw, labels, instances = arrays(seed)
    stored = {
        "images": rgb.transpose(0, 3, 2, 1),  # N x 3 x W x H
        "depths": depth.transpose(0, 2, 1),
        "rawDepths": raw.transpose(0, 2, 1),
        "labels": labels.transpose(0, 2, 1),
        "instances": instances.transpose(0, 2, 1),
    }
    stored.update(replace or {})
    with h5py.File(path, "w", userblock_size=512) as f:
        for key, arr in stored.items():
            if key in skip:
                continue
            chunks = (1, *arr.shape[1:]) if arr.ndim >= 2 and arr.shape[0] else None
            ds = f.create_dataset(key, data=arr, chunks=chunks, compression="gzip")
            ds.attrs["MATLAB_class"] = np.bytes_(
                {"u1": "uint8", "u2": "uint16", "f4": "single"}.get(arr.dtype.str[1:], "double")
            )
    with open(path, "r+b") as fh:
        fh.write(HEADER.ljust(116) + bytes(8) + b"\x00\x02IM")
    return Fake(path, rgb, depth, raw, labels, instances)
