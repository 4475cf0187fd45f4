"""The held object's model (:class:`ObjectModel`): mass, centre of mass, inertia and the
grasp (contact points, inward normals), in an object frame aligned with the world; and
standard gravity (:data:`GRAVITY`)."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np


#: Standard gravity (m/s²); gravity is ``g = (0, 0, −GRAVITY)`` in the world frame.
GRAVITY = 9.81


def _vector(value, name: str, size: int = 3) -> np.ndarray:
    v = np.asarray(value, dtype=float)
    if v.shape != (size,) or not np.all(np.isfinite(v)):
        raise ValueError(f"{name}: {size} finite numbers are required (got {np.shape(value)})")
    return v


@dataclass(frozen=True)
class ObjectModel:
    """The held object: mass, centre of mass, inertia and the grasp.

    Every vector is in the object frame, aligned with the world frame (the desired path
    translates the object), with its origin at a point the user picks (e.g. the grasp
    points' midpoint).

    Parameters
    ----------
    mass : float
        ``m`` (kg), > 0.
    com : array_like, shape (3,)
        Centre of mass (m).
    inertia : array_like, shape (3, 3)
        Rotational inertia about the centre of mass (kg·m²), symmetric positive semidefinite.
    grasp_points : array_like, shape (k, 3)
        The contact points (m), one per arm, k >= 1.
    grasp_normals : array_like, shape (k, 3)
        Each contact's normal pointing into the object (the direction the arm pushes to
        squeeze), unit after normalization.

    Raises
    ------
    ValueError
        Naming the field: a mass <= 0 or not finite, wrong shapes, a zero normal.
    """

    mass: float
    com: np.ndarray = field(default_factory=lambda: np.zeros(3))
    inertia: np.ndarray = field(default_factory=lambda: np.zeros((3, 3)))
    grasp_points: np.ndarray = field(default_factory=lambda: np.array([[-1.0, 0, 0],
                                                                       [1.0, 0, 0]]))
    grasp_normals: np.ndarray = field(default_factory=lambda: np.array([[1.0, 0, 0],
                                                                        [-1.0, 0, 0]]))

    def __post_init__(self):
        m = self.mass
        if isinstance(m, bool) or not isinstance(m, (int, float, np.floating)) \
                or not np.isfinite(m) or m <= 0:
            raise ValueError(f"mass: a finite number > 0 is required (kg), got {m!r}")
        object.__setattr__(self, "mass", float(m))
        object.__setattr__(self, "com", _vector(self.com, "com"))
        inertia = np.asarray(self.inertia, dtype=float)
        if inertia.shape != (3, 3) or not np.all(np.isfinite(inertia)) \
                or not np.allclose(inertia, inertia.T) \
                or np.min(np.linalg.eigvalsh(inertia)) < -1e-12:
            raise ValueError("inertia: a symmetric positive semidefinite 3x3 matrix is required")
        object.__setattr__(self, "inertia", inertia)
        points = np.asarray(self.grasp_points, dtype=float)
        normals = np.asarray(self.grasp_normals, dtype=float)
        if points.ndim != 2 or points.shape[1] != 3 or len(points) < 1 \
                or not np.all(np.isfinite(points)):
            raise ValueError("grasp_points: k >= 1 rows of 3 finite numbers are required")
        if normals.shape != points.shape or not np.all(np.isfinite(normals)):
            raise ValueError(f"grasp_normals: {points.shape} finite numbers are required "
                             f"(one normal per grasp point), got {normals.shape}")
        norms = np.linalg.norm(normals, axis=1)
        if np.any(norms < 1e-9):
            raise ValueError("grasp_normals: every normal must be nonzero")
        object.__setattr__(self, "grasp_points", points)
        object.__setattr__(self, "grasp_normals", normals / norms[:, None])

    @property
    def contacts(self) -> int:
        """The number of contacts ``k``."""
        return len(self.grasp_points)
