"""The held object's metrics (``contact`` mode): friction-cone use per pad, the object's pose
error along the desired path, slips and drops, from the plant's truth.

A ``contact`` run logs, per robot (:func:`~drake_coop.experiment.simulate.collect_logs`):
``object_pose`` (the box's quaternion ``[w, x, y, z]`` and position, the plant's state),
``F_meas`` (the pad's contact force from the plant's contact results,
:class:`~drake_coop.plant.grasp.PadForces`, held and logged at every plant step:
:class:`~drake_coop.plant.ground_truth.PadForceLog`), its normal and tangential parts on the
box's face
``pad_normal_force``, ``pad_tangential_force`` (:func:`~drake_coop.kinematics.rotations.
pad_contact_components`), ``pad_in_object`` (the pad's centre in the box's frame) and
``pad_rotation`` (the pad body's orientation). From them, per robot and phase:

``friction_use`` (no unit)
    ``f_t / (μ f_n)`` of the pad's total contact force, on the samples where the pad presses
    (``f_n`` ≥ :data:`CONTACT_FORCE`): 1 is the edge of the friction cone; the cone margin is
    ``1 − friction_use`` (``max`` gives the smallest margin). The total force of a patch
    inside the cone is necessary, not sufficient, for sticking (the torsional friction that
    holds the box about the pad axis uses the same budget), so the margin is an upper bound.
``object_position_error`` (m), ``object_angle_error`` (rad)
    The box's centre against the desired path: the midpoint of the robots' desired
    end-effector points (28) plus the box's offset from it at the grasp tick (where the box
    rests on its stand); its rotation against its orientation at the grasp. Held phases only
    (``lift``, ``circle``, ``put_down``).
``object_turn``, ``object_tilt`` (rad)
    The box's rotation since the grasp tick split about the grasp line (:func:`turn_and_tilt`):
    ``q_rel = q₀* ⊗ q`` (the rotation in the box's frame at the grasp) = ``swing ⊗ twist``,
    the twist about the grasp line ``a`` (the turn, signed: ``2 atan2(v·a, w)``) and the swing
    about an axis normal to it (the tilt, ``2 arccos √(w² + (v·a)²)``). The grasp line is the
    line through the two pads' contact points at the grasp tick (each pad's centre projected
    on its face: ``pad_in_object`` with its x set to the face's ``±`` half width, or on its own
    face of the prism, :func:`pad_faces`), fixed in the box; with three or more pads, the
    normal of the plane through their contact points (the
    turn is then the box's rotation in that plane). The turn is the "spin" the paper's
    introduction asks the squeeze to prevent: two pads resist it only through the torsional
    friction of their contact patches. Held phases only.
``slip`` (m)
    The pad's sliding on its own face of the object since the grasp (the box's ``±x`` face on
    its side; with three or more pads the prism's face in the run's ``object_faces``), net of
    rolling: at each step the
    pad's material point at the contact (``−d n`` from the pad's centre, ``d`` the centre's
    distance to the face) moves with the pad's body and the box's point under it with the
    box; their tangential difference (box frame) is summed. Rolling (the pad is a sphere on
    a link whose orientation changes) moves neither relative to the other.
    Beside it, ``floor`` (m): :func:`creep_floor` of the run's plant step over the phase's held
    time, the sliding the simulator's friction regularization alone can give a box held
    still; a slip at or below it is not the controller's.
``slips`` (a count, ``{"count": k}``)
    Slides of :data:`SLIP_DISTANCE` each: every time the summed slip has moved that far from
    where the last count left it, one more (a continuous slide of 5 mm counts 2).
``mass_estimate_error`` (kg), ``mass_convergence_time`` (``{"time": s}``)
    With an object model (``mass_share`` logs, ``object_model`` known or estimated): the sum
    of the arms' mass shares less the true mass (held phases), and the time from the grasp
    after which it stays within :data:`MASS_TOLERANCE` of it while the box is carried, to the
    circle's end (null: never; the same in every phase). In the put-down the stand takes the
    weight back and the estimate follows it down, as it should.
``drops`` (a count)
    Episodes where the box is lost: after both pads have pressed with
    :data:`CONTACT_FORCE` for :data:`SETTLE_TIME` without a break (the grasp established:
    the pads' first touches may bounce while the squeeze ramps up from zero, the box still
    on its stand) and before the release, its position error exceeds :data:`DROP_DISTANCE`,
    or a pad stops pressing while the box is off its stand: more than :data:`REST_HEIGHT` away
    from its height at the grasp tick (where the stand carried it). A pad letting go of a box
    set down on its stand in the put-down's last moments is not a drop; one letting go at
    the circle's lowest point, over a lowered stand, is counted as soon as the box falls.
    Object-level (the same for every robot).
"""

