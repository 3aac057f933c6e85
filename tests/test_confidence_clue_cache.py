"""The confidence ConvNet's per-scene clue caches (rgbd_rs.nn.confidence_data.prepare): a resumed
run reuses a scene's file only when it was made from the same data with the same matcher."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest

from rgbd_rs import RgbdError
from rgbd_rs.data.synth import generate, synth3_rig
from rgbd_rs.fusion.evaluate import Sample
from rgbd_rs.io import read_npz, write_npz
from rgbd_rs.nn.confidence_data import load_scenes, prepare

RIG = synth3_rig(0.125)


def test_resume_checks_what_a_cached_scene_was_made_from(tmp_path: Path) -> None:
    s = generate(0, "test", 0, RIG, meshes=[])[0]
    sample = Sample("s", s.left, s.right, s.tof_depth, s.tof_amplitude, RIG, s.gt_disparity)
    out = tmp_path / "clues"
    (path,) = prepare([sample], out, quiet=True)
    assert load_scenes([path])[0]["clues"].shape[0] == 4
    made = path.stat().st_mtime_ns
    assert prepare([sample], out, quiet=True) == [path] and path.stat().st_mtime_ns == made
    with pytest.raises(RgbdError, match=r"s\.npz: cached from other data or another matcher"):
        prepare([sample], out, quiet=True, matcher="census")
    other = dataclasses.replace(sample, tof_depth=sample.tof_depth * np.float32(1.01))
    with pytest.raises(RgbdError, match=r"scene 's', matcher 'opencv'"):
        prepare([other], out, quiet=True)
    # a file written before fingerprints were kept is reused as it is
    old = {k: v for k, v in read_npz(path).items() if k != "fingerprint"}
    write_npz(path, old)
    assert prepare([other], out, quiet=True) == [path]
