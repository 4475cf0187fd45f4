"""What Meshcat shows beyond the plant's geometry: force arrows and the held object.

:class:`ForceArrows` is a LeafSystem that publishes (30 Hz by default), for each robot i, three
arrows at its end-effector point ``p_E = fk(q)``:

* desired ``−N_iᵀ λ_d`` (green), from the reference (29);
* measured ``−F_meas`` (red), the ground-truth wrist force (never read by the controllers);
* estimated ``−N_iᵀ λ̂`` (blue), the force observer (22);

each the force the end effector exerts *on the object* (palm frame): the rows of ``N_i``
(``arm.N``, m_i × 3) are the object's outward unit normals at contact i, and ``N_iᵀ λ`` is the
object's force on the end effector (Decision 1), so a squeeze (λ > 0) draws arrows pointing
into the object. For the paper (m_i = 1) ``N_i = n_iᵀ = (s_i, 0, 0)`` and the arrows are
``−λ n_i``. λ_d and the held flag are read from the reference vector through its
:class:`~drake_coop.control.reference_layout.ReferenceLayout` (``3 n_i + m_i + 1`` rows). An arrow of
force F ends at ``p_E + o_k`` (``o_k`` a small vertical offset per kind so the three stay
apart) and starts at ``p_E + o_k − scale · F``: it pushes on the pad from outside the object,
so a squeeze's arrows are never hidden inside the held box (5 mm per newton by default: 12 cm
for the paper's 24 N). In ``planes`` mode it also draws the held
object while the reference says it is held: for two robots a translucent box between the two
pads (facing each other along x, the paper's geometry), for three or more a translucent
vertical disc touching every pad (:func:`held_disc_pose`).

Each Meshcat call passes the context time as ``time_in_recording``: when the Meshcat records
(the HTML replay), the arrows are recorded in the same animation as the arms; otherwise they
are drawn live.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np
from pydrake.geometry import Box, Cylinder, MeshcatCone, Rgba
from pydrake.math import RigidTransform, RollPitchYaw, RotationMatrix
from pydrake.systems.framework import DiagramBuilder, LeafSystem
from pydrake.systems.primitives import Demultiplexer

from drake_coop.control.reference_layout import ReferenceLayout
from drake_coop.plant.arms import Arm

if TYPE_CHECKING:
    from pydrake.geometry import Meshcat
    from pydrake.systems.framework import Context, OutputPort

    from drake_coop.plant.cooperative import CoopPlant

__all__ = ["ARROW_KINDS", "ForceArrows", "add_force_arrows", "arrow_pose", "frame_workspace",
           "held_box_pose", "held_disc_pose", "workspace_camera"]

#: name: (colour RGBA, vertical offset of the tail from p_E in m).
ARROW_KINDS: dict[str, tuple[tuple[float, float, float, float], float]] = {
    "desired": ((0.1, 0.75, 0.2, 0.9), 0.025),
    "measured": ((0.9, 0.15, 0.1, 0.9), 0.0),
    "estimated": ((0.15, 0.35, 0.95, 0.9), -0.025),
}
ROOT = "/drake/coop"
"""Meshcat path of the drawings (under ``/drake``, so ``Meshcat.Delete()`` clears them)."""
HEAD_LENGTH = 0.015
"""Length of an arrow's head (m); the shaft is the rest of ``scale · |F|``."""
SHAFT_RADIUS = 0.004
MIN_LENGTH = 1e-3
"""Arrows shorter than this (m) are hidden."""
ARROW_SCALE = 0.005
"""Metres of arrow per newton (the paper's 24 N squeeze: 12 cm, visible beside 0.5 m arms)."""
BOX_SECTION = 0.06
"""Height and depth of the planes mode's held box, height of the held disc (m)."""
PAD_RADIUS = 0.015
"""Radius of the shipped arms' spherical pads (m), for arms without closed-form geometry."""
SURROUND = 1.6
"""Camera distance factor for three or more arms around the target (:func:`workspace_camera`)."""


