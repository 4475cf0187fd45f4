"""The prism that ``l ≥ 3`` pads hold by friction in ``contact`` mode: its horizontal
cross-section, one flat side per pad a pad radius inside the pad's contact point along its
outward normal (:func:`prism_section`), and Drake's :class:`~pydrake.geometry.Convex` of it.
Each pad then presses a sphere on a plane, as on the two-arm box; used by
:func:`drake_coop.plant.grasp.add_contact_object`."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["PrismSection", "prism_section"]


@dataclass(frozen=True)
class PrismSection:
    """The cross-section of the ``l ≥ 3`` pads' prism (horizontal, in the object's frame).

    Attributes
    ----------
    normals : ndarray, shape (l, 3)
        Each face's outward unit normal (robot order), horizontal.
    offsets : ndarray, shape (l,)
        Each face's distance from the origin (m): face ``i`` is ``normals[i] · p = offsets[i]``.
    vertices : ndarray, shape (l, 2)
        The polygon's corners, counter-clockwise.
    """

    normals: np.ndarray
    offsets: np.ndarray
    vertices: np.ndarray


def prism_section(points: np.ndarray, normals: np.ndarray, r_pad: float) -> PrismSection:
    """The polygon whose side ``i`` lies a pad radius inside contact point ``i`` along the
    outward normal ``i`` (both horizontal, robot order), about the points' mean.

    Parameters
    ----------
    points : ndarray, shape (l, 2)
        The robots' contact points (``contact_xy``), l ≥ 3.
    normals : ndarray, shape (l, 2)
        Their outward normals ``N_i`` (x, y; normalized here).
    r_pad : float
        The pads' radius (m).

    Raises
    ------
    ValueError
        The normals leave a gap of 180° or more (the faces do not enclose an object), a face is
        not a side of the polygon, or a pad's contact point is within a pad radius of its
        side's ends (or off it).
    """
    points = np.asarray(points, dtype=float)
    n = np.asarray(normals, dtype=float)
    n = n / np.linalg.norm(n, axis=1, keepdims=True)
    rel = points - points.mean(axis=0)
    offsets = np.einsum("ij,ij->i", n, rel) - r_pad
    angle = np.arctan2(n[:, 1], n[:, 0])
    order = np.argsort(angle)
    gaps = np.diff(np.concatenate([angle[order], [angle[order[0]] + 2 * np.pi]]))
    if np.any(gaps >= np.pi - 1e-9) or np.any(gaps <= 1e-9):
        raise ValueError("contact mode: the robots' normals must surround the object (every "
                         "angle between neighbouring normals in (0°, 180°)) for a prism")
    corners = []
    for a, b in zip(order, np.roll(order, -1)):
        corners.append(np.linalg.solve(np.array([n[a], n[b]]), [offsets[a], offsets[b]]))
    vertices = np.array(corners)
    if np.any(vertices @ n.T > offsets + 1e-9):
        raise ValueError("contact mode: every robot's face must be a side of the prism (a "
                         "face lies outside the others': move its contact point inwards)")
    for k, i in enumerate(order):
        v0, v1 = vertices[k - 1], vertices[k]        # the side between its two neighbours
        touch = rel[i] - r_pad * n[i]
        d = v1 - v0
        s = float((touch - v0) @ d) / float(d @ d)
        length = float(np.linalg.norm(d))
        if not (r_pad / length < s < 1.0 - r_pad / length):
            raise ValueError(f"contact mode: robot {int(i) + 1}'s contact point must lie on "
                             f"its face at least a pad radius ({r_pad} m) from its ends")
    return PrismSection(normals=np.column_stack([n, np.zeros(len(n))]), offsets=offsets,
                        vertices=vertices)


def _prism_shape(section: PrismSection, height: float):
    """Drake's :class:`Convex` of the prism of ``section`` and ``height``, centred on z."""
    from pydrake.geometry import Convex

    v = section.vertices
    top = np.column_stack([v, np.full(len(v), height / 2)])
    bottom = np.column_stack([v, np.full(len(v), -height / 2)])
    return Convex(np.vstack([bottom, top]).T, "prism")