from __future__ import annotations

import numpy as np

from drake_coop.kinematics.rotations import quaternion_rotations

__all__ = ["CONTACT_FORCE", "DROP_DISTANCE", "EVENT_METRICS", "HELD_PHASES", "MASS_TOLERANCE", "REST_HEIGHT",
           "SETTLE_TIME",
           "CREEP_RATE", "pad_faces", "SLIP_DISTANCE", "creep_floor", "grasp_axis", "object_metrics",
           "object_signals", "slip_between", "turn_and_tilt"]

#: A pad presses on the box when its normal force is at least this (N).
CONTACT_FORCE = 0.5
#: One counted slip: the pad slides this far on the box's face (m).
SLIP_DISTANCE = 2e-3
#: The creep floor's rate at a 3 ms plant step (m/s): twice the largest creep measured with the
#: path held still on ``contact.yaml``'s plant (0.5 kg, μ 1: 0.045-0.056 mm per 90 s; 1.5 kg,
#: μ 0.5: 0.087-0.089 mm per 90 s; a third of each at a 1 ms step, 0.015-0.030 mm: the creep is
#: proportional to the step, SAP's friction regularization); ``tests/results/test_creep.py``
#: keeps it above the measured creep.
CREEP_RATE = 2e-6
#: The grasp is established once both pads have pressed this long without a break (s).
SETTLE_TIME = 0.1
#: The box is dropped when its centre is this far from the desired path (m).
DROP_DISTANCE = 0.02
#: The box rests on its stand when its centre is within this of its height at the grasp (m).
REST_HEIGHT = 1e-3
#: The mass estimate has converged when the arms' shares sum to within this fraction of the
#: true mass (and stay there until the release).
MASS_TOLERANCE = 0.05
#: The phases where the box is held.
HELD_PHASES = ("lift", "circle", "put_down")
#: The object's counts and times, as :func:`object_metrics` writes them: metric name ->
#: (its one value's key, whether that value may be null). A count is an integer >= 0
#: (``{"count": k}``), a time a number of seconds or null (``{"time": s}``, null: never);
#: every other entry of a phase is ``{"rms": …, "max": …}``. A study's stored-case check
#: (:mod:`drake_coop.studies.store`) reads this table.
EVENT_METRICS = {"slips": ("count", False), "drops": ("count", False),
                 "mass_convergence_time": ("time", True)}


def creep_floor(time_step: float, duration: float) -> float:
    """The creep floor (m): how far a box held still by friction slides on the pads in
    ``duration`` seconds at plant step ``time_step`` (s), from :data:`CREEP_RATE` scaled in
    proportion to the step.

    Parameters
    ----------
    time_step : float
        The plant's step, s.
    duration : float
        The time held still, s.
    """
    return CREEP_RATE * (float(time_step) / 3e-3) * float(duration)


def _rotation_angle(R: np.ndarray) -> np.ndarray:
    """Angle of each rotation ``(K, 3, 3)`` (rad)."""
    c = 0.5 * (np.trace(R, axis1=1, axis2=2) - 1.0)
    return np.arccos(np.clip(c, -1.0, 1.0))