def arrow_pose(p_tail: np.ndarray, F: np.ndarray, scale: float
               ) -> tuple[RigidTransform, float]:
    """Pose and length of an arrow drawn along its frame's +z axis.

    Parameters
    ----------
    p_tail : ndarray, shape (3,)
        Where the arrow starts (palm frame, m).
    F : ndarray, shape (3,)
        The force (N).
    scale : float
        Metres per newton.

    Returns
    -------
    (X_WA, L) : (RigidTransform, float)
        ``X_WA`` has its origin at ``p_tail`` and its z axis along ``F``; the tip is at
        ``X_WA · (0, 0, L)`` with ``L = scale |F|``.
    """
    F = np.asarray(F, dtype=float)
    L = scale * float(np.linalg.norm(F))
    if L == 0.0:
        return RigidTransform(np.asarray(p_tail, dtype=float)), 0.0
    return RigidTransform(RotationMatrix.MakeFromOneVector(F / np.linalg.norm(F), 2),
                          np.asarray(p_tail, dtype=float)), L


def held_box_pose(p_E1: np.ndarray, p_E2: np.ndarray, r_pad: float
                  ) -> tuple[np.ndarray, np.ndarray]:
    """Centre and size of the box held between two pads facing each other along x.

    The box spans the gap between the pads' surfaces: its x size is ``|x_2 − x_1| − 2 r_pad``,
    its centre is the midpoint of the two end-effector points (``planes`` mode: the pads'
    centres lie on the planes ``x = b_i``).

    Parameters
    ----------
    p_E1, p_E2 : numpy.ndarray
        The two end-effector points (3,), m, palm frame.
    r_pad : float
        The pads' radius, m.

    Returns
    -------
    (centre, size) : (ndarray, ndarray), each shape (3,)
        The box's centre and size, m.
    """
    p1, p2 = np.asarray(p_E1, dtype=float), np.asarray(p_E2, dtype=float)
    width = max(abs(p2[0] - p1[0]) - 2 * r_pad, 1e-3)
    return 0.5 * (p1 + p2), np.array([width, BOX_SECTION, BOX_SECTION])


def held_disc_pose(points: list[np.ndarray], r_pad: float) -> tuple[np.ndarray, float]:
    """Centre and radius of a vertical disc held by three or more pads around it.

    The centre is the mean of the end-effector points; the radius is their mean horizontal
    distance from it minus the pad radius, so that the disc's rim touches each pad's surface
    when the pads stand on a circle (the three-arm scenario).

    Parameters
    ----------
    points : list of numpy.ndarray
        The end-effector points (3,), m, palm frame.
    r_pad : float
        The pads' radius, m.

    Returns
    -------
    (centre, radius) : (ndarray shape (3,), float)
        The disc's centre and radius, m.
    """
    p = np.asarray(points, dtype=float)
    centre = p.mean(axis=0)
    reach = np.linalg.norm(p[:, :2] - centre[:2], axis=1).mean()
    return centre, max(float(reach) - r_pad, 1e-3)


def workspace_camera(arms: list[Arm], z_target: float) -> tuple[np.ndarray, np.ndarray]:
    """A camera position and target that frame every arm and the space between them.

    The target is the mean of the bases at height ``z_target``; the camera looks from the
    front-right (−y, +x), above, at a distance proportional to ``d = max(2 r, 0.5 m)``, ``r``
    the largest horizontal distance of a base from the target. Two arms facing each other (the
    paper) give ``d`` = the distance between their bases. Three or more arms stand around the
    target, one of them between it and the camera: the distance is ``1.6 d`` then.

    Parameters
    ----------
    arms : list of Arm
        The arms.
    z_target : float
        The target's height, m.

    Returns
    -------
    (camera_in_world, target_in_world) : (ndarray, ndarray)
        The camera's position and target (3,), m.
    """
    bases = np.array([a.p_base for a in arms])
    target = bases.mean(axis=0)
    target[2] = z_target
    r = float(np.max(np.linalg.norm(bases[:, :2] - target[:2], axis=1)))
    spread = max(2.0 * r, 0.5) * (1.0 if len(arms) <= 2 else SURROUND)
    return target + spread * np.array([0.35, -0.95, 0.35]), target


