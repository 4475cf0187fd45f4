"""The ``contact`` object mode: a real object on a stand, held only by friction at the pads.

Model
-----
The object has one flat face per pad, its outward normal the arm's constraint normal ``N_i``:
with two arms (normals ``∓x``) the box below; with ``l ≥ 3`` arms (horizontal normals that
surround the object) the right prism below, whose ``l`` side faces are where the pads'
surfaces are. A curved object (a cylinder) is not offered: a pad on a curved face touches it
along a line that moves as the object turns, so no face frame exists for the slip and the
normal/tangential split, and the contact patch is no longer a sphere on a plane.

Box (two arms)
    A free body (model instance ``object``, body ``box``) of mass ``scenario.plant.object_mass``
    (default 0.5 kg), a solid cuboid of size ``(b_2 − b_1 − 2 r_pad) × 0.08 × 0.10`` m. The
    end-effector point E_i is the centre of the spherical pad, so the box's x faces lie where the
    pads' surfaces are when E_i is on its plane ``x = b_i``: at ``b_1 + r_pad`` and
    ``b_2 − r_pad``. At rest its centre is at ``(½(b_1 + b_2), 0, z_grasp)``, ``z_grasp =
    circle_top_z − lift_height`` (0.535 m): the grasp points are the centres of its x faces.
Prism (``l ≥ 3`` arms)
    A free body (model instance ``object``, body ``box``: the name is the object's, whatever
    its shape) of mass ``scenario.plant.object_mass``: a right prism 0.10 m high whose
    cross-section is the polygon ``{p : N_i · (p − c) ≤ d_i}``, ``c`` the mean of the robots'
    contact points, ``d_i = N_i · (p_i − c) − r_pad`` (face ``i`` lies where pad ``i``'s surface
    is when E_i is on its plane); an equilateral triangle for three arms 120° apart. Each face
    is a rectangle, so the pad-on-face physics of the box (a sphere on a plane, its pressure
    patch, its torsional friction) and the slip on the pad's own face carry over unchanged,
    and ``l`` equal squeezes ``N_i`` 120° apart sum to zero. Drake's :class:`Convex` from the
    prism's vertices, rigid-hydroelastic; its spatial inertia Drake's
    :func:`CalcSpatialInertia` of that shape at the uniform density. Rest pose: frame at
    ``(c, z_grasp)``, identity rotation. The normals must surround the object (every angular
    gap between consecutive normals below 180°), every face must be an edge of the polygon, and
    each pad's contact point must lie on its face at least a pad radius from its ends.
Stand
    A body (``stand``) welded to the world, a box under the object: half the object's width in x
    (so it never reaches the pads, which touch the object 5 cm above its bottom face), the
    object's depth in y (for a prism: a square of side the polygon's smallest face distance
    ``min d_i``, inside its inscribed circle), from the floor (z = 0) to the object's bottom face, on a locked
    vertical slide (model instance ``stand``). The circle (28) passes through the grasp pose
    at its lowest point (43–46 s), so a box carried along it comes back onto its stand there.
    With ``scenario.plant.stand_clearance`` = d > 0 the run lowers the stand by d while the
    box is carried around the circle (:meth:`ContactObject.set_stand_lowered`, from the
    circle's start, when the box is 10 cm up, to its end) and puts it back for the put-down:
    the carried box then passes d above it. At d = 0 it brushes it.
Floor
    A slab under everything (world geometry), so that a dropped box lands somewhere.

Contact (the plant uses ``contact_model="hydroelastic_with_fallback"`` and SAP)
    * Pads: compliant-hydroelastic spheres (``pad_collision`` in the arm URDFs: r = 15 mm,
      E = 5 MPa, or ``scenario.plant.pad_modulus``), their centre is E_i; their friction is
      set to the box's (``scenario.plant.friction``), so that the pair's coefficient is that
      number (Drake combines two materials' as ``2 μ_1 μ_2 / (μ_1 + μ_2)``).
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
    RoleAssign,
    SceneGraph,
    Sphere,
)
from pydrake.math import RigidTransform
from pydrake.multibody.math import SpatialVelocity
from pydrake.multibody.plant import ContactResults, CoulombFriction, MultibodyPlant
from pydrake.multibody.tree import (
    FixedOffsetFrame,
    ModelInstanceIndex,
    PrismaticJoint,
    RigidBody,
    SpatialInertia,
    UnitInertia,
)
from pydrake.common.value import AbstractValue
from pydrake.systems.framework import Context, InputPort, LeafSystem, OutputPort

from drake_coop.plant.prism import _prism_shape, prism_section
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
        The box's x, y, z size (m); a prism's bounding box.
    X_WBox0 : RigidTransform
        The box's rest pose on the stand (world = palm frame).
    box_geometry : GeometryId or None
        The box's collision geometry.
    pad_geometries : list[GeometryId]
        The pads' collision geometries, one per arm, in the scenario's robot order.
    face_normals : ndarray, shape (l, 3) or None
        The outward unit normal, in the object's frame, of the face each pad touches (robot
        order); None for the two-arm box, whose pads touch its ``±x`` faces (the pad's side).
    face_offsets : ndarray, shape (l,) or None
        Each face's distance from the object's frame origin along its normal (m); None for
        the box (``size[0] / 2``).
    stand_slide : PrismaticJoint or None
        The stand's vertical slide, locked; :meth:`set_stand_lowered` moves it.
    stand_drop : float
        How far the stand is lowered, m.
    """

    box: RigidBody
    stand: RigidBody | None
    size: np.ndarray
    X_WBox0: RigidTransform
    box_geometry: GeometryId | None = None
    pad_geometries: list[GeometryId] = field(default_factory=list)
    face_normals: np.ndarray | None = None
    face_offsets: np.ndarray | None = None
    stand_slide: PrismaticJoint | None = None
    stand_drop: float = 0.0
    _pad_index: dict = field(init=False, repr=False, compare=False, default_factory=dict)

    def __post_init__(self):
        self._pad_index = {pad: i for i, pad in enumerate(self.pad_geometries)}

    def set_stand_lowered(self, context: Context, lowered: bool) -> None:
        """Put the stand :attr:`stand_drop` below its place (``lowered``) or back; its slide
        stays locked (between two ``AdvanceTo`` calls, as the grasp is switched).

        Parameters
        ----------
        context : Context
            The plant's context.
        lowered : bool
            Lowered or back in place.
        """
        if self.stand_slide is not None:
            self.stand_slide.set_translation(context, -self.stand_drop if lowered else 0.0)
            self.stand_slide.set_translation_rate(context, 0.0)

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
        if self.stand_slide is not None:
            self.set_stand_lowered(context, False)
            self.stand_slide.Lock(context)

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

        Returns
        -------
        numpy.ndarray
            The force (3,), N, world frame.
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

    def pad_forces(self, results: ContactResults) -> list[np.ndarray]:
        """:meth:`pad_force` of every pad (in :attr:`pad_geometries`' order), in one pass
        over the contacts.

        Parameters
        ----------
        results : ContactResults
            The plant's ``contact_results`` output.

        Returns
        -------
        list of numpy.ndarray
            One force (3,) per pad, N, world frame.
        """
        return [np.array(t) for t in self._pad_totals(results)]

    def pad_forces_vector(self, results: ContactResults) -> np.ndarray:
        """:meth:`pad_forces` as one vector ``[F_1, …, F_l]``.

        Parameters
        ----------
        results : ContactResults
            The plant's ``contact_results`` output.

        Returns
        -------
        numpy.ndarray
            ``[F_1, …, F_l]`` (3 l,), N.
        """
        return np.array([x for t in self._pad_totals(results) for x in t])

    def _pad_totals(self, results: ContactResults) -> list[list[float]]:
        """Every pad's force as a list of three floats (the sums of :meth:`pad_forces`)."""
        index = self._pad_index
        box = self.box_geometry
        totals = [[0.0, 0.0, 0.0] for _ in self.pad_geometries]
        for k in range(results.num_hydroelastic_contacts()):
            info = results.hydroelastic_contact_info(k)
            surface = info.contact_surface()
            M, N = surface.id_M(), surface.id_N()
            if M == box:
                i, sign = index.get(N), -1.0
            elif N == box:
                i, sign = index.get(M), 1.0
            else:
                continue
            if i is None:
                continue
            f = info.F_Ac_W().translational()      # on the body of geometry M
            t = totals[i]
            t[0] += sign * f[0]
            t[1] += sign * f[1]
            t[2] += sign * f[2]
        for k in range(results.num_point_pair_contacts()):
            info = results.point_pair_contact_info(k)
            pp = info.point_pair()
            if pp.id_A == box:
                i, sign = index.get(pp.id_B), 1.0
            elif pp.id_B == box:
                i, sign = index.get(pp.id_A), -1.0
            else:
                continue
            if i is None:
                continue
            f = info.contact_force()               # on body B (geometry id_B)
            t = totals[i]
            t[0] += sign * f[0]
            t[1] += sign * f[1]
            t[2] += sign * f[2]
        return totals


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


