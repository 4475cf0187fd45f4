"""The reference signal of one robot: its rows ``[q_d, q̇_d, q̈_d, λ_d, held]``
(:data:`REFERENCE_ROWS`), one sample of it (:class:`Reference`) and its layout in the vector
(:class:`ReferenceLayout`: the one owner of its size and of where each part sits). Built by
the application's references, read by the controller (13), the observers (15)–(16), (22) and
the object blocks.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

#: Rows of the reference signal fed to each robot's controller and observers, in order
#: (their sizes: n, n, n, m, 1; see :class:`ReferenceLayout`).
REFERENCE_ROWS = ("q_d", "qdot_d", "qddot_d", "lambda_d", "held")


@dataclass
class Reference:
    """One sample of a robot's reference signal (see :class:`ReferenceLayout`).

    Attributes
    ----------
    q_d, qdot_d, qddot_d : ndarray, shape (n,)
        The desired joint positions, velocities and accelerations.
    lambda_d : ndarray, shape (m,)
        The desired constraint forces.
    held : bool
        Whether the object is held (the constraint active).
    """

    q_d: np.ndarray
    qdot_d: np.ndarray
    qddot_d: np.ndarray
    lambda_d: np.ndarray
    held: bool


@dataclass(frozen=True)
class ReferenceLayout:
    """The layout of a robot's reference signal ``[q_d, q̇_d, q̈_d, λ_d, held]``: the one
    owner of its size and of where each part sits (built by
    :mod:`drake_coop.experiment.references`, read by the controller and the observers).

    Parameters
    ----------
    n : int
        Joints.
    m : int
        Constraints (rows of ``λ_d``).
    """

    n: int
    m: int = 1

    @staticmethod
    def check(layout, name: str = "layout") -> "ReferenceLayout":
        """``layout`` if it is a :class:`ReferenceLayout` (``TypeError`` naming ``name``).

        Parameters
        ----------
        layout : object
            The value to check.
        name : str
            The argument's name, for the message.
        """
        if not isinstance(layout, ReferenceLayout):
            raise TypeError(f"{name}: a drake_coop.control.ReferenceLayout is required "
                            f"(got {type(layout).__name__})")
        return layout

    @property
    def size(self) -> int:
        """``3 n + m + 1``."""
        return 3 * self.n + self.m + 1

    def slices(self) -> dict[str, slice]:
        """Where each row of :data:`REFERENCE_ROWS` sits in the vector.

        Returns
        -------
        dict of str to slice
            Row name → its slice.
        """
        n, m = self.n, self.m
        return {"q_d": slice(0, n), "qdot_d": slice(n, 2 * n), "qddot_d": slice(2 * n, 3 * n),
                "lambda_d": slice(3 * n, 3 * n + m), "held": slice(3 * n + m, 3 * n + m + 1)}

    def held(self, r: np.ndarray) -> bool:
        """Whether the sample ``r`` holds the object (its ``held`` row above 1/2).

        Parameters
        ----------
        r : numpy.ndarray
            One reference sample (size,).
        """
        return bool(r[3 * self.n + self.m] > 0.5)

    def unpack(self, r: np.ndarray) -> Reference:
        """One sample from the vector.

        Parameters
        ----------
        r : numpy.ndarray
            One reference sample (size,).

        Returns
        -------
        Reference
            Its rows: ``q_d`` (rad), ``q̇_d`` (rad/s), ``q̈_d`` (rad/s²), ``λ_d`` (N), ``held``.
        """
        n, m = self.n, self.m
        return Reference(r[0:n], r[n:2 * n], r[2 * n:3 * n], r[3 * n:3 * n + m], self.held(r))

    def pack(self, q_d: np.ndarray, qdot_d: np.ndarray, qddot_d: np.ndarray,
             lambda_d: np.ndarray, held: np.ndarray) -> np.ndarray:
        """Samples ``(K, size)`` from ``(K, n)`` references, ``(K, m)`` forces and ``(K,)``
        held flags.

        Parameters
        ----------
        q_d, qdot_d, qddot_d : numpy.ndarray
            The joint reference (K, n): rad, rad/s, rad/s².
        lambda_d : numpy.ndarray
            The desired force (K, m), N.
        held : numpy.ndarray
            The held flags (K,).

        Returns
        -------
        numpy.ndarray
            The samples (K, size).
        """
        return np.hstack([q_d, qdot_d, qddot_d, np.reshape(lambda_d, (-1, self.m)),
                          np.reshape(held, (-1, 1)).astype(float)])

    def column(self, samples: np.ndarray, row: str) -> np.ndarray:
        """One row of :data:`REFERENCE_ROWS` from samples ``(K, size)``: ``(K, width)``.

        Parameters
        ----------
        samples : numpy.ndarray
            Reference samples (K, size).
        row : str
            A row of :data:`REFERENCE_ROWS`.

        Returns
        -------
        numpy.ndarray
            That row (K, width).
        """
        return samples[:, self.slices()[row]]
