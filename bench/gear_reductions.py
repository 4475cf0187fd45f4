"""What a URDF's gear reductions would add to a joint's inertia, and to its derived gain:
``python -m bench.gear_reductions --out docs/results/gear_reductions.json``.

Drake ignores a URDF's ``mechanicalReduction``; a geared joint's rotor reflects ``N² J_m`` onto
the joint. For each joint of :data:`JOINTS` (the lab-arms page's table), at the arm's mid-range
posture (the middle of each joint's limits, 0 for an unlimited joint): the inertia the joint
sees with the others free, ``J_j = 1/(H⁻¹)_jj`` (``CalcMassMatrix``), and the gain
``drake-coop gains`` would derive from it, ``K_R,j = κ J_j / h`` (κ = 1, h = 9 ms), for the URDF
as Drake reads it (no rotor) and with Drake's own reflected inertia
(``JointActuator.set_default_rotor_inertia(J_m)``, ``set_default_gear_ratio(N)``, N the URDF's
reduction of that joint, 1 where it gives none) for each ``J_m`` of :data:`ROTOR_INERTIAS` (an
assumption for illustration: small servo motors' rotors, not these arms' values). Needs the
robots extra (``example-robot-data``); a few seconds of CPU.
"""

from __future__ import annotations

import argparse
import json
import math

#: (arm of ``drake-coop arms``, joint index from 0) of the page's table.
JOINTS = (("xarm7", 6), ("xarm7", 1), ("jaco2", 5), ("jaco2", 1))
#: Rotor inertias J_m tried, kg·m².
ROTOR_INERTIAS = (1e-5, 5e-5)
#: The control period h (s) and the gain factor κ of K_R,j = κ J_j / h.
PERIOD, KAPPA = 0.009, 1.0


def joint_inertias(name: str, rotor_inertia: float) -> tuple[list[float], list[float]]:
    """The inertia each joint of arm ``name`` sees with the others free, at mid-range.

    Parameters
    ----------
    name : str
        A key of ``drake_coop.scenario.lab_arms.LAB_ARMS``.
    rotor_inertia : float
        J_m (kg·m²) given to every actuator, with its URDF reduction as the gear ratio; 0 for
        the URDF as Drake reads it.

    Returns
    -------
    tuple of list of float
        ``J_j = 1/(H⁻¹)_jj`` (kg·m²) per joint in velocity order, and each joint's gear ratio.
    """
    import numpy as np
    from pydrake.multibody.parsing import Parser
    from pydrake.multibody.plant import MultibodyPlant

    from drake_coop.scenario.lab_arms import arm_facts, lab_arm_robot

    facts = arm_facts(name)
    plant = MultibodyPlant(0.0)
    Parser(plant).AddModels(facts.path)
    plant.WeldFrames(plant.world_frame(),
                     plant.GetFrameByName(lab_arm_robot(name).base_frame))
    ratios = {}
    for index in plant.GetJointActuatorIndices():
        actuator = plant.get_joint_actuator(index)
        joint = actuator.joint().name()
        n = facts.reductions[facts.joints.index(joint)] or 1.0
        ratios[joint] = n
        if rotor_inertia > 0:
            actuator.set_default_rotor_inertia(rotor_inertia)
            actuator.set_default_gear_ratio(n)
    plant.Finalize()
    context = plant.CreateDefaultContext()
    lower, upper = plant.GetPositionLowerLimits(), plant.GetPositionUpperLimits()
    mid = np.where(np.isfinite(lower) & np.isfinite(upper), 0.5 * (lower + upper), 0.0)
    plant.SetPositions(context, mid)
    H = plant.CalcMassMatrix(context)
    inertia = [float(1.0 / v) for v in np.diag(np.linalg.inv(H))]
    return inertia, [ratios[j] for j in facts.joints]


def table() -> dict:
    """Every row of :data:`JOINTS`, without a rotor and with each of :data:`ROTOR_INERTIAS`.

    Returns
    -------
    dict
        ``rows[ARM_jJ]``: ``gear_ratio``, ``no_rotor`` / ``rotor_<J_m>`` each with
        ``inertia_kg_m2`` and ``K_R``; and the inputs.
    """
    rows = {}
    for name, j in JOINTS:
        row = {}
        for rotor in (0.0,) + ROTOR_INERTIAS:
            inertia, ratios = joint_inertias(name, rotor)
            key = "no_rotor" if rotor == 0 else f"rotor_{rotor:g}"
            row[key] = {"inertia_kg_m2": inertia[j], "K_R": KAPPA * inertia[j] / PERIOD}
            row["gear_ratio"] = ratios[j]
        row["reflected_factor"] = {f"rotor_{r:g}": row[f"rotor_{r:g}"]["inertia_kg_m2"]
                                   / row["no_rotor"]["inertia_kg_m2"] for r in ROTOR_INERTIAS}
        rows[f"{name}_j{j + 1}"] = row
    assert all(math.isfinite(v["no_rotor"]["K_R"]) for v in rows.values())
    return {"rows": rows, "period_s": PERIOD, "kappa": KAPPA,
            "rotor_inertias_kg_m2": list(ROTOR_INERTIAS),
            "posture": "the middle of each joint's limits (0 where unlimited)"}


if __name__ == "__main__":
    import sys

    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--out", default=None, help="write the table as JSON")
    args = parser.parse_args()
    numbers = table()
    numbers["command"] = "python -m bench.gear_reductions" + (f" --out {args.out}"
                                                              if args.out else "")
    for key, row in numbers["rows"].items():
        print(key, f"N = {row['gear_ratio']:g}", "  ".join(
            f"{k}: J {v['inertia_kg_m2']:.4g} kg m2, K_R {v['K_R']:.4g}"
            for k, v in row.items() if isinstance(v, dict) and "K_R" in v))
    if args.out:
        from drake_coop.results.io import atomic_write_text

        atomic_write_text(args.out, json.dumps(numbers, indent=2))
    sys.exit(0)