def _set_pad_material(scene_graph: SceneGraph, plant: MultibodyPlant,
                      pads: list[GeometryId], mu: float, modulus: float | None) -> None:
    """The pads' friction set to the box's ``μ`` (so that the pair's combined coefficient,
    ``2 μ_pad μ_box / (μ_pad + μ_box)`` in Drake, is ``μ`` itself) and, when given, their
    hydroelastic modulus; every other property stays the arm model's."""
    inspector = scene_graph.model_inspector()
    for pad in pads:
        props = ProximityProperties(inspector.GetProximityProperties(pad))
        props.UpdateProperty("material", "coulomb_friction", CoulombFriction(mu, mu))
        if modulus is not None:
            props.UpdateProperty("hydroelastic", "hydroelastic_modulus", float(modulus))
        scene_graph.AssignRole(plant.get_source_id(), pad, props, RoleAssign.kReplace)


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

    Parameters
    ----------
    scene_graph : SceneGraph
        The plant's scene graph.
    pad : GeometryId
        The pad's collision geometry.

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
    """Add the object (model instance ``object``: the box of two arms, the prism of three or
    more), its stand and the floor to a plant.

    Call after the arms are added (their pads' collisions with the stand and floor are
    filtered) and before ``plant.Finalize()``.

    Parameters
    ----------
    plant : MultibodyPlant
        The unfinalized cooperative plant, registered with ``scene_graph``.
    scene_graph : SceneGraph
        The plant's scene graph.
    scenario : Scenario
        Uses the robots' contact x (``contact_xy[0]``) and pad radius, ``task.circle_top_z``,
        ``task.lift_height``, ``plant.object_mass``, ``plant.friction``,
        ``plant.stand_clearance`` and ``plant.pad_modulus``.

    Returns
    -------
    ContactObject
        The box, its stand and the pads' geometries.
    """
    if len(scenario.robots) >= 3:
        return _add_prism(plant, scene_graph, scenario)
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

    stand_top = center[2] - BOX_HEIGHT / 2
    stand_shape = Box(STAND_WIDTH_FRACTION * width, BOX_DEPTH, stand_top)
    # The stand in a model instance of its own, on a locked vertical slide (the box's state
    # stays the "object" instance's alone); lowered by stand_clearance during the circle.
    stand, stand_slide = _add_stand_and_floor(plant, scene_graph, scenario, pads, center,
                                              stand_shape, mu)
    return ContactObject(box=box, stand=stand, size=size, X_WBox0=RigidTransform(center),
                         box_geometry=box_geometry, pad_geometries=pads,
                         stand_slide=stand_slide,
                         stand_drop=float(scenario.plant.stand_clearance))


