"""Reader for SYNTH3 in its published, pre-reprojected MATLAB layout (Agresti et al. 2017, as
used by the thesis §3.5; METHOD_NOTES §3)::

    ROOT/{train,test}/stereo_disparity_maps/<p>scene_<i>_disparity_stereo_dx.mat
                                                                                     disparity_stereo_dx
    ROOT/{train,test}/tof_disparity_reprojected/<p>scene_<i>_MHz120_disparity_reprojected.mat
                                                                                     disparity_120_PU_rp
    ROOT/{train,test}/amplitude_reprojected/<p>scene_<i>_MHz120_amplitude_reprojected.mat
                                                                                     amplitude_120_rp
    ROOT/{train,test}/disparity_ground_truth_halfResolution/<p>scene_<i>_disparity_stereo_dx_GT.mat
                                                                                     disparity_GT

``<p>`` is empty for train and ``test_`` for test; ``<i>`` is the scene number as MATLAB's
``num2str(i, '%05.4u')`` prints it (zero-padded; leading spaces are tolerated). All maps are on
the right camera at 960x540; 0 marks invalid pixels and is returned as NaN.
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import numpy.typing as npt

from rgbd_rs import _validate
from rgbd_rs._array_eq import array_eq
from rgbd_rs.errors import InvalidArgumentError, RgbdError

from .._reasons import reason

F32 = npt.NDArray[np.float32]

#: (folder, file suffix after ``scene_<i>_``, MATLAB variable) of each map.
LAYOUT = {
    "stereo": ("stereo_disparity_maps", "disparity_stereo_dx.mat", "disparity_stereo_dx"),
    "tof": ("tof_disparity_reprojected", "MHz120_disparity_reprojected.mat", "disparity_120_PU_rp"),
    "amplitude": ("amplitude_reprojected", "MHz120_amplitude_reprojected.mat", "amplitude_120_rp"),
    "gt": ("disparity_ground_truth_halfResolution", "disparity_stereo_dx_GT.mat", "disparity_GT"),
}


@array_eq
@dataclass(frozen=True)
class Synth3Sample:
    """One SYNTH3 scene on the right camera: stereo and ToF disparity, ToF amplitude, GT."""

    stereo_disparity: F32
    tof_disparity: F32
    tof_amplitude: F32
    gt_disparity: F32


def _load_mat(path: Path, variable: str) -> F32:
    from scipy.io import loadmat

    try:
        data = loadmat(path, variable_names=[variable])
    except Exception as exc:  # scipy raises ValueError/TypeError/OSError for broken files
        raise RgbdError(f"{path}: corrupt or truncated MATLAB file ({reason(exc)})") from exc
    if variable not in data:
        raise RgbdError(f"{path}: has no variable {variable!r}")
    raw = np.asarray(data[variable])
    if raw.dtype.kind not in "biuf":
        raise RgbdError(f"{path}: {variable} holds {raw.dtype} data, expected a numeric map")
    arr = raw.astype(np.float32)
    if arr.ndim != 2:
        raise RgbdError(f"{path}: {variable} has shape {arr.shape}, expected a 2-D map")
    return np.where(arr > 0, arr, np.float32(np.nan)).astype(np.float32)


class Synth3Dataset:
    """The scenes of one split of a SYNTH3 folder, indexed by scene number order."""

    def __init__(self, root: str | Path, split: str = "train") -> None:
        if not isinstance(root, (str, Path)) or not str(root):
            raise InvalidArgumentError(f"root: got {root!r}, expected the SYNTH3 folder path")
        self.root = Path(root)
        self.split = _validate.choice("split", split, ("train", "test"))
        prefix = "test_scene_" if split == "test" else "scene_"
        folder, suffix, _ = LAYOUT["stereo"]
        base = self.root / split / folder
        if not base.is_dir():
            raise RgbdError(
                f"{base}: not found; expected the SYNTH3 layout (see rgbd_rs.data.synth3)"
            )
        pattern = re.compile(rf"^{prefix}\s*(\d+)_{re.escape(suffix)}$")
        found = {}
        for p in base.iterdir():
            m = pattern.match(p.name)
            if m:
                found[int(m.group(1))] = p.name[len(prefix) : -len(suffix) - 1]
        if not found:
            raise RgbdError(f"{base}: no {prefix}<i>_{suffix} files")
        self.indices = sorted(found)
        self._tags = found

    def __len__(self) -> int:
        return len(self.indices)

    def path(self, i: int, kind: str) -> Path:
        """File of map ``kind`` (stereo / tof / amplitude / gt) of the ``i``-th scene."""
        folder, suffix, _ = LAYOUT[_validate.choice("kind", kind, tuple(LAYOUT))]
        i = _validate.integer("i", i, maximum=len(self) - 1)
        prefix = "test_scene_" if self.split == "test" else "scene_"
        tag = self._tags[self.indices[i]]
        return self.root / self.split / folder / f"{prefix}{tag}_{suffix}"

    def __getitem__(self, i: int) -> Synth3Sample:
        i = _validate.integer("i", i, maximum=len(self) - 1)
        maps = {}
        for kind, (_, _, var) in LAYOUT.items():
            p = self.path(i, kind)
            if not p.is_file():
                raise RgbdError(f"{p}: file not found (scene {self.indices[i]} is incomplete)")
            maps[kind] = _load_mat(p, var)
        shapes = {k: v.shape for k, v in maps.items()}
        if len(set(shapes.values())) != 1:
            raise RgbdError(f"scene {self.indices[i]} of {self.root}: map sizes differ {shapes}")
        return Synth3Sample(maps["stereo"], maps["tof"], maps["amplitude"], maps["gt"])