def _quaternion_product(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Hamilton products ``a ⊗ b`` of ``[w, x, y, z]`` rows (broadcast)."""
    aw, av = a[..., :1], a[..., 1:]
    bw, bv = b[..., :1], b[..., 1:]
    return np.concatenate([aw * bw - np.sum(av * bv, axis=-1, keepdims=True),
                           aw * bv + bw * av + np.cross(av, bv)], axis=-1)


def turn_and_tilt(quaternions: np.ndarray, k0: int, axis: np.ndarray
                  ) -> tuple[np.ndarray, np.ndarray]:
    """The box's turn about ``axis`` and its tilt since sample ``k0`` (rad).

    Parameters
    ----------
    quaternions : ndarray, shape (K, 4)
        The box's orientation ``[w, x, y, z]`` (world from box) per sample.
    k0 : int
        The reference sample (the grasp tick).
    axis : ndarray, shape (3,)
        The grasp line's direction in the box's frame (normalized here).

    Returns
    -------
    turn, tilt : ndarray, shape (K,)
        With ``q_rel = q₀* ⊗ q = (w, v)`` (sign chosen so ``w ≥ 0``) written
        ``swing ⊗ twist``, the twist about ``a`` of angle ``turn = 2 atan2(v·a, w)`` and the
        swing about an axis normal to ``a`` of angle ``tilt = 2 arccos √(w² + (v·a)²)``
        (computed as ``2 atan2(|s_v|, s_w)`` of the swing ``s``, accurate near 0):
        ``R = R₀ R_swing(tilt) R_twist(turn)``.
    """
    q = np.asarray(quaternions, dtype=float)
    q = q / np.linalg.norm(q, axis=1, keepdims=True)
    a = np.asarray(axis, dtype=float)
    a = a / np.linalg.norm(a)
    q0_conj = q[k0] * np.array([1.0, -1.0, -1.0, -1.0])
    rel = _quaternion_product(q0_conj[None, :], q)
    rel = np.where(rel[:, :1] < 0.0, -rel, rel)
    w, along = rel[:, 0], rel[:, 1:] @ a
    turn = 2.0 * np.arctan2(along, w)
    norm = np.sqrt(w * w + along * along)
    twist = np.column_stack([w, np.outer(along, a)]) / np.where(norm > 0.0, norm, 1.0)[:, None]
    swing = _quaternion_product(rel, twist * np.array([1.0, -1.0, -1.0, -1.0]))
    # atan2 of the swing's parts, not arccos of its w: accurate for small tilts too.
    tilt = 2.0 * np.arctan2(np.linalg.norm(swing[:, 1:], axis=1), np.abs(swing[:, 0]))
    return turn, tilt


def pad_faces(meta: dict, robots: list[str]) -> list[tuple[np.ndarray, float] | None]:
    """Each robot's face ``(outward normal in the object's frame, offset)`` from the run's
    ``object_faces`` (the prism of three or more pads), or None per robot for the two-pad box
    (its ``±x`` face on the pad's side, at ``object_size[0] / 2``).

    Parameters
    ----------
    meta : dict
        The run's metadata.
    robots : list of str
        The robots, in order.

    Returns
    -------
    list
        Per robot ``(normal (3,), offset in m)`` or None.
    """
    faces = meta.get("object_faces")
    if faces is None:
        return [None] * len(robots)
    return [(np.asarray(f[:3], dtype=float), float(f[3])) for f in faces]


def _on_face(c: np.ndarray, face: tuple[np.ndarray, float] | None, half_width: float
             ) -> np.ndarray:
    """A pad's centre ``c`` (object frame) projected on its face: the contact point."""
    if face is None:
        return np.array([np.copysign(half_width, c[0]), c[1], c[2]])
    n, d = face
    return c - (float(n @ c) - d) * n


def grasp_axis(pads_in_object: list[np.ndarray], half_width: float,
               faces: list[tuple[np.ndarray, float] | None] | None = None) -> np.ndarray:
    """The grasp line's unit direction in the box's frame from the pads' centres in it (each
    projected on its face: the ``±x`` face of the box, or the pad's own face ``faces[i]``,
    :func:`pad_faces`: the contact point): through the two contact points, or with three or
    more the normal of the plane through them (the smallest singular vector).

    Parameters
    ----------
    pads_in_object : list of numpy.ndarray
        The pads' centres in the object's frame (3,), m.
    half_width : float
        The box's half x size, m.
    faces : list or None
        :func:`pad_faces`' faces; None for the box's.

    Returns
    -------
    numpy.ndarray
        The unit direction (3,).
    """
    faces = [None] * len(pads_in_object) if faces is None else faces
    points = np.array([_on_face(np.asarray(c, dtype=float), f, half_width)
                       for c, f in zip(pads_in_object, faces)])
    if len(points) == 2:
        d = points[1] - points[0]
        return d / np.linalg.norm(d)
    _, _, vt = np.linalg.svd(points - points.mean(axis=0))
    return vt[-1]


def _held_window(t: np.ndarray, phases: list) -> tuple[float, float]:
    """``[t_grasp, t_release)`` from the phases."""
    span = {str(name): (a, b) for name, a, b in phases}
    return float(span["lift"][0]), float(span["put_down"][1])


def _settled(t: np.ndarray, pressing: np.ndarray) -> np.ndarray:
    """True from the first sample at which ``pressing`` has held for :data:`SETTLE_TIME`
    without a break, on."""
    out = np.zeros(t.size, dtype=bool)
    start = None
    for k in range(t.size):
        if not pressing[k]:
            start = None
            continue
        start = t[k] if start is None else start
        if t[k] - start >= SETTLE_TIME - 1e-12:
            out[k:] = True
            break
    return out


def _carried_end(phases: list) -> float:
    """The end of the carrying (the circle's end; the put-down's start if there is no circle)."""
    span = {str(name): (a, b) for name, a, b in phases}
    return float(span["circle"][1] if "circle" in span else span["put_down"][0])


def object_signals(logs: dict[str, dict[str, np.ndarray]], meta: dict
                   ) -> dict[str, dict[str, np.ndarray]] | None:
    """Per robot, the per-sample object signals (``friction_use``, ``object_position_error``,
    ``object_angle_error``, ``object_turn``, ``object_tilt``, ``slip``) and the sample indices where a slip or a drop is
    counted (``slip_events``, ``drop_events``); None without an ``object_pose`` log.

    Parameters
    ----------
    logs : dict
        ``logs[robot][array]`` of a ``contact`` run.
    meta : dict
        Run metadata: ``phases``, ``friction`` (``μ``) and ``object_size`` (the box's x, y,
        z size, m).

    Returns
    -------
    dict or None
        ``signals[robot][name]``, or None.
    """
    robots = [r for r, log in logs.items() if "object_pose" in log]
    if not robots or len(robots) != len(logs):
        return None
    mu = float(meta["friction"])
    first = logs[robots[0]]
    t = np.asarray(first["t"], dtype=float)
    K = t.size
    pose = np.asarray(first["object_pose"], dtype=float)
    t_grasp, t_release = _held_window(t, meta["phases"])
    held = (t >= t_grasp) & (t < t_release)
    out: dict[str, dict[str, np.ndarray]] = {}
    if K == 0:
        return {r: {} for r in robots}
    # Pose error: the box against the robots' desired midpoint + the offset at the grasp tick.
    mid_d = np.mean([np.asarray(logs[r]["x_d"], dtype=float) for r in robots], axis=0)
    k0 = int(np.searchsorted(t, t_grasp - 1e-9))
    position_error = np.full(K, np.nan)
    angle_error = np.full(K, np.nan)
    turn = np.full(K, np.nan)
    tilt = np.full(K, np.nan)
    R_B = quaternion_rotations(pose[:, :4])
    if k0 < K:
        offset = pose[k0, 4:7] - mid_d[k0]
        position_error = np.linalg.norm(pose[:, 4:7] - mid_d - offset, axis=1)
        angle_error = _rotation_angle(np.einsum("ji,kjl->kil", R_B[k0], R_B))
        position_error[~held] = np.nan
        angle_error[~held] = np.nan
        if all("pad_in_object" in logs[r] for r in robots):
            axis = grasp_axis([np.asarray(logs[r]["pad_in_object"], dtype=float)[k0]
                               for r in robots], 0.5 * float(meta["object_size"][0]),
                              pad_faces(meta, robots))
            turn, tilt = turn_and_tilt(pose[:, :4], k0, axis)
            turn[~held] = np.nan
            tilt[~held] = np.nan
    normals = {r: np.asarray(logs[r]["pad_normal_force"], dtype=float) for r in robots}
    pressing = np.all([normals[r] >= CONTACT_FORCE for r in robots], axis=0)
    established = held & _settled(t, held & pressing)
    resting = np.zeros(K, dtype=bool)
    if k0 < K:
        resting = np.abs(pose[:, 6] - pose[k0, 6]) <= REST_HEIGHT
    lost = established & ((~pressing & ~resting) | (position_error > DROP_DISTANCE))
    drop_events = np.flatnonzero(lost & ~np.concatenate([[False], lost[:-1]]))
    for r, face in zip(robots, pad_faces(meta, robots)):
        log = logs[r]
        f_n = normals[r]
        f_t = np.asarray(log["pad_tangential_force"], dtype=float)
        with np.errstate(invalid="ignore", divide="ignore"):
            use = np.where(f_n >= CONTACT_FORCE, f_t / (mu * f_n), np.nan)
        slip, slip_events = _slip(log, R_B, pose, established,
                                  0.5 * float(meta["object_size"][0]), face)
        out[r] = {"friction_use": use, "object_position_error": position_error,
                  "object_angle_error": angle_error, "object_turn": turn,
                  "object_tilt": tilt, "slip": slip,
                  "slip_events": slip_events, "drop_events": drop_events}
    if all("mass_share" in logs[r] for r in robots) and "object_mass" in meta:
        m = float(meta["object_mass"])
        estimate = np.sum([np.asarray(logs[r]["mass_share"], dtype=float) for r in robots],
                          axis=0)
        error = np.where(held, estimate - m, np.nan)
        ok = np.abs(estimate - m) <= MASS_TOLERANCE * m
        # The first carried sample after which the estimate stays within the tolerance. The
        # carried window ends with the circle: in the put-down the stand takes the box's
        # weight back from the arms, and their estimate rightly follows it down.
        carried = held & (t < _carried_end(meta["phases"]))
        bad = np.flatnonzero(carried & ~ok)
        after = t >= t_grasp
        converged: float | None = None
        if after.any() and bad.size == 0:
            converged = 0.0
        elif after.any() and bad[-1] + 1 < K and carried[bad[-1] + 1]:
            converged = float(t[bad[-1] + 1] - t_grasp)
        for r in robots:
            out[r]["mass_error"] = error
            out[r]["mass_convergence_time"] = converged
    return out


def _slip(log: dict[str, np.ndarray], R_B: np.ndarray, pose: np.ndarray,
          established: np.ndarray, half_width: float,
          face: tuple[np.ndarray, float] | None = None) -> tuple[np.ndarray, np.ndarray]:
    """The pad's summed sliding on the box's face (m, NaN outside the established grasp) and
    the samples where a :data:`SLIP_DISTANCE` slide is counted (see the module). ``face``:
    the pad's own face (outward normal in the object's frame, offset), :func:`pad_faces`;
    None for the box's ``±x`` face on the pad's side at ``half_width``."""
    K = R_B.shape[0]
    slip = np.full(K, np.nan)
    if "pad_rotation" not in log or not established.any():
        return slip, np.zeros(0, dtype=int)
    E = np.asarray(log["x"], dtype=float)
    R_P = np.asarray(log["pad_rotation"], dtype=float).reshape(K, 3, 3)
    p_B = np.asarray(log["pad_in_object"], dtype=float)
    p = pose[:, 4:7]
    ks = np.flatnonzero(established)
    total, ref = np.zeros(2), np.zeros(2)
    if face is not None:
        # Two unit vectors spanning the face (object frame): its tangent plane.
        n_B, d_B = face
        u = np.cross([0.0, 0.0, 1.0], n_B)
        u = u / np.linalg.norm(u) if np.linalg.norm(u) > 1e-9 else np.array([1.0, 0.0, 0.0])
        T_B = np.array([u, np.cross(n_B, u)])
    events = []
    slip[ks[0]] = 0.0
    for a, b in zip(ks[:-1], ks[1:]):
        if b == a + 1:
            if face is None:
                side = 1.0 if p_B[a, 0] >= 0.0 else -1.0
                n = side * R_B[a][:, 0]                   # the face's outward normal
                c = -(abs(p_B[a, 0]) - half_width) * n    # pad centre → contact point
            else:
                n = R_B[a] @ n_B
                c = -(float(n_B @ p_B[a]) - d_B) * n
            pad_point = E[b] + R_P[b] @ (R_P[a].T @ c)    # the pad's material point, moved
            box_point = p[b] + R_B[b] @ (R_B[a].T @ (E[a] + c - p[a]))   # the box's point
            d = R_B[b].T @ (pad_point - box_point)
            total = total + (d[1:] if face is None else T_B @ d)          # along the face
            while np.linalg.norm(total - ref) >= SLIP_DISTANCE:
                ref = ref + SLIP_DISTANCE * (total - ref) / np.linalg.norm(total - ref)
                events.append(b)
        slip[b] = np.linalg.norm(total)
    return slip, np.asarray(events, dtype=int)


def slip_between(logs: dict[str, dict[str, np.ndarray]], meta: dict, t0: float, t1: float
                 ) -> dict[str, float]:
    """Each pad's sliding on the box from ``t0`` to ``t1`` (m): the ``slip`` of the module
    summed over the samples in ``[t0, t1]`` only (from the plant's logged poses, net of
    rolling). With the path held still, this is the box's creep against the pads.

    Parameters
    ----------
    logs : dict
        ``logs[robot][array]`` of a ``contact`` run.
    meta : dict
        The run's metadata.
    t0, t1 : float
        The interval, s.

    Returns
    -------
    dict of str to float
        Robot → its pad's sliding, m.
    """
    robots = list(logs)
    first = logs[robots[0]]
    t = np.asarray(first["t"], dtype=float)
    pose = np.asarray(first["object_pose"], dtype=float)
    window = (t >= t0 - 1e-12) & (t <= t1 + 1e-12)
    R_B = quaternion_rotations(pose[:, :4])
    half = 0.5 * float(meta["object_size"][0])
    out = {}
    for r, face in zip(robots, pad_faces(meta, robots)):
        slip, _ = _slip(logs[r], R_B, pose, window, half, face)
        out[r] = float(slip[np.flatnonzero(window)[-1]]) if window.any() else 0.0
    return out


def object_metrics(logs: dict[str, dict[str, np.ndarray]], meta: dict,
                   masks: dict[str, np.ndarray]) -> dict[str, dict[str, dict]]:
    """``metrics[robot][phase]`` entries of the object (see the module); {} without an
    ``object_pose`` log.

    Parameters
    ----------
    logs : dict
        ``logs[robot][array]``.
    meta : dict
        ``phases``, ``friction``, ``object_size``.
    masks : dict
        ``phase -> mask`` of the samples (:func:`~drake_coop.results.metrics.phase_masks`).
    """
    signals = object_signals(logs, meta)
    if signals is None:
        return {}
    t = np.asarray(next(iter(logs.values()))["t"], dtype=float)
    step = meta.get("plant_time_step")
    units = {"friction_use": "", "object_position_error": "m", "object_angle_error": "rad",
             "object_turn": "rad", "object_tilt": "rad", "slip": "m"}
    out: dict[str, dict[str, dict]] = {}
    for robot, sig in signals.items():
        per_phase = {}
        for phase, mask in masks.items():
            entry: dict = {}
            for name, unit in units.items():
                if name not in sig:
                    continue
                x = sig[name][mask]
                x = x[np.isfinite(x)]
                if x.size:
                    entry[name] = {"rms": float(np.sqrt(np.mean(x ** 2))),
                                   "max": float(np.max(np.abs(x))), "unit": unit}
                    if name == "slip" and step is not None:
                        held = t[mask & np.isfinite(sig[name])]
                        entry[name]["floor"] = creep_floor(step, float(held[-1] - held[0]))
            if "mass_error" in sig:
                x = sig["mass_error"][mask]
                x = x[np.isfinite(x)]
                if x.size:
                    entry["mass_estimate_error"] = {"rms": float(np.sqrt(np.mean(x ** 2))),
                                                    "max": float(np.max(np.abs(x))),
                                                    "unit": "kg"}
                key = EVENT_METRICS["mass_convergence_time"][0]
                entry["mass_convergence_time"] = {key: sig["mass_convergence_time"],
                                                  "unit": "s"}
            index = np.flatnonzero(mask)
            for name in ("slips", "drops"):
                events = sig.get(f"{name[:-1]}_events", np.zeros(0, dtype=int))
                entry[name] = {EVENT_METRICS[name][0]: int(np.isin(events, index).sum()),
                               "unit": "events"}
            per_phase[phase] = entry
        out[robot] = per_phase
    return out