def _add_stand_and_floor(plant: MultibodyPlant, scene_graph: SceneGraph, scenario: Scenario,
                         pads: list[GeometryId], center: np.ndarray, stand_shape: Box,
                         mu: float) -> tuple[RigidBody, PrismaticJoint]:
    """The stand (``stand_shape`` under ``center``, on its locked slide), the floor, the pads'
    material and the collision filters (see the module)."""
    stand_top = center[2] - BOX_HEIGHT / 2
    # The stand in a model instance of its own, on a locked vertical slide (the box's state
    # stays the "object" instance's alone); lowered by stand_clearance during the circle.
    stand = plant.AddRigidBody("stand", plant.AddModelInstance("stand"),
                               SpatialInertia(1.0, np.zeros(3), UnitInertia.SolidBox(
                                   stand_shape.width(), stand_shape.depth(), stand_top)))
    anchor = plant.AddFrame(FixedOffsetFrame(
        "stand_anchor", plant.world_frame(),
        RigidTransform(np.array([center[0], center[1], stand_top / 2]))))
    stand_slide = plant.AddJoint(PrismaticJoint("stand_slide", anchor, stand.body_frame(),
                                                [0.0, 0.0, 1.0]))
    stand_geometry = plant.RegisterCollisionGeometry(
        stand, RigidTransform(), stand_shape, "stand_collision",
        _props(STAND_FRICTION, compliant_modulus=STAND_MODULUS))
    plant.RegisterVisualGeometry(stand, RigidTransform(), stand_shape, "stand_visual",
                                 _STAND_COLOR)

    floor = Box(1.0, 1.0, 0.02)
    X_WF = RigidTransform(np.array([center[0], center[1], -0.01]))
    floor_geometry = plant.RegisterCollisionGeometry(
        plant.world_body(), X_WF, floor, "floor_collision",
        _props(mu, compliant_modulus=STAND_MODULUS))
    plant.RegisterVisualGeometry(plant.world_body(), X_WF, floor, "floor_visual", _FLOOR_COLOR)

    _set_pad_material(scene_graph, plant, pads, mu, scenario.plant.pad_modulus)
    statics = GeometrySet([stand_geometry, floor_geometry])
    manager = scene_graph.collision_filter_manager()
    manager.Apply(CollisionFilterDeclaration()
                  .ExcludeWithin(statics)
                  .ExcludeBetween(GeometrySet(pads), statics)
                  .ExcludeWithin(GeometrySet(pads)))
    return stand, stand_slide


