r"""Joint-position encoders of one robot: quantization, white noise, a delay of whole samples.

The reading of tick ``k`` is

.. math::
    q_m(k) = r(k - d), \qquad
    r(j) = \delta \,\mathrm{round}\big((q(t_j) + w_j)/\delta\big), \qquad
    \delta = 2\pi / c

(``c`` counts per joint revolution; without ``c`` no rounding: ``r(j) = q(t_j) + w_j``),
``w_j`` seeded white Gaussian noise (:func:`~drake_coop.sensing.sampling.white_noise`) and
``d`` the delay in samples. Before the first ``d`` ticks the reading is the initial
``r(0)`` without noise (the encoders were read at rest before the run).

Timing (sample and hold, as the controller (13)): at a tick ``k`` that has not been latched
yet the output is computed from the current input, so with ``d = 0`` it is ``q(t_k)`` of the
same instant (an ideal encoder gives exactly the plant's ``q``); the periodic update latches
``r(k)`` and the output holds ``r(k − d)`` until the next tick.
"""

from __future__ import annotations

import math

import numpy as np
from pydrake.systems.framework import BasicVector, Context, DiscreteValues, LeafSystem

from drake_coop.scenario.schema import Encoders as EncoderSettings
from drake_coop.control.timing import tick_of
from drake_coop.sensing.sampling import ENCODER_STREAM, white_noise


def quantize(q: np.ndarray, counts_per_rev: int | None) -> np.ndarray:
    """``δ round(q/δ)`` with ``δ = 2π/counts_per_rev`` (``q`` unchanged when None).

    Parameters
    ----------
    q : numpy.ndarray
        Joint positions, rad.
    counts_per_rev : int or None
        Encoder counts per joint revolution; None for no quantization.

    Returns
    -------
    numpy.ndarray
        The quantized positions, rad.
    """
    if counts_per_rev is None:
        return np.asarray(q, dtype=float)
    delta = 2.0 * math.pi / counts_per_rev
    return delta * np.round(np.asarray(q, dtype=float) / delta)


class Encoders(LeafSystem):
    """The encoders of one arm (``robotN_encoders``).

    State ``[k, r(k−d), …, r(k)]``: the last latched tick and the readings of the last
    ``d + 1`` ticks.

    Parameters
    ----------
    n : int
        Number of joints.
    period : float
        Sampling time ``h`` (s).
    settings : drake_coop.scenario.Encoders
        Resolution, noise, delay and seed.
    robot_index : int
        Index of the robot (noise stream).

    Input ports
    -----------
    state : 2n-vector
        The arm's ``[q, q̇]`` from the plant (only ``q`` is read).

    Output ports
    ------------
    q : n-vector
        The reading ``q_m(k)``.
    """

    def __init__(self, n: int, period: float, settings: EncoderSettings | None = None,
                 robot_index: int = 0):
        super().__init__()
        s = settings or EncoderSettings()
        self._n = n
        self._h = period
        self._counts = s.counts_per_rev
        self._std = float(s.noise_std)
        self._d = int(s.delay_samples)
        self._seed = int(s.seed)
        self._robot = int(robot_index)
        self._input = self.DeclareVectorInputPort("state", 2 * n)
        self._state = self.DeclareDiscreteState(np.concatenate([[-1.0],
                                                                np.zeros((self._d + 1) * n)]))
        self.DeclarePeriodicDiscreteUpdateEvent(period, 0.0, self._update_readings)
        self.DeclareVectorOutputPort("q", n, self._calc_q)

    @property
    def delay_samples(self) -> int:
        """The delay ``d`` of the readings, in ticks."""
        return self._d

    def reading(self, q: np.ndarray, k: int) -> np.ndarray:
        """``r(k)`` for the true position ``q`` at tick ``k``.

        Parameters
        ----------
        q : numpy.ndarray
            The true joint positions (n,), rad.
        k : int
            The tick index (seeds the noise).

        Returns
        -------
        numpy.ndarray
            The reading (n,), rad.
        """
        noise = white_noise(self._seed, self._robot, ENCODER_STREAM, k, self._std, self._n)
        return quantize(np.asarray(q, dtype=float) + noise, self._counts)

    def initial_reading(self, q0: np.ndarray) -> np.ndarray:
        """The noiseless reading of the posture at rest ``q0`` (``q0`` itself when ideal).

        Parameters
        ----------
        q0 : numpy.ndarray
            The posture at rest (n,), rad.

        Returns
        -------
        numpy.ndarray
            The reading (n,), rad.
        """
        return quantize(q0, self._counts)

    def set_initial_state(self, context: Context, q0: np.ndarray) -> None:
        """Fill the delay line with :meth:`initial_reading` of the initial posture ``q0``.

        Parameters
        ----------
        context : Context
            This system's context.
        q0 : numpy.ndarray
            The initial posture (n,), rad.
        """
        r0 = self.initial_reading(q0)
        context.SetDiscreteState(self._state, np.concatenate([[-1.0], np.tile(r0, self._d + 1)]))

    def _buffer(self, context: Context) -> tuple[int, np.ndarray]:
        x = context.get_discrete_state(self._state).value()
        return int(x[0]), x[1:].reshape(self._d + 1, self._n)

    def _calc_q(self, context: Context, output: BasicVector) -> None:
        latched, buffer = self._buffer(context)
        k = tick_of(context.get_time(), self._h)
        if k is not None and latched != k:       # tick k, not latched yet
            if self._d == 0:
                output.SetFromVector(self.reading(self._input.Eval(context)[: self._n], k))
            else:
                output.SetFromVector(buffer[1])  # r(k − d) once r(k) is appended
        else:
            output.SetFromVector(buffer[0])      # held r(k − d)

    def _update_readings(self, context: Context, discrete_state: DiscreteValues) -> None:
        k = tick_of(context.get_time(), self._h)
        _, buffer = self._buffer(context)
        r = self.reading(self._input.Eval(context)[: self._n], k)
        new = np.vstack([buffer[1:], r[None, :]])
        discrete_state.set_value(self._state, np.concatenate([[float(k)], new.ravel()]))
