"""What the sampled sensor models share: seeded white noise and the first-order low-pass.

All sensors are sampled at the control period ``h`` (their tick index is
:func:`drake_coop.control.timing.tick_of`). Their noise is a deterministic function of
``(seed, stream, tick)``, so a run is reproducible and a sensor read twice at the same tick
(e.g. by the controller and by a logger) returns the same value.
"""

from __future__ import annotations

import numpy as np

from drake_coop.control.timing import lowpass_alpha

__all__ = ["ENCODER_STREAM", "FORCE_SENSOR_STREAM", "white_noise", "lowpass_alpha"]

#: Noise streams: one per robot and sensor, so that equal seeds give independent noises.
ENCODER_STREAM = 0
FORCE_SENSOR_STREAM = 1


def white_noise(seed: int, robot: int, stream: int, k: int, std: float, size: int
                ) -> np.ndarray:
    """The samples of zero-mean Gaussian white noise of standard deviation ``std`` at tick ``k``.

    Drawn from a generator seeded with ``[seed, robot, stream, k]`` (NumPy's ``SeedSequence``
    mixes them), so the value depends on nothing else: reproducible, independent across
    ticks, robots and sensors.

    Parameters
    ----------
    seed : int
        The scenario's seed.
    robot : int
        The robot's index.
    stream : int
        The sensor's stream number.
    k : int
        The tick index.
    std : float
        The standard deviation (the signal's unit).
    size : int
        The number of samples.
    """
    if std == 0.0:
        return np.zeros(size)
    rng = np.random.default_rng([int(seed), int(robot), int(stream), int(k)])
    return std * rng.standard_normal(size)