def _add_prism(plant: MultibodyPlant, scene_graph: SceneGraph,
               scenario: Scenario) -> ContactObject:
    """:func:`add_contact_object` for ``l ≥ 3`` robots: the prism of :func:`prism_section`."""
    from pydrake.multibody.tree import CalcSpatialInertia

    pads = _pad_geometries(plant, scenario)
    r_pad = pad_radius(scene_graph, pads[0])
    points = np.array([r.contact_xy for r in scenario.robots], dtype=float)
    normals = np.array([r.normals[0][:2] for r in scenario.robots], dtype=float)
    section = prism_section(points, normals, r_pad)
    shape = _prism_shape(section, BOX_HEIGHT)
    lo, hi = section.vertices.min(axis=0), section.vertices.max(axis=0)
    size = np.array([hi[0] - lo[0], hi[1] - lo[1], BOX_HEIGHT])
    z_grasp = scenario.task.circle_top_z - scenario.task.lift_height
    center = np.array([*points.mean(axis=0), z_grasp])
    mu = scenario.plant.friction

    instance = plant.AddModelInstance("object")
    m = scenario.plant.object_mass
    area = 0.5 * abs(float(np.sum(section.vertices[:, 0] * np.roll(section.vertices[:, 1], -1)
                                  - np.roll(section.vertices[:, 0], -1)
                                  * section.vertices[:, 1])))
    box = plant.AddRigidBody("box", instance,
                             CalcSpatialInertia(shape, m / (area * BOX_HEIGHT)))
    box_geometry = plant.RegisterCollisionGeometry(box, RigidTransform(), shape,
                                                   "box_collision", _props(mu))
    plant.RegisterVisualGeometry(box, RigidTransform(), shape, "box_visual", _BOX_COLOR)
    side = STAND_WIDTH_FRACTION * 2.0 * float(section.offsets.min())
    stand, stand_slide = _add_stand_and_floor(plant, scene_graph, scenario, pads, center,
                                              Box(side, side, center[2] - BOX_HEIGHT / 2), mu)
    return ContactObject(box=box, stand=stand, size=size, X_WBox0=RigidTransform(center),
                         box_geometry=box_geometry, pad_geometries=pads,
                         stand_slide=stand_slide,
                         stand_drop=float(scenario.plant.stand_clearance),
                         face_normals=section.normals, face_offsets=section.offsets)


