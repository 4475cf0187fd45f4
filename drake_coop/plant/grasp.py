"""The ``contact`` object mode: a real box on a stand, held only by friction at the two pads.

Model
-----
Box
    A free body (model instance ``object``, body ``box``) of mass ``scenario.plant.object_mass``
    (default 0.5 kg), a solid cuboid of size ``(b_2 − b_1 − 2 r_pad) × 0.08 × 0.10`` m. The
    end-effector point E_i is the centre of the spherical pad, so the box's x faces lie where the
    pads' surfaces are when E_i is on its plane ``x = b_i``: at ``b_1 + r_pad`` and
    ``b_2 − r_pad``. At rest its centre is at ``(½(b_1 + b_2), 0, z_grasp)``, ``z_grasp =
    circle_top_z − lift_height`` (0.535 m): the grasp points are the centres of its x faces.
Stand
    A body (``stand``) welded to the world, a box under the object: half the object's width in x
    (so it never reaches the pads, which touch the object 5 cm above its bottom face), the
    object's depth in y, from the floor (z = 0) to the object's bottom face.
Floor
    A slab under everything (world geometry), so that a dropped box lands somewhere.

Contact (the plant uses ``contact_model="hydroelastic_with_fallback"`` and SAP)
    * Pads: compliant-hydroelastic spheres (``pad_collision`` in the arm URDFs: r = 15 mm,
      E = 5 MPa, μ = 1), their centre is E_i.
    * Box: **rigid**-hydroelastic, friction ``scenario.plant.friction``. A compliant sphere
      against a rigid box is a supported hydroelastic pair: the contact is a pressure patch
      (≈ 6–7 mm radius at a 32 N squeeze), whose distributed tangential tractions give the
      torsional friction that holds the box about the pad axis — two point contacts would not,
      and the box spins about that axis once it moves. Making the box compliant too would only
      soften the grip (two springs in series) and cost a tetrahedral mesh; the pad is the
      rubber, the object is stiff.
    * Stand and floor: compliant-hydroelastic (E = 10 MPa), so the box rests on a pressure
      patch (box-on-box point contact would pick a corner and tip the box). The stand's top is
      smooth (:data:`STAND_FRICTION`): with the paper's numbers the lowest point of the circle
      (28) is the grasp height, so the carried box brushes its stand there while moving
      sideways at full speed, and a rough stand would twist it in the grasp.
    * Filtered pairs: pads against stand, floor and each other, and stand against floor.
      What remains: pad–box (hydroelastic patches), box–stand and box–floor.

No constraint is switched: the grasp exists when the controllers squeeze.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from pydrake.geometry import (
    AddCompliantHydroelasticProperties,
    AddContactMaterial,
    AddRigidHydroelasticProperties,
    Box,
    CollisionFilterDeclaration,
    GeometryId,
    GeometrySet,
    ProximityProperties,
    SceneGraph,
    Sphere,
)
from pydrake.math import RigidTransform
from pydrake.multibody.math import SpatialVelocity
from pydrake.multibody.plant import ContactResults, CoulombFriction, MultibodyPlant
from pydrake.multibody.tree import (
    ModelInstanceIndex,
    RigidBody,
    SpatialInertia,
    UnitInertia,
)
from pydrake.systems.framework import Context

from drake_coop.scenario.schema import Scenario

#: y (depth) and z (height) size of the box (m).
BOX_DEPTH, BOX_HEIGHT = 0.08, 0.10
#: Stand width as a fraction of the box's width (x).
STAND_WIDTH_FRACTION = 0.5
#: Friction of the stand's (smooth) top. The circle (28) ends its lower half at the grasp height
#: (0.635 − 2·0.05 = 0.535 m), so the box brushes the stand at the circle's bottom while moving
#: sideways; a smooth stand keeps that touch from twisting the box in the grasp.
STAND_FRICTION = 0.05
#: Hydroelastic modulus of the stand and floor (Pa).
STAND_MODULUS = 1e7
#: Initial clearance between the box and the stand (m): it settles without a jump.
SETTLE_GAP = 1e-5
#: Hunt–Crossley dissipation (s/m) and point stiffness (N/m, used only by a point-contact
#: fallback) of the object's and stand's contact materials.
DISSIPATION, POINT_STIFFNESS = 5.0, 1e6

_BOX_COLOR = np.array([0.8, 0.6, 0.2, 1.0])
_STAND_COLOR = np.array([0.5, 0.5, 0.55, 1.0])
_FLOOR_COLOR = np.array([0.7, 0.7, 0.7, 0.3])


@dataclass
class ContactObject:
    """The box of the ``contact`` mode and what it rests on.

    Attributes
    ----------
    box : RigidBody
        The free box (model instance ``object``).
    stand : RigidBody or None
        The stand, welded to the world.
    size : ndarray, shape (3,)
        The box's x, y, z size (m).
    X_WBox0 : RigidTransform
        The box's rest pose on the stand (world = palm frame).
    box_geometry : GeometryId or None
        The box's collision geometry.
    pad_geometries : list[GeometryId]
        The pads' collision geometries, one per arm, in the scenario's robot order.
    """

    box: RigidBody
    stand: RigidBody | None
    size: np.ndarray
    X_WBox0: RigidTransform
    box_geometry: GeometryId | None = None
    pad_geometries: list[GeometryId] = field(default_factory=list)

    def initialize(self, plant: MultibodyPlant, context: Context) -> None:
        """Put the box at rest on the stand, :data:`SETTLE_GAP` above it.

        Parameters
        ----------
        plant : MultibodyPlant
            The finalized plant.
        context : Context
            The plant's context (modified).
        """
        X = RigidTransform(self.X_WBox0.rotation(),
                           self.X_WBox0.translation() + np.array([0.0, 0.0, SETTLE_GAP]))
        plant.SetFreeBodyPose(context, self.box, X)
        plant.SetFreeBodySpatialVelocity(context, self.box, SpatialVelocity.Zero())

    def pad_force(self, results: ContactResults, pad: GeometryId) -> np.ndarray:
        """Total contact force of the box on one pad, world frame (N).

        Sums the hydroelastic patches (and, should the plant fall back to it, point contact)
        between ``pad`` and the box's collision geometry in ``results``.

        Parameters
        ----------
        results : ContactResults
            The plant's ``contact_results`` output.
        pad : GeometryId
            The pad's collision geometry (an entry of :attr:`pad_geometries`).
        """
        total = np.zeros(3)
        pair = {pad, self.box_geometry}
        for k in range(results.num_hydroelastic_contacts()):
            info = results.hydroelastic_contact_info(k)
            surface = info.contact_surface()
            if {surface.id_M(), surface.id_N()} != pair:
                continue
            f = info.F_Ac_W().translational()      # on the body of geometry M
            total += f if surface.id_M() == pad else -f
        for k in range(results.num_point_pair_contacts()):
            info = results.point_pair_contact_info(k)
            pp = info.point_pair()
            if {pp.id_A, pp.id_B} != pair:
                continue
            f = info.contact_force()               # on body B (geometry id_B)
            total += f if pp.id_B == pad else -f
        return total


def _props(mu: float, compliant_modulus: float | None = None) -> ProximityProperties:
    """Contact material (friction μ) with rigid or compliant hydroelastic properties."""
    props = ProximityProperties()
    AddContactMaterial(dissipation=DISSIPATION, point_stiffness=POINT_STIFFNESS,
                       friction=CoulombFriction(mu, mu), properties=props)
    if compliant_modulus is None:
        AddRigidHydroelasticProperties(properties=props)
    else:
        AddCompliantHydroelasticProperties(resolution_hint=0.02,
                                           hydroelastic_modulus=compliant_modulus,
                                           properties=props)
    return props


def _pad_geometries(plant: MultibodyPlant, scenario: Scenario) -> list[GeometryId]:
    """The pads' collision geometries in robot order (the arms must already be in the plant).

    The arms' model instances are named ``<robot>::<urdf model>`` (parser prefix).
    """
    ids = []
    for robot in scenario.robots:
        for k in range(plant.num_model_instances()):
            instance = ModelInstanceIndex(k)
            if (plant.GetModelInstanceName(instance).startswith(f"{robot.name}::")
                    and plant.HasBodyNamed("pad", instance)):
                ids.extend(plant.GetCollisionGeometriesForBody(
                    plant.GetBodyByName("pad", instance)))
    return ids


def pad_radius(scene_graph: SceneGraph, pad: GeometryId) -> float:
    """The radius of a pad's sphere (the shipped arms' 15 mm, or a ``tool``'s ``pad_radius``).

    Raises
    ------
    ValueError
        The pad's collision geometry is not a sphere.
    """
    shape = scene_graph.model_inspector().GetShape(pad)
    if not isinstance(shape, Sphere):
        raise ValueError(f"contact mode: a pad must be a sphere, got {type(shape).__name__}")
    return float(shape.radius())


def add_contact_object(plant: MultibodyPlant, scene_graph: SceneGraph,
                       scenario: Scenario) -> ContactObject:
    """Add the box (model instance ``object``), its stand and the floor to a plant.

    Call after the arms are added (their pads' collisions with the stand and floor are
    filtered) and before ``plant.Finalize()``.

    Parameters
    ----------
    plant : MultibodyPlant
        The unfinalized cooperative plant, registered with ``scene_graph``.
    scene_graph : SceneGraph
    scenario : Scenario
        Uses the robots' contact x (``contact_xy[0]``) and pad radius, ``task.circle_top_z``,
        ``task.lift_height``, ``plant.object_mass`` and ``plant.friction``.

    Returns
    -------
    ContactObject
    """
    r1, r2 = scenario.robots
    pads = _pad_geometries(plant, scenario)
    r_pad = pad_radius(scene_graph, pads[0])
    lo, hi = sorted([r1.contact_xy[0], r2.contact_xy[0]])
    width = (hi - lo) - 2 * r_pad
    if width <= 0:
        raise ValueError(f"contact mode: the planes b_i are too close for the pads "
                         f"(|b_2 − b_1| = {hi - lo} m, pad radius {r_pad} m)")
    size = np.array([width, BOX_DEPTH, BOX_HEIGHT])
    z_grasp = scenario.task.circle_top_z - scenario.task.lift_height
    center = np.array([0.5 * (lo + hi), 0.0, z_grasp])
    mu = scenario.plant.friction

    instance = plant.AddModelInstance("object")
    m = scenario.plant.object_mass
    box = plant.AddRigidBody("box", instance,
                             SpatialInertia(m, np.zeros(3), UnitInertia.SolidBox(*size)))
    box_geometry = plant.RegisterCollisionGeometry(box, RigidTransform(), Box(*size),
                                                   "box_collision", _props(mu))
    plant.RegisterVisualGeometry(box, RigidTransform(), Box(*size), "box_visual", _BOX_COLOR)

    stand_top = z_grasp - BOX_HEIGHT / 2
    stand_shape = Box(STAND_WIDTH_FRACTION * width, BOX_DEPTH, stand_top)
    stand = plant.AddRigidBody("stand", instance,
                               SpatialInertia(1.0, np.zeros(3), UnitInertia.SolidBox(
                                   STAND_WIDTH_FRACTION * width, BOX_DEPTH, stand_top)))
    plant.WeldFrames(plant.world_frame(), stand.body_frame(),
                     RigidTransform(np.array([center[0], 0.0, stand_top / 2])))
    stand_geometry = plant.RegisterCollisionGeometry(
        stand, RigidTransform(), stand_shape, "stand_collision",
        _props(STAND_FRICTION, compliant_modulus=STAND_MODULUS))
    plant.RegisterVisualGeometry(stand, RigidTransform(), stand_shape, "stand_visual",
                                 _STAND_COLOR)

    floor = Box(1.0, 1.0, 0.02)
    X_WF = RigidTransform(np.array([center[0], 0.0, -0.01]))
    floor_geometry = plant.RegisterCollisionGeometry(
        plant.world_body(), X_WF, floor, "floor_collision",
        _props(mu, compliant_modulus=STAND_MODULUS))
    plant.RegisterVisualGeometry(plant.world_body(), X_WF, floor, "floor_visual", _FLOOR_COLOR)

    pads = _pad_geometries(plant, scenario)
    statics = GeometrySet([stand_geometry, floor_geometry])
    manager = scene_graph.collision_filter_manager()
    manager.Apply(CollisionFilterDeclaration()
                  .ExcludeWithin(statics)
                  .ExcludeBetween(GeometrySet(pads), statics)
                  .ExcludeWithin(GeometrySet(pads)))
    return ContactObject(box=box, stand=stand, size=size, X_WBox0=RigidTransform(center),
                         box_geometry=box_geometry, pad_geometries=pads)
