"""The ``contact`` object mode: a real box on a stand, held only by friction at the two pads.

The box (``object_mass``, default 0.5 kg) is a free body whose x faces lie where the pads'
surfaces are when the end-effector points are on their planes: ``b_1 + r_pad`` and
``b_2 − r_pad`` (the end-effector point is the pad's centre). It rests on a stand welded to the
world, narrower than the box so the pads never touch it, with the box's centre at the grasp
height. The pads are compliant-hydroelastic spheres and the box is rigid-hydroelastic: the
contact is a pressure patch, which gives torsional friction — two point contacts would let the
box spin about the pad axis. The stand is compliant-hydroelastic too, so the box rests on a
pressure patch (box-on-box point contact would pick one corner and tip it), and smooth: with the
paper's numbers the circle's lowest point is the grasp height, so the box brushes the stand there.

No constraint is switched: the grasp exists when the controllers squeeze.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from pydrake.geometry import (
    AddCompliantHydroelasticProperties,
    AddContactMaterial,
    AddRigidHydroelasticProperties,
    Box,
    ProximityProperties,
    SceneGraph,
)
from pydrake.math import RigidTransform
from pydrake.multibody.math import SpatialVelocity
from pydrake.multibody.plant import CoulombFriction, MultibodyPlant
from pydrake.multibody.tree import RigidBody, SpatialInertia, UnitInertia
from pydrake.systems.framework import Context

from drake_coop.arms import GEOMETRY
from drake_coop.scenario import Scenario

#: y and z size of the box (m).
BOX_DEPTH, BOX_HEIGHT = 0.08, 0.10
#: Friction of the stand's (smooth) top. The circle (28) ends its lower half at the grasp height
#: (0.635 − 2·0.05 = 0.535 m), so the box brushes the stand at the circle's bottom (t = 45 s)
#: while moving sideways; a smooth stand keeps that touch from twisting the box in the grasp.
STAND_FRICTION = 0.05
#: Initial clearance between the box and the stand (m): it settles without a jump.
SETTLE_GAP = 1e-5


@dataclass
class ContactObject:
    """The box of the ``contact`` mode.

    Attributes
    ----------
    box : RigidBody
        The free box.
    size : ndarray
        Its x, y, z size (m).
    X_WBox0 : RigidTransform
        Its rest pose on the stand.
    """

    box: RigidBody
    size: np.ndarray
    X_WBox0: RigidTransform

    def initialize(self, plant: MultibodyPlant, context: Context) -> None:
        """Put the box at rest on the stand."""
        X = RigidTransform(self.X_WBox0.translation() + np.array([0.0, 0.0, SETTLE_GAP]))
        plant.SetFreeBodyPose(context, self.box, X)
        plant.SetFreeBodySpatialVelocity(context, self.box, SpatialVelocity.Zero())




def _props(mu: float, compliant_modulus: float | None = None) -> ProximityProperties:
    props = ProximityProperties()
    AddContactMaterial(dissipation=5.0, point_stiffness=1e6,
                       friction=CoulombFriction(mu, mu), properties=props)
    if compliant_modulus is None:
        AddRigidHydroelasticProperties(properties=props)
    else:
        AddCompliantHydroelasticProperties(resolution_hint=0.02,
                                           hydroelastic_modulus=compliant_modulus,
                                           properties=props)
    return props


def add_contact_object(plant: MultibodyPlant, scene_graph: SceneGraph,
                       scenario: Scenario) -> ContactObject:
    """Add the box (model instance ``object``) and its stand to an unfinalized plant."""
    r1, r2 = scenario.robots
    r_pad = GEOMETRY[r1.model].r_pad
    lo, hi = sorted([r1.plane_b, r2.plane_b])
    width = (hi - lo) - 2 * r_pad
    size = np.array([width, BOX_DEPTH, BOX_HEIGHT])
    z_grasp = scenario.task.circle_top_z - scenario.task.lift_height
    center = np.array([0.5 * (lo + hi), 0.0, z_grasp])
    mu = scenario.plant.friction

    instance = plant.AddModelInstance("object")
    m = scenario.plant.object_mass
    box = plant.AddRigidBody("box", instance,
                             SpatialInertia(m, np.zeros(3), UnitInertia.SolidBox(*size)))
    plant.RegisterCollisionGeometry(box, RigidTransform(), Box(*size), "box_collision",
                                    _props(mu))
    plant.RegisterVisualGeometry(box, RigidTransform(), Box(*size), "box_visual",
                                 np.array([0.8, 0.6, 0.2, 1.0]))

    stand_top = z_grasp - BOX_HEIGHT / 2
    stand = Box(0.5 * width, BOX_DEPTH, stand_top)
    X_WS = RigidTransform(np.array([center[0], 0.0, stand_top / 2]))
    plant.RegisterCollisionGeometry(plant.world_body(), X_WS, stand, "stand_collision",
                                    _props(STAND_FRICTION, compliant_modulus=1e7))
    plant.RegisterVisualGeometry(plant.world_body(), X_WS, stand, "stand_visual",
                                 np.array([0.5, 0.5, 0.55, 1.0]))
    # The floor, so that a dropped box lands somewhere.
    floor = Box(1.0, 1.0, 0.02)
    X_WF = RigidTransform(np.array([center[0], 0.0, -0.01]))
    plant.RegisterCollisionGeometry(plant.world_body(), X_WF, floor, "floor_collision",
                                    _props(mu, compliant_modulus=1e7))
    return ContactObject(box=box, size=size, X_WBox0=RigidTransform(center))
