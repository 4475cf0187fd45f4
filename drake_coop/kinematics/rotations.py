"""Rotations of logged poses, NumPy only: a free body's quaternions as rotation matrices and a
pad's contact force split along the face of the box it touches.

Below the plant and the results (it imports nothing of the package and no Drake), so that the
logs' post-processing (:func:`~drake_coop.experiment.simulate.collect_logs`,
:mod:`drake_coop.results.object_metrics`) needs no pydrake.
"""

from __future__ import annotations

import numpy as np

__all__ = ["pad_contact_components", "quaternion_rotations"]


def quaternion_rotations(quaternions: np.ndarray) -> np.ndarray:
    """Rotation matrices of unit quaternions ``[w, x, y, z]`` (the order of a free body's
    positions in the plant's state), normalized first.

    Parameters
    ----------
    quaternions : numpy.ndarray
        Quaternions (K, 4) or (4,).

    Returns
    -------
    numpy.ndarray
        The rotation matrices (K, 3, 3).
    """
    q = np.asarray(quaternions, dtype=float).reshape(-1, 4)
    q = q / np.linalg.norm(q, axis=1, keepdims=True)
    w, x, y, z = q.T
    return np.stack([
        np.stack([1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)], axis=1),
        np.stack([2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)], axis=1),
        np.stack([2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)], axis=1),
    ], axis=1)


def pad_contact_components(F: np.ndarray, p_pad: np.ndarray, pose: np.ndarray,
                           face_normal: np.ndarray | None = None
                           ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Normal and tangential parts of a pad's contact force, per sample.

    The pad touches one of the box's x faces (the one on its side of the box's centre); its
    outward normal is ``n = ± R_WB e_x``; on another object (the prism of three or more
    arms) the face of ``face_normal`` (its outward unit normal in the object's frame):
    ``n = R_WB face_normal``. With ``F`` the box's force on the pad,
    ``f_n = n · F`` (positive when the box pushes the pad away: a compressive contact) and
    ``f_t = ‖F − f_n n‖``.

    Parameters
    ----------
    F : ndarray, shape (K, 3)
        The box's force on the pad (palm frame, N).
    p_pad : ndarray, shape (K, 3)
        The pad's centre (the end-effector point, m).
    pose : ndarray, shape (K, 7)
        The box's ``[w, x, y, z]`` quaternion and position (the plant's free-body positions).
    face_normal : ndarray, shape (3,), optional
        The pad's face's outward normal in the object's frame (default: the box's ``±x``).

    Returns
    -------
    f_n, f_t : ndarray, shape (K,)
        The normal and tangential components, N.
    p_B : ndarray, shape (K, 3)
        The pad's centre in the box's frame (where on the box it sits).
    """
    R = quaternion_rotations(pose[:, :4])
    p_B = np.einsum("kji,kj->ki", R, np.asarray(p_pad, dtype=float) - pose[:, 4:7])
    if face_normal is None:
        side = np.where(p_B[:, 0] >= 0.0, 1.0, -1.0)
        n = R[:, :, 0] * side[:, None]
    else:
        n = R @ np.asarray(face_normal, dtype=float)
    F = np.asarray(F, dtype=float)
    f_n = np.einsum("ki,ki->k", n, F)
    f_t = np.linalg.norm(F - f_n[:, None] * n, axis=1)
    return f_n, f_t, p_B