class PadForces(LeafSystem):
    """Every pad's contact force from the plant's contact results: the ``contact`` mode's
    ground-truth wrist force.

    .. pydrake_system::

        name: PadForces
        input_ports:
        - contact_results
        output_ports:
        - forces

    In ``contact`` mode the box is the only thing a pad touches (the pads' collisions with the
    stand, the floor and each other are filtered, and the arms have no other collision
    geometry), so the force of the object on the end effector, what Newton's law on the
    sensor's bodies gives from the weld's reaction force (:class:`~drake_coop.plant.wrist.
    WristKinematics`), is the pad's contact force itself (:meth:`ContactObject.pad_forces`):
    the plant's contact results of the step, without the reaction forces, body poses,
    velocities and accelerations.

    No event of its own: ``forces`` is computed when read. Read by a C++ ``ZeroOrderHold`` at
    the plant's own step times (period ``Δt``, offset 0: the discrete phase of every plant
    update, after the controllers' latch of their torque) it is the force of the step the
    plant takes there, from the same context as the plant's update (the step's solve is
    shared): :func:`~drake_coop.plant.ground_truth.add_pad_force_log`. A read between two
    plant updates solves a step of its own.

    With a control ``period`` of ``N = h/Δt ≥ 3`` plant steps, only the steps the ground truth
    uses are computed: those that start a tick, ``[t_k, t_k + Δt)`` (the step taken from the
    tick), and those that end one, ``[t_k − Δt, t_k)`` (the F/T sensor model's reading); at
    the ``N − 2`` steps between them ``forces`` is NaN without reading the contact results
    (each read costs a Python call into the plant's results: ~20 µs per contact in a run).
    The step is the context's time in plant steps, ``j = round(t/Δt)``: exact at the plant's
    own step times.

    Parameters
    ----------
    grasp : ContactObject
        The box and the pads' geometries (the pads in robot order).
    period, time_step : float, optional
        The control period ``h`` and the plant's step ``Δt`` (both or neither): compute only
        the steps next to a tick (above). Default: every read.

    Input ports
    -----------
    contact_results
        The plant's ``contact_results``.

    Output ports
    ------------
    forces : 3l-vector
        ``[F_1, …, F_l]``: the box's force on each pad (palm frame, N) of the step from the
        context's state (NaN at the steps skipped with a ``period``).
    """

    def __init__(self, grasp: ContactObject, period: float | None = None,
                 time_step: float | None = None):
        super().__init__()
        self._grasp = grasp
        size = 3 * len(grasp.pad_geometries)
        self._skipped = np.full(size, np.nan)
        self._dt = None if time_step is None else float(time_step)
        self._steps = None if period is None else int(round(period / time_step))
        self._results = self.DeclareAbstractInputPort(
            "contact_results", AbstractValue.Make(ContactResults()))
        self._forces = self.DeclareVectorOutputPort(
            "forces", size, self._calc_forces,
            prerequisites_of_calc={self._results.ticket(), self.time_ticket()})

    def get_contact_results_input_port(self) -> InputPort:
        """The plant's ``contact_results``."""
        return self._results

    def get_forces_output_port(self) -> OutputPort:
        """``[F_1, …, F_l]`` of the step from the context's state."""
        return self._forces

    def _calc_forces(self, context: Context, output) -> None:
        if self._steps is not None and self._steps > 2:
            j = round(context.get_time() / self._dt) % self._steps
            if 0 < j < self._steps - 1:          # a step between ticks: not used
                output.SetFromVector(self._skipped)
                return
        output.SetFromVector(self._grasp.pad_forces_vector(self._results.Eval(context)))
