"""A ring of ``l`` identical arms around one object: the general system's scaling scenario.

:func:`ring_scenario` builds ``l`` CRS A255 arms ``360°/l`` apart around the palm origin (the
geometry of ``scenarios/three_arms.yaml``), each pushing on its own plane towards the centre.
Tutorial 04 and the benchmark of cost against ``l`` (``bench/robots.py``) use it.
"""

from __future__ import annotations

import math

from drake_coop.scenario.loading import load_scenario
from drake_coop.scenario.resources import scenarios_dir
from drake_coop.scenario.schema import Robot, Scenario
from drake_coop.scenario.validation import validate

__all__ = ["CONTACT_RADIUS", "BASE_RADIUS", "ring_scenario"]

#: Distances from the object's centre (m): the contact points and the bases.
CONTACT_RADIUS, BASE_RADIUS = 0.1, 0.44


def ring_scenario(l: int) -> Scenario:
    """``l`` A255 arms ``360°/l`` apart around the palm origin, each pushing on its own plane
    towards the centre; the object dips along z instead of the circle (as three_arms.yaml).

    Parameters
    ----------
    l : int
        The number of arms.
    """

    s = load_scenario(scenarios_dir() / "three_arms.yaml")
    template = s.robots[0]
    robots = []
    for i in range(l):
        a = 2 * math.pi * i / l
        c, sn = math.cos(a), math.sin(a)
        robots.append(Robot(
            name=f"robot{i + 1}", model=template.model, base_xyz=[BASE_RADIUS * c,
                                                                  BASE_RADIUS * sn, 0.0],
            base_yaw_deg=math.degrees(a) + 180.0 - (360.0 if a > math.pi else 0.0),
            contact_xy=[CONTACT_RADIUS * c, CONTACT_RADIUS * sn], normals=[[c, sn, 0.0]],
            home=[2 * CONTACT_RADIUS * c, 2 * CONTACT_RADIUS * sn, 0.6], gains=template.gains))
    s.robots = robots
    validate(s)
    return s