class ForceArrows(LeafSystem):
    """Draws force arrows at each end effector (and the held object) in Meshcat.

    Input ports (per robot ``<name>``, with ``n`` joints and ``m`` constraints)
    ---------------------------------------------------------------------------
    <name>_state : 2n-vector
        The arm's plant state ``[q, v]`` (the end-effector point is ``fk(q)``).
    <name>_reference : (3n + m + 1)-vector
        The robot's reference ``[q_d, q̇_d, q̈_d, λ_d, held]``
        (:class:`~drake_coop.control.reference_layout.ReferenceLayout`).
    <name>_F_meas : 3-vector
        Ground-truth force on the end effector (N).
    <name>_lambda_hat : m-vector
        The force observer's estimate λ̂ (N).

    Parameters
    ----------
    meshcat : pydrake.geometry.Meshcat
        The viewer.
    arms : list[Arm]
        The robots; ``m`` of each is its number of normals (``arm.N`` rows).
    n_joints : list[int], optional
        Joints of each arm (default: the size of its joint limits, ``arm.q_min``).
    scale : float
        Metres of arrow per newton.
    show_held_box : bool
        Draw the held object while held (``planes`` mode): a box between two pads, a disc
        among three or more.
    publish_period : float
        Seconds between drawings.
    """

    def __init__(self, meshcat: Meshcat, arms: list[Arm], *, n_joints: list[int] | None = None,
                 scale: float = ARROW_SCALE, show_held_box: bool = False,
                 publish_period: float = 1 / 30) -> None:
        super().__init__()
        self._meshcat = meshcat
        self._arms = arms
        self._scale = scale
        self._show_held_box = show_held_box
        if n_joints is None:
            n_joints = [int(np.size(arm.q_min)) for arm in arms]
        self._layouts = [ReferenceLayout(n, arm.m) for n, arm in zip(n_joints, arms)]
        self._r_pad = next((a.geometry.r_pad for a in arms if a.geometry is not None),
                           PAD_RADIUS)
        self._ports = []
        for arm, layout in zip(arms, self._layouts):
            self._ports.append({
                "state": self.DeclareVectorInputPort(f"{arm.name}_state", 2 * layout.n),
                "reference": self.DeclareVectorInputPort(f"{arm.name}_reference", layout.size),
                "F_meas": self.DeclareVectorInputPort(f"{arm.name}_F_meas", 3),
                "lambda_hat": self.DeclareVectorInputPort(f"{arm.name}_lambda_hat", layout.m),
            })
        self.DeclarePeriodicPublishEvent(publish_period, 0.0, self._publish)
        self.DeclareInitializationPublishEvent(self._publish)
        self._set_objects()

    # ------------------------------------------------------------------ scene
    def _set_objects(self) -> None:
        """Unit geometry, scaled and posed at each publish: per arrow a shaft (a unit
        cylinder from z = 0 to 1 under a node scaled along z) and a head (a cone)."""
        m = self._meshcat
        m.Delete(ROOT)
        for arm in self._arms:
            for kind, (rgba, _) in ARROW_KINDS.items():
                path = f"{ROOT}/forces/{arm.name}/{kind}"
                colour = Rgba(*rgba)
                m.SetObject(f"{path}/shaft/unit", Cylinder(SHAFT_RADIUS, 1.0), colour)
                m.SetTransform(f"{path}/shaft/unit", RigidTransform([0.0, 0.0, 0.5]))
                m.SetObject(f"{path}/head/cone", MeshcatCone(HEAD_LENGTH, 2.5 * SHAFT_RADIUS,
                                                             2.5 * SHAFT_RADIUS), colour)
                # The cone's apex is at its origin, opening along +z: flip it to point up.
                m.SetTransform(f"{path}/head/cone", RigidTransform(
                    RollPitchYaw(np.pi, 0.0, 0.0), [0.0, 0.0, 0.0]))
                m.SetProperty(path, "visible", False)
        if self._show_held_box:
            shape = Box(1.0, 1.0, 1.0) if len(self._arms) <= 2 else Cylinder(1.0, 1.0)
            m.SetObject(f"{ROOT}/held_object/scaled/unit", shape, Rgba(0.85, 0.65, 0.25, 0.45))
            m.SetProperty(f"{ROOT}/held_object", "visible", False)

    # ------------------------------------------------------------------ publishing
    def forces(self, context: Context, i: int) -> dict[str, np.ndarray]:
        """Robot i's force on the object (N, palm frame): desired ``−N_iᵀ λ_d``, measured
        ``−F_meas``, estimated ``−N_iᵀ λ̂``.

        Parameters
        ----------
        context : Context
            This system's context.
        i : int
            The robot's index.

        Returns
        -------
        dict of str to numpy.ndarray
            ``desired``, ``measured``, ``estimated`` (3,), N.
        """
        ports = self._ports[i]
        N = self._arms[i].N
        rows = self._layouts[i].slices()
        lambda_d = np.asarray(ports["reference"].Eval(context), dtype=float)[rows["lambda_d"]]
        lambda_hat = np.asarray(ports["lambda_hat"].Eval(context), dtype=float)
        return {"desired": -(N.T @ lambda_d),
                "measured": -np.asarray(ports["F_meas"].Eval(context), dtype=float),
                "estimated": -(N.T @ lambda_hat)}

    def held(self, context: Context) -> bool:
        """Whether the first robot's reference says the object is held.

        Parameters
        ----------
        context : Context
            This system's context.
        """
        return self._layouts[0].held(self._ports[0]["reference"].Eval(context))

    def ee_point(self, context: Context, i: int) -> np.ndarray:
        """End-effector point ``fk(q)`` of robot i (palm frame).

        Parameters
        ----------
        context : Context
            This system's context.
        i : int
            The robot's index.

        Returns
        -------
        numpy.ndarray
            The point (3,), m.
        """
        n = self._layouts[i].n
        return self._arms[i].fk(self._ports[i]["state"].Eval(context)[:n])

    def _publish(self, context: Context) -> None:
        m, t = self._meshcat, context.get_time()
        points = []
        for i, arm in enumerate(self._arms):
            p_E = self.ee_point(context, i)
            points.append(p_E)
            for kind, F in self.forces(context, i).items():
                path = f"{ROOT}/forces/{arm.name}/{kind}"
                offset = np.array([0.0, 0.0, ARROW_KINDS[kind][1]])
                # The tip on the pad, the tail outside the object.
                X, L = arrow_pose(p_E + offset - self._scale * np.asarray(F), F, self._scale)
                visible = L >= MIN_LENGTH
                m.SetProperty(path, "visible", visible, t)
                if not visible:
                    continue
                shaft = max(L - HEAD_LENGTH, 1e-6)
                m.SetTransform(path, X, t)
                m.SetProperty(f"{path}/shaft", "scale", [1.0, 1.0, shaft], t)
                m.SetTransform(f"{path}/head", RigidTransform([0.0, 0.0, L]), t)
        if self._show_held_box:
            held = self.held(context)
            m.SetProperty(f"{ROOT}/held_object", "visible", held, t)
            if held:
                if len(points) <= 2:
                    centre, size = held_box_pose(points[0], points[-1], self._r_pad)
                else:
                    centre, radius = held_disc_pose(points, self._r_pad)
                    size = np.array([radius, radius, BOX_SECTION])
                m.SetTransform(f"{ROOT}/held_object", RigidTransform(centre), t)
                m.SetProperty(f"{ROOT}/held_object/scaled", "scale", list(size), t)


