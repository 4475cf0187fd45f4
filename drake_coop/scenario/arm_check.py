"""The rules of a scenario that depend on the arms: sizes, constraints (2), Assumption 1.

Checked by :func:`drake_coop.scenario.validation.validate` once the model files have given
each arm's joint count ``n_i`` (:mod:`drake_coop.scenario.model_check`): lists sized by ``n_i``
or ``m_i``, the normals (``1 <= m_i <= min(n_i, 3)``, independent), ``ξ_i`` symmetric positive
definite, enough joints for the task (3 for a position reference, 6 for a position and
orientation; more make a redundant arm, whose reference has a null-space objective), the circle's axes and the object's motion within every robot's
constraint planes. Each problem raises :class:`~drake_coop.scenario.ScenarioError` naming the
field.
"""

import numpy as np

from drake_coop.scenario.bounds import show
from drake_coop.scenario.schema import Robot, Scenario, ScenarioError

#: Tolerance of symmetry of ξ.
_TOL = 1e-9


def _unit_rows(rows: list[list[float]], name: str) -> np.ndarray:
    """The rows normalized; a zero row is an error."""
    a = np.asarray(rows, dtype=float).reshape(-1, 3)
    norms = np.linalg.norm(a, axis=1)
    for j, value in enumerate(norms):
        if value < 1e-6:
            raise ScenarioError(f"{name}[{j}] must be a nonzero direction, got {show(rows[j])}")
    return a / norms[:, None]


def check_axes(scenario: Scenario) -> None:
    """The circle's axes (unit and orthogonal, or one of them zero) and the object's motion
    against every robot's constraint planes.

    Parameters
    ----------
    scenario : Scenario
        The scenario.

    Raises
    ------
    ScenarioError
        Naming ``task.circle_axes``, or the normal of ``robots[i].normals`` the object's
        motion is not orthogonal to.
    """
    t = scenario.task
    axes = np.asarray(t.circle_axes, dtype=float)
    norms = np.linalg.norm(axes, axis=1)
    if not all(abs(v - 1.0) < 1e-6 or v == 0.0 for v in norms) or norms.max() == 0.0:
        raise ScenarioError("task.circle_axes must be two unit vectors (or one of them "
                            f"[0, 0, 0]), got {show(t.circle_axes)}")
    if abs(axes[0] @ axes[1]) > 1e-6:
        raise ScenarioError(f"task.circle_axes must be orthogonal, got {show(t.circle_axes)}")
    if scenario.plant.object_mode == "none":
        return
    moves = [("the lift (z)", np.array([0.0, 0.0, 1.0]))] if t.lift_height > 0 else []
    moves += [(f"task.circle_axes[{k}]", a) for k, a in enumerate(axes)
              if norms[k] > 0 and t.circle_radius > 0]
    for i, r in enumerate(scenario.robots):
        N = _unit_rows(r.normals, f"robots[{i}].normals")
        for label, direction in moves:
            j = int(np.argmax(np.abs(N @ direction)))
            if abs(N[j] @ direction) > 1e-6:
                raise ScenarioError(
                    f"robots[{i}].normals[{j}] must be orthogonal to {label}: the object moves "
                    "along it while held, so it must lie in every constraint plane")


def check_dimensions(robot: Robot, n: int, where: str) -> None:
    """Lists sized by the arm's ``n`` joints and ``m`` constraints, and Assumption 1.

    Parameters
    ----------
    robot : Robot
        The robot's entry.
    n : int
        Its arm's joints.
    where : str
        The entry's path for messages (``robots[i]``).

    Raises
    ------
    ScenarioError
        Naming the field and the allowed size or value.
    """
    m = len(robot.normals)
    if not 1 <= m <= min(n, 3):
        raise ScenarioError(f"{where}.normals has {m} rows; allowed 1 to {min(n, 3)} "
                            f"(m_i <= n_i = {n} joints, at most 3 for a point)")
    N = _unit_rows(robot.normals, f"{where}.normals")
    if np.linalg.svd(N, compute_uv=False).min() < 1e-3:
        raise ScenarioError(f"{where}.normals must be linearly independent (J_phi full rank), "
                            f"got {show(robot.normals)}")
    sized = {f"{where}.force_weights": (robot.force_weights, m),
             f"{where}.gains.K_R": (robot.gains.K_R, n),
             f"{where}.actuators.torque_limits": (robot.actuators.torque_limits, n),
             f"{where}.q_seed": (robot.q_seed, n)}
    if robot.model_error.coulomb_friction:
        sized[f"{where}.model_error.coulomb_friction"] = (robot.model_error.coulomb_friction, n)
    if robot.gains.K_R is not None and len(robot.gains.K_R) != n \
            and list(robot.gains.K_R) == list(type(robot.gains)().K_R):
        raise ScenarioError(f"{where}.gains.K_R must have {n} entries (one per joint); the "
                            f"{len(robot.gains.K_R)} it has are the defaults (the paper's "
                            f"{len(robot.gains.K_R)}-joint arm's, no gains given): run "
                            "`drake-coop gains SCENARIO --out DIR` to derive this arm's gains")
    for name, (value, size) in sized.items():
        if value is not None and len(value) != size:
            raise ScenarioError(f"{name} must have {size} entries (one per "
                                f"{'constraint' if size == m and 'weights' in name else 'joint'}"
                                f"), got {len(value)}")
    xi = robot.gains.xi_matrix
    if xi is not None:
        X = np.asarray(xi, dtype=float) if all(len(row) == m for row in xi) else None
        if X is None or X.shape != (m, m):
            raise ScenarioError(f"{where}.gains.xi_matrix must be {m}x{m} (m_i = {m}), "
                                f"got {show(xi)}")
        if not np.allclose(X, X.T, rtol=0, atol=_TOL) or np.linalg.eigvalsh(X).min() <= 0:
            raise ScenarioError(f"{where}.gains.xi_matrix must be symmetric positive definite, "
                                f"got {show(xi)}")
    task_dim = 3 if robot.ee_rpy_deg is None else 6
    if n < 3:
        raise ScenarioError(f"{where}.model has {n} joints: an arm needs at least 3 (a "
                            "position reference)")
    if n >= 6 and task_dim == 3:
        raise ScenarioError(f"{where}.ee_rpy_deg must be given for a {n}-joint arm (its "
                            "reference is position and orientation)")
    if n < task_dim:
        raise ScenarioError(f"{where}.ee_rpy_deg must be null for a {n}-joint arm "
                            "(position-only reference: fewer joints than a position and "
                            "orientation)")
    if robot.q_nominal is not None and len(robot.q_nominal) != n:
        raise ScenarioError(f"{where}.q_nominal must have {n} entries (one per joint), got "
                            f"{len(robot.q_nominal)}")
