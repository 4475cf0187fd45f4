"""Failure guards: what a user calls a failed run, checked on the plant's truth.

A run can stay finite and within its joint limits while the task has failed: the pads far
from their path, the held box tilted or off its path, the squeeze far from its reference, the
grasp lost. :class:`FailureCheck` checks these on samples fed in time order, each against its
``guards`` field (:class:`~drake_coop.scenario.schema.Guards`):

``max_pad_error`` (m)
    Every robot's pad (its end-effector point ``x(q)``) against its desired path:
    ``‖x − x_d‖``, the whole run.
``max_squeeze_error`` (N)
    The measured squeeze against the desired one, ``‖λ − λ_d‖`` (the norm of the constraint
    rows), while the object is held, from :data:`SQUEEZE_SETTLE` after the grasp to the
    release (the squeeze ramps up from zero at the grasp).
``max_object_tilt_deg`` (degrees), ``contact`` mode
    The box's swing since the grasp about an axis normal to the grasp line (the line through
    the pads' contact points at the grasp, fixed in the box; with three or more pads, the
    normal of their plane): ``2 atan2(‖v_⊥‖, |w|)`` of ``q₀* ⊗ q`` less its twist about that
    line. The same quantity as the run's ``object_tilt`` metric
    (:func:`~drake_coop.results.object_metrics.turn_and_tilt`), computed here independently.
    Held phases.
``max_object_position_error`` (m), ``contact`` mode
    The box's centre against the robots' desired midpoint plus its offset from it at the
    grasp. Held phases.
``grasp_lost`` (true/false), ``contact`` mode
    Once every pad has pressed with at least :data:`CONTACT_FORCE` for :data:`SETTLE_TIME`
    without a break (the grasp established), a pad that stops pressing while the box is off
    its stand (more than :data:`REST_HEIGHT` from its height at the grasp) before the
    release. The thresholds are those of the run's ``drops`` metric.

During the simulation the runner feeds one sample per guard chunk from the plant's state
(:func:`~drake_coop.experiment.simulate.simulate`), so a run stops within ``check_period`` of
its failure; after the run it checks every logged tick (:func:`first_failure_in_logs`, the
same rules on the arrays at once), so that no run whose logs pass a guard's bound between two
chunks is called completed. The first
failure ends the run with ``status = "failed"`` and :attr:`Failure.message`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from drake_coop.kinematics.rotations import pad_contact_components, quaternion_rotations
from drake_coop.scenario.schema import Guards

__all__ = ["CONTACT_FORCE", "REST_HEIGHT", "SETTLE_TIME", "SQUEEZE_SETTLE", "Failure",
           "FailureCheck", "GraspSample", "SUMMARY_PHASES", "failure_check",
           "first_failure_in_logs", "plant_sample", "summary_failure", "tilt_about_line"]

#: A pad presses on the box when its normal force is at least this (N); as the ``drops``
#: metric's.
CONTACT_FORCE = 0.5
#: The grasp is established once every pad has pressed this long without a break (s).
SETTLE_TIME = 0.1
#: The box rests on its stand within this of its height at the grasp (m).
REST_HEIGHT = 1e-3
#: The squeeze is checked from this long after the grasp (s): it ramps up from zero there.
SQUEEZE_SETTLE = 0.5


@dataclass
class Failure:
    """The first failure a guard saw.

    Attributes
    ----------
    guard : str
        The ``guards`` field that tripped (``max_pad_error``, ...).
    who : str
        The robot's name, or ``box``.
    t : float
        The sample's time, s.
    value, limit : float
        The quantity and its bound, in the field's unit (m, N, degrees; 1 and 0 for
        ``grasp_lost``).
    text : str
        What the quantity is, with its value.
    """

    guard: str
    who: str
    t: float
    value: float
    limit: float
    text: str

    @property
    def message(self) -> str:
        """One line: ``failed at t = … s: <who> <quantity> (guards.<field> = …)``."""
        return f"failed at t = {self.t:.3f} s: {self.who} {self.text}"

    def as_dict(self) -> dict:
        """The failure as ``run.json`` records it.

        Returns
        -------
        dict
            ``guard``, ``who``, ``t``, ``value``, ``limit``.
        """
        return {"guard": self.guard, "who": self.who, "t": self.t, "value": self.value,
                "limit": self.limit}


@dataclass
class GraspSample:
    """One sample of what the guards read, at time ``t`` (palm frame, SI units).

    Attributes
    ----------
    t : float
        Time, s.
    x, x_d : list of numpy.ndarray
        Each robot's pad point and its desired point (3,).
    lam, lam_d : list of numpy.ndarray
        Each robot's measured and desired squeeze (m_i,); None without a held object.
    pose : numpy.ndarray or None
        The box's ``[w, x, y, z]`` quaternion and position (7,) (``contact`` mode).
    F : list of numpy.ndarray or None
        Each pad's contact force from the box (3,) (``contact`` mode).
    """

    t: float
    x: list
    x_d: list
    lam: list | None = None
    lam_d: list | None = None
    pose: np.ndarray | None = None
    F: list | None = None


def tilt_about_line(q0: np.ndarray, q: np.ndarray, axis: np.ndarray) -> float:
    """The swing angle of the rotation from ``q0`` to ``q`` about axes normal to ``axis``.

    Parameters
    ----------
    q0, q : numpy.ndarray
        Unit quaternions ``[w, x, y, z]`` (4,) of the body at the grasp and now (world frame).
    axis : numpy.ndarray
        A unit direction (3,) fixed in the body.

    Returns
    -------
    float
        The tilt, rad, in ``[0, π]``: ``q_rel = q0* ⊗ q = swing ⊗ twist``, the twist about
        ``axis`` and the swing about a normal to it; the swing's angle.
    """
    w0, v0 = q0[0], -np.asarray(q0[1:], dtype=float)
    w1, v1 = q[0], np.asarray(q[1:], dtype=float)
    w = w0 * w1 - v0 @ v1
    v = w0 * v1 + w1 * v0 + np.cross(v0, v1)
    a = np.asarray(axis, dtype=float)
    along = float(v @ a)
    # |w_swing| = sqrt(w² + along²); its vector part's norm = sqrt(|v|² − along²).
    return float(2.0 * math.atan2(math.sqrt(max(float(v @ v) - along * along, 0.0)),
                                  math.sqrt(w * w + along * along)))


@dataclass
class FailureCheck:
    """The failure guards of one run, fed samples in time order (see the module docstring).

    Parameters
    ----------
    guards : Guards
        The bounds.
    robots : list of str
        The robots' names.
    t_grasp, t_release : float
        The held window ``[t_grasp, t_release)``, s.
    contact : bool
        Whether the box is a free body held by friction (``contact`` mode).
    half_width : float
        Half the box's x size (m): the two-pad box's faces are at ``±half_width``.
    faces : list of (numpy.ndarray, float) or None
        Three or more pads: each pad's face, its outward unit normal (3,) in the box frame
        and its offset from the frame's origin (m); None for the two-pad box.
    squeeze : bool
        Whether the squeeze is checked (an object is held: every ``object_mode`` but
        ``none``).
    """

    guards: Guards
    robots: list
    t_grasp: float
    t_release: float
    contact: bool = False
    half_width: float = 0.0
    faces: list | None = None
    squeeze: bool = True
    _q0: np.ndarray | None = field(default=None, init=False, repr=False)
    _axis: np.ndarray | None = field(default=None, init=False, repr=False)
    _offset: np.ndarray | None = field(default=None, init=False, repr=False)
    _z0: float = field(default=0.0, init=False, repr=False)
    _pressing_since: float | None = field(default=None, init=False, repr=False)
    _established: bool = field(default=False, init=False, repr=False)

    def check(self, s: GraspSample) -> Failure | None:
        """Check one sample (the next in time).

        Parameters
        ----------
        s : GraspSample
            The sample.

        Returns
        -------
        Failure or None
            The first guard the sample fails, in the order of the module docstring.
        """
        g = self.guards
        for name, x, x_d in zip(self.robots, s.x, s.x_d):
            e = float(np.linalg.norm(np.asarray(x) - np.asarray(x_d)))
            if not e <= g.max_pad_error:
                return _pad_failure(g, name, s.t, e)
        held = self.t_grasp <= s.t < self.t_release
        if held and self.squeeze and s.lam is not None and s.t >= self.t_grasp + SQUEEZE_SETTLE:
            for name, lam, lam_d in zip(self.robots, s.lam, s.lam_d):
                e = float(np.linalg.norm(np.asarray(lam) - np.asarray(lam_d)))
                if not e <= g.max_squeeze_error:
                    return _squeeze_failure(g, name, s.t, e)
        if not (self.contact and held and s.pose is not None):
            return None
        return self._check_box(s)

    def _check_box(self, s: GraspSample) -> Failure | None:
        g = self.guards
        pose = np.asarray(s.pose, dtype=float)
        mid_d = np.mean([np.asarray(x) for x in s.x_d], axis=0)
        comps = [pad_contact_components(np.asarray(F, dtype=float)[None], np.asarray(x)[None],
                                        pose[None], face)
                 for F, x, face in zip(s.F, s.x, [f[0] for f in self.faces]
                                      if self.faces else [None] * len(s.x))]
        if self._q0 is None:             # the first held sample: the grasp's reference
            self._q0 = pose[:4] / np.linalg.norm(pose[:4])
            self._offset = pose[4:7] - mid_d
            self._z0 = float(pose[6])
            self._axis = self._grasp_line([c[2][0] for c in comps])
        e = float(np.linalg.norm(pose[4:7] - mid_d - self._offset))
        if not e <= g.max_object_position_error:
            return _position_failure(g, s.t, e)
        tilt = math.degrees(tilt_about_line(self._q0, pose[:4] / np.linalg.norm(pose[:4]),
                                            self._axis))
        if not tilt <= g.max_object_tilt_deg:
            return _tilt_failure(g, s.t, tilt)
        f_n = [float(c[0][0]) for c in comps]
        pressing = all(f >= CONTACT_FORCE for f in f_n)
        if not self._established:
            if not pressing:
                self._pressing_since = None
            else:
                if self._pressing_since is None:
                    self._pressing_since = s.t
                self._established = s.t - self._pressing_since >= SETTLE_TIME - 1e-12
            return None
        resting = abs(float(pose[6]) - self._z0) <= REST_HEIGHT
        if g.grasp_lost and not pressing and not resting:
            j = int(np.argmin(f_n))
            return _grasp_failure(self.robots[j], s.t, f_n[j], abs(float(pose[6]) - self._z0))
        return None

    def _grasp_line(self, pads_in_box: list) -> np.ndarray:
        """The grasp line in the box frame: through the two pads' contact points (each pad's
        centre moved onto its face), or the normal of the plane of three or more."""
        points = []
        for p, face in zip(pads_in_box, self.faces or [None] * len(pads_in_box)):
            p = np.array(p, dtype=float)
            if face is None:
                p[0] = math.copysign(self.half_width, p[0])
            else:
                n, offset = np.asarray(face[0], dtype=float), float(face[1])
                p = p - (p @ n - offset) * n
            points.append(p)
        points = np.asarray(points)
        if len(points) == 2:
            d = points[1] - points[0]
            return d / np.linalg.norm(d)
        return np.linalg.svd(points - points.mean(axis=0))[2][-1]


def _pad_failure(g: Guards, name: str, t: float, e: float) -> Failure:
    return Failure("max_pad_error", name, t, e, g.max_pad_error,
                   f"pad {e * 1e3:.1f} mm off its path (guards.max_pad_error = "
                   f"{g.max_pad_error * 1e3:g} mm)")


def _squeeze_failure(g: Guards, name: str, t: float, e: float) -> Failure:
    return Failure("max_squeeze_error", name, t, e, g.max_squeeze_error,
                   f"squeeze {e:.1f} N from its reference (guards.max_squeeze_error = "
                   f"{g.max_squeeze_error:g} N)")


def _position_failure(g: Guards, t: float, e: float) -> Failure:
    return Failure("max_object_position_error", "box", t, e, g.max_object_position_error,
                   f"{e * 1e3:.1f} mm off its path (guards.max_object_position_error = "
                   f"{g.max_object_position_error * 1e3:g} mm)")


def _tilt_failure(g: Guards, t: float, tilt: float) -> Failure:
    return Failure("max_object_tilt_deg", "box", t, tilt, g.max_object_tilt_deg,
                   f"tilted {tilt:.1f} deg (guards.max_object_tilt_deg = "
                   f"{g.max_object_tilt_deg:g})")


def _grasp_failure(name: str, t: float, f_n: float, off_stand: float) -> Failure:
    return Failure("grasp_lost", name, t, 1.0, 0.0,
                   f"lost the grasp: its pad presses {f_n:.2f} N (< {CONTACT_FORCE} N) with "
                   f"the box {1e3 * off_stand:.1f} mm off its stand (guards.grasp_lost)")


def _tilts(q0: np.ndarray, q: np.ndarray, axis: np.ndarray) -> np.ndarray:
    """:func:`tilt_about_line` of every row of ``q`` (K, 4)."""
    w0, v0 = q0[0], -np.asarray(q0[1:], dtype=float)
    q = q / np.linalg.norm(q, axis=1, keepdims=True)
    w = w0 * q[:, 0] - q[:, 1:] @ v0
    v = w0 * q[:, 1:] + q[:, :1] * v0 + np.cross(v0, q[:, 1:])
    along = v @ np.asarray(axis, dtype=float)
    return 2.0 * np.arctan2(np.sqrt(np.maximum(np.sum(v * v, axis=1) - along ** 2, 0.0)),
                            np.sqrt(w * w + along * along))


def _first(mask: np.ndarray) -> int | None:
    k = np.flatnonzero(mask)
    return int(k[0]) if k.size else None


def first_failure_in_logs(check: FailureCheck, logs: dict) -> Failure | None:
    """The first failure on the logged ticks, as :meth:`FailureCheck.check` fed every tick in
    order from a fresh state would report it (computed on the arrays at once).

    Parameters
    ----------
    check : FailureCheck
        The run's guards (its state is not read or changed).
    logs : dict
        ``logs[robot][array]`` of :func:`~drake_coop.experiment.simulate.collect_logs`
        (``t``, ``x``, ``x_d``, ``lambda_meas``, ``lambda_d``; in ``contact`` mode
        ``object_pose`` and ``F_meas``). Rows from the first non-finite pad point on (a
        blown-up state: the divergence guards' report) are not read.

    Returns
    -------
    Failure or None
        The first failure, or None.
    """
    names = list(logs)
    if not names:
        return None
    g = check.guards
    K = min(len(np.asarray(logs[r]["t"])) for r in names)

    def rows(key):
        return [np.asarray(logs[r][key], dtype=float)[:K].reshape(K, -1) for r in names]

    t = np.asarray(logs[names[0]]["t"], dtype=float)[:K]
    x, x_d = rows("x"), rows("x_d")
    bad = _first(~np.all([np.all(np.isfinite(a), axis=1) for a in x], axis=0))
    K = K if bad is None else bad
    t, x, x_d = t[:K], [a[:K] for a in x], [a[:K] for a in x_d]
    found: list[tuple[int, int, Failure]] = []       # (tick, the check's order, failure)
    for i, name in enumerate(names):
        e = np.linalg.norm(x[i] - x_d[i], axis=1)
        k = _first(~(e <= g.max_pad_error))
        if k is not None:
            found.append((k, i, _pad_failure(g, name, float(t[k]), float(e[k]))))
    held = (t >= check.t_grasp) & (t < check.t_release)
    if check.squeeze and "lambda_meas" in logs[names[0]]:
        lam, lam_d = rows("lambda_meas"), rows("lambda_d")
        settled = held & (t >= check.t_grasp + SQUEEZE_SETTLE)
        for i, name in enumerate(names):
            e = np.linalg.norm(lam[i][:K] - lam_d[i][:K], axis=1)
            k = _first(settled & ~(e <= g.max_squeeze_error))
            if k is not None:
                found.append((k, len(names) + i, _squeeze_failure(g, name, float(t[k]),
                                                                  float(e[k]))))
    k0 = _first(held)
    if check.contact and "object_pose" in logs[names[0]] and k0 is not None:
        found += _box_failures(check, names, t, x, x_d, rows, k0, held)
    if not found:
        return None
    return min(found, key=lambda f: (f[0], f[1]))[2]


def _box_failures(check: FailureCheck, names: list, t: np.ndarray, x: list, x_d: list, rows,
                  k0: int, held: np.ndarray) -> list:
    """The box's failures of :func:`first_failure_in_logs` (the first of each guard)."""
    g = check.guards
    K = t.size
    order = 2 * len(names)
    pose = rows("object_pose")[0][:K]          # robot 1's log (the same in every robot's)
    F = [a[:K] for a in rows("F_meas")]
    faces = [f[0] for f in check.faces] if check.faces else [None] * len(names)
    comps = [pad_contact_components(F[i], x[i], pose, faces[i]) for i in range(len(names))]
    probe = FailureCheck(g, names, check.t_grasp, check.t_release, True, check.half_width,
                         check.faces)
    axis = probe._grasp_line([c[2][k0] for c in comps])
    q0 = pose[k0, :4] / np.linalg.norm(pose[k0, :4])
    mid_d = np.mean(x_d, axis=0)
    e = np.linalg.norm(pose[:, 4:7] - mid_d - (pose[k0, 4:7] - mid_d[k0]), axis=1)
    out = []
    k = _first(held & ~(e <= g.max_object_position_error))
    if k is not None:
        out.append((k, order, _position_failure(g, float(t[k]), float(e[k]))))
    tilt = np.degrees(_tilts(q0, pose[:, :4], axis))
    k = _first(held & ~(tilt <= g.max_object_tilt_deg))
    if k is not None:
        out.append((k, order + 1, _tilt_failure(g, float(t[k]), float(tilt[k]))))
    if not g.grasp_lost:
        return out
    f_n = np.array([c[0] for c in comps])
    pressing = np.all(f_n >= CONTACT_FORCE, axis=0)
    since, established = None, None
    for k in range(k0, K):                     # the state machine of FailureCheck.check
        if not held[k]:
            break
        if not pressing[k]:
            since = None
            continue
        since = t[k] if since is None else since
        if t[k] - since >= SETTLE_TIME - 1e-12:
            established = k
            break
    if established is None:
        return out
    off = np.abs(pose[:, 6] - pose[k0, 6])
    after = np.arange(K) > established
    k = _first(after & held & ~pressing & (off > REST_HEIGHT))
    if k is not None:
        j = int(np.argmin(f_n[:, k]))
        out.append((k, order + 2, _grasp_failure(names[j], float(t[k]), float(f_n[j, k]),
                                                 float(off[k]))))
    return out


def failure_check(exp) -> FailureCheck:
    """The failure guards of a built experiment (its scenario's ``guards`` and phases).

    Parameters
    ----------
    exp : Experiment
        The experiment (:func:`~drake_coop.experiment.diagram.build_experiment`).

    Returns
    -------
    FailureCheck
        Not fed yet.
    """
    sc = exp.scenario
    grasp = exp.coop.grasp
    contact = sc.plant.object_mode == "contact" and grasp is not None
    faces = None
    if contact and grasp.face_normals is not None:
        faces = [(np.asarray(n, dtype=float), float(d))
                 for n, d in zip(grasp.face_normals, grasp.face_offsets)]
    return FailureCheck(sc.guards, [rs.name for rs in exp.robots], sc.task.t_grasp,
                        sc.task.t_release, contact,
                        0.5 * float(grasp.size[0]) if contact else 0.0, faces,
                        sc.plant.object_mode != "none")


def plant_sample(exp, context, forces: list | None, x_d: list[np.ndarray]) -> GraspSample:
    """What the guards read at a tick, from the plant's state (the truth).

    Parameters
    ----------
    exp : Experiment
        The experiment.
    context : Context
        The root context at a tick, before its updates.
    forces : list of numpy.ndarray or None
        Each arm's wrist force ``F`` (3,) of the plant step before the tick (the divergence
        guards' read, :func:`~drake_coop.experiment.simulate.simulate`); None without an
        object.
    x_d : list of numpy.ndarray
        Each robot's desired pad position (3,) at the context's time, m
        (:func:`~drake_coop.scenario.task_path.cartesian_reference`; the caller evaluates the
        path at every stop at once: one evaluation costs as much for one time as for a
        thousand).

    Returns
    -------
    GraspSample
        The sample at the context's time.
    """
    sc = exp.scenario
    plant = exp.coop.plant
    pc = plant.GetMyContextFromRoot(context)
    t = float(context.get_time())
    x, lam, lam_d = [], [], []
    for i, rs in enumerate(exp.robots):
        q = exp.coop.arm_positions(pc, i)
        x.append(np.asarray(exp.coop.arms[i].arm.fk(q[None, :]), dtype=float).reshape(3))
        if forces is not None and rs.log is not None and "reference" in rs.log.ports:
            N = np.atleast_2d(np.asarray(sc.robots[i].normals, dtype=float))
            N = N / np.linalg.norm(N, axis=1, keepdims=True)
            lam.append(N @ np.asarray(forces[i], dtype=float))
            ref = np.asarray(rs.log.now(context, "reference"), dtype=float)
            lam_d.append(rs.law.layout.column(ref[None, :], "lambda_d")[0])
    pose = None
    grasp = exp.coop.grasp
    if sc.plant.object_mode == "contact" and grasp is not None:
        X = plant.EvalBodyPoseInWorld(pc, grasp.box)
        pose = np.concatenate([X.rotation().ToQuaternion().wxyz(), X.translation()])
    return GraspSample(t, x, x_d, lam if lam else None, lam_d if lam_d else None, pose,
                       None if pose is None else list(forces))


#: The metrics' phases whose samples each guard reads: the pads' path the whole run, the
#: squeeze from :data:`SQUEEZE_SETTLE` after the grasp (the circle and the put-down lie past
#: it; the lift starts at the grasp), the box while held.
SUMMARY_PHASES = {"max_pad_error": ("free", "lift", "circle", "put_down", "return"),
                  "max_squeeze_error": ("circle", "put_down"),
                  "max_object_tilt_deg": ("lift", "circle", "put_down"),
                  "max_object_position_error": ("lift", "circle", "put_down")}


def summary_failure(maxima: dict, guards: Guards, phase: str) -> Failure | None:
    """The first guard that a phase's logged maxima prove tripped, without the logs.

    A run's summary (a study's ``results.csv`` row, a ``metrics.json``) keeps each error's
    largest value per phase; where that value is beyond a guard's bound and the guard reads
    that phase (:data:`SUMMARY_PHASES`), the run would now end ``failed``. The pad's error is
    summarised by its worst axis, ``max_j |x_j − x_d,j| ≤ ‖x − x_d‖``, so a worst axis beyond
    ``max_pad_error`` proves the trip (a norm beyond it with every axis within is not seen
    here). The time of the failure is not known (``t`` is NaN).

    Parameters
    ----------
    maxima : dict
        Per robot name, ``{error: largest value in the phase}`` with any of
        ``position_error`` (worst axis, m), ``force_error`` (``‖λ − λ_d‖``, N),
        ``object_tilt`` (rad) and ``object_position_error`` (m); missing ones are skipped.
    guards : Guards
        The bounds.
    phase : str
        The metrics' phase (``free``, ``lift``, ``circle``, ``put_down``, ``return``).

    Returns
    -------
    Failure or None
        The first guard proven tripped (robots in order: pad, squeeze, then the box), or None.
    """
    nan = float("nan")
    g = guards
    for name, m in maxima.items():
        e = m.get("position_error")
        if e is not None and phase in SUMMARY_PHASES["max_pad_error"] and e > g.max_pad_error:
            return _pad_failure(g, name, nan, float(e))
        e = m.get("force_error")
        if (e is not None and phase in SUMMARY_PHASES["max_squeeze_error"]
                and e > g.max_squeeze_error):
            return _squeeze_failure(g, name, nan, float(e))
    for m in maxima.values():
        tilt = m.get("object_tilt")
        if (tilt is not None and phase in SUMMARY_PHASES["max_object_tilt_deg"]
                and math.degrees(tilt) > g.max_object_tilt_deg):
            return _tilt_failure(g, nan, math.degrees(float(tilt)))
        e = m.get("object_position_error")
        if (e is not None and phase in SUMMARY_PHASES["max_object_position_error"]
                and e > g.max_object_position_error):
            return _position_failure(g, nan, float(e))
    return None
