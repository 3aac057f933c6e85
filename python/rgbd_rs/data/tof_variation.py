"""Per-scene randomisation of the ToF simulator, so a network trained on our data does not learn
one simulated sensor's quirks (issue: "randomise the simulator when training").

Each scene of a ``--vary-tof`` dataset draws its own sensor: modulation frequency, emitter power
(SNR), read and shot noise, the number of multipath rays (0 = none), mixed-pixel sub-sampling, an
amplitude unit (the amplitude is multiplied by a factor spanning five orders of magnitude, as a
sensor reporting in other units would) and a fraction of flying pixels (isolated samples pulled
towards the camera, as edge artefacts and dust are on real sensors). The ranges are chosen to
bracket the default model, not fitted to a sensor.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from rgbd_rs.render import ToFModel

#: Ranges of the draws (uniform unless noted; "log" = log-uniform).
FREQUENCY_HZ = (20e6, 120e6)
POWER_LOG10 = (np.log10(5e3), np.log10(8e4))
NOISE_FACTOR_LOG10 = (-0.5, 0.7)
MULTIPATH_RAYS = (0, 4, 8, 16)
SUBSAMPLES = (1, 2, 3)
AMPLITUDE_UNIT_LOG10 = (-2.5, 2.5)
FLYING_FRACTION = (0.0, 0.005)
#: Flying pixels land at this fraction of their true depth (uniform).
FLYING_DEPTH = (0.1, 0.6)


@dataclass(frozen=True)
class ToFVariation:
    """One scene's sensor: the simulator model plus what is applied after simulation."""

    model: ToFModel
    amplitude_unit: float
    flying_fraction: float


def random_variation(rng: np.random.Generator) -> ToFVariation:
    """Draw one scene's sensor from ``rng``."""
    base = ToFModel()
    noise = 10 ** rng.uniform(*NOISE_FACTOR_LOG10)
    model = ToFModel(
        frequency_hz=float(rng.uniform(*FREQUENCY_HZ)),
        subsamples=int(rng.choice(SUBSAMPLES)),
        multipath_rays=int(rng.choice(MULTIPATH_RAYS)),
        noise=True,
        power=float(10 ** rng.uniform(*POWER_LOG10)),
        read_noise=float(base.read_noise * noise),
        shot_noise=float(base.shot_noise * noise),
        ambient=base.ambient,
        amplitude_threshold=base.amplitude_threshold,
        wrap_phase=False,
    )
    return ToFVariation(
        model=model,
        amplitude_unit=float(10 ** rng.uniform(*AMPLITUDE_UNIT_LOG10)),
        flying_fraction=float(rng.uniform(*FLYING_FRACTION)),
    )


def apply(
    depth: npt.NDArray[np.float32],
    amplitude: npt.NDArray[np.float32],
    variation: ToFVariation,
    rng: np.random.Generator,
) -> tuple[npt.NDArray[np.float32], npt.NDArray[np.float32]]:
    """The frame as the varied sensor reports it: amplitude in its unit, flying pixels added."""
    d = depth.copy()
    valid = np.flatnonzero(np.isfinite(d) & (d > 0))
    n = round(variation.flying_fraction * valid.size)
    if n:
        idx = rng.choice(valid, n, replace=False)
        d.flat[idx] *= rng.uniform(*FLYING_DEPTH, n).astype(np.float32)
    return d, (amplitude * np.float32(variation.amplitude_unit)).astype(np.float32)