def _named(builder: DiagramBuilder, name: str):
    """The builder's system called ``name``, or None."""
    return next((s for s in builder.GetSystems() if s.get_name() == name), None)


def _logged_source(builder: DiagramBuilder, robot: str, key: str) -> OutputPort:
    """The output port that feeds the logged signal ``key`` of ``robot`` (an input of its
    ``<robot>_log_signals`` Multiplexer, in the order of
    :data:`~drake_coop.experiment.diagram.LOG_KEYS`, without
    :data:`~drake_coop.experiment.diagram.GROUND_TRUTH_KEYS` when the ground truth is computed
    after the run)."""
    from drake_coop.experiment.diagram import GROUND_TRUTH_KEYS, LOG_KEYS

    mux = builder.GetSubsystemByName(f"{robot}_log_signals")
    keys = list(LOG_KEYS)        # first in the Multiplexer (the object's signals follow)
    if (_named(builder, "ground_truth_log") is not None        # the offline ground truth
            or _named(builder, "pad_forces_log") is not None):
        live_ft = _named(builder, f"{robot}_ft_sensor") is not None
        keys = [k for k in keys
                if k not in GROUND_TRUTH_KEYS or (k == "lambda_sensor" and live_ft)]
    index = keys.index(key)
    for (system, port), (source, out_index) in builder.connection_map().items():
        if system is mux and int(port) == index:
            return source.get_output_port(out_index)
    raise KeyError(f"{robot}'s logged {key} is not connected")


def add_force_arrows(builder: DiagramBuilder, coop: CoopPlant, meshcat: Meshcat, *,
                     scale: float = ARROW_SCALE, publish_period: float = 1 / 30) -> ForceArrows:
    """Add :class:`ForceArrows` to an experiment's builder, fed by the robots' logged signals.

    Call it from ``build_experiment``'s ``before_build`` hook (the logged ``reference`` and
    ``lambda_hat`` of each robot must exist, i.e. ``log=True``). ``F_meas`` is the logged
    live ground truth's or, when the ground truth is computed after the run, the
    ``wrist_forces_at_tick`` system's ``<robot>_F_step`` (the same force of the step from the
    last tick, evaluated only when the arrows are drawn); in ``contact`` mode the pad's force
    of the last plant step, from the ground truth's ``pad_forces_hold`` (split per pad by
    ``pad_forces_split``).

    Parameters
    ----------
    builder : DiagramBuilder
        The experiment's builder, not yet built.
    coop : CoopPlant
        The cooperative plant (arms, object mode).
    meshcat : pydrake.geometry.Meshcat
        The viewer.
    scale : float
        Metres of arrow per newton.
    publish_period : float
        Seconds between drawings.

    Returns
    -------
    ForceArrows
        The system added.
    """
    arms = [h.arm for h in coop.arms]
    arrows = builder.AddNamedSystem("force_arrows", ForceArrows(
        meshcat, arms, n_joints=[coop.plant.num_positions(h.instance) for h in coop.arms],
        scale=scale, show_held_box=coop.mode == "planes", publish_period=publish_period))
    # contact mode: the pads' forces of the last plant step, from the ground truth's hold
    held = _named(builder, "pad_forces_hold")
    pads = None
    if held is not None:
        pads = builder.AddNamedSystem("pad_forces_split",
                                      Demultiplexer(held.get_output_port().size(), 3))
        builder.Connect(held.get_output_port(), pads.get_input_port())
    for i, h in enumerate(coop.arms):
        name = h.arm.name
        builder.Connect(coop.plant.get_state_output_port(h.instance),
                        arrows.GetInputPort(f"{name}_state"))
        for key in ("reference", "lambda_hat"):
            builder.Connect(_logged_source(builder, name, key),
                            arrows.GetInputPort(f"{name}_{key}"))
        offline = _named(builder, "wrist_forces_at_tick")
        if pads is not None:
            force = pads.get_output_port(i)
        elif offline is not None:
            force = offline.GetOutputPort(f"{name}_F_step")
        else:
            force = _logged_source(builder, name, "F_meas")
        builder.Connect(force, arrows.GetInputPort(f"{name}_F_meas"))
    return arrows


def frame_workspace(meshcat: Meshcat, arms: list[Arm], z_target: float) -> None:
    """Point Meshcat's camera at every arm and the space between them
    (:func:`workspace_camera`); the HTML replay opens with this view.

    Parameters
    ----------
    meshcat : Meshcat
        The viewer.
    arms : list of Arm
        The arms.
    z_target : float
        The target's height, m.
    """
    camera, target = workspace_camera(arms, z_target)
    meshcat.SetCameraPose(camera, target)
