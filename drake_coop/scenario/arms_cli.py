"""``drake-coop arms [--yaml NAME]``: the arms of ``example-robot-data`` that load, with their
fields (:mod:`drake_coop.scenario.lab_arms`).

Without ``--yaml``: one row per arm (short name, joints, the fields ``base_frame``,
``locked_joints``, ``tool.flange``, the flange's tool axis, the effort limits Drake reads and the URDF's gear reductions
Drake ignores), each arm prepared and loaded as a run does. With ``--yaml NAME``: the robot entry
of that arm for a scenario's ``robots:`` list, to paste and complete (placement, normals), then
``drake-coop gains`` derives its gains. Exit codes: 0 every arm loads, 1 one or more did not (its
row says why), 2 bad input or the package is not installed (one line).
"""

from __future__ import annotations

import sys

__all__ = ["add_arms_parser", "cmd_arms"]


def add_arms_parser(sub) -> None:
    """Register ``arms`` on the ``drake-coop`` subparsers.

    Parameters
    ----------
    sub : argparse._SubParsersAction
        The ``drake-coop`` subparsers.
    """
    p = sub.add_parser("arms", help="list the arms of example-robot-data that load, with the "
                                    "fields a scenario needs")
    p.add_argument("--yaml", metavar="NAME", help="print the robot entry of arm NAME")
    p.set_defaults(func=cmd_arms)


def _error(message: str) -> int:
    """``drake-coop: error: <message>`` on one line, exit code 2 (as
    :func:`drake_coop.console.error`, which sits above this layer)."""
    from drake_coop.scenario.bounds import one_line

    print(f"drake-coop: error: {one_line(message)}", file=sys.stderr)
    return 2


def _numbers(values) -> str:
    return " ".join("-" if v is None else f"{v:g}" for v in values)


def _yaml(name: str) -> str:
    from drake_coop.scenario.lab_arms import LAB_ARMS, SENSOR_RPY_FOR_AXIS, arm_facts

    arm = LAB_ARMS[name]
    facts = arm_facts(name)
    locked = ", ".join(f"{k}: {v:g}" for k, v in arm.locked_joints.items())
    mid = [round((lo + hi) / 2, 3) for lo, hi in zip(facts.lower, facts.upper)]
    if facts.tool_axis == "+z":
        tool = (f"  tool: {{flange: {arm.flange}}}   # the pad 45 mm out along the flange's z, "
                "its tool axis")
    else:
        tool = (f"  tool: {{flange: {arm.flange}, sensor_rpy_deg: "
                f"{SENSOR_RPY_FOR_AXIS[facts.tool_axis]}}}   # the flange's tool axis is its "
                f"{facts.tool_axis}: the sensor turned onto it, the pad 45 mm out along it")
    lines = [f"- name: {name}_1",
             f"  model: {arm.model}",
             f"  base_frame: {arm.base_frame}",
             "  base_xyz: [0.0, 0.0, 0.0]        # where the arm stands (m)",
             "  base_yaw_deg: 0.0",
             f"  locked_joints: {{{locked}}}",
             tool,
             "  ee_frame: pad",
             "  sensor_joint: flange_sensor_weld",
             "  contact_xy: [0.6, 0.0]           # the pad's contact point at the grasp (x, y)",
             "  normals: [[-1.0, 0.0, 0.0]]      # the object's outward normal there",
             "  home: [0.5, 0.0, 0.6]            # the pad's start and end point"]
    if len(facts.joints) >= 6:
        lines.append("  ee_rpy_deg: [0.0, 90.0, 0.0]     # the pad's z (approach) along +x, "
                     "towards the object (the 6-D task); another arm: add its base_yaw_deg "
                     "to the yaw")
    else:
        lines.append("  ee_rpy_deg: null                 # too few joints for an orientation: "
                     "a position task")
    if len(facts.joints) > 6:
        lines.append(f"  q_nominal: {mid}   # the null-space posture (here: mid-range)")
    lines.append(f"  # joints: {', '.join(facts.joints)}; effort limits "
                 f"{_numbers(facts.effort_limits)} (the squeeze check uses these when actuators.torque_limits is null)")
    lines.append("  # gains: derived by drake-coop gains")
    return "\n".join(lines) + "\n"


def cmd_arms(args) -> int:
    """The exit code of ``drake-coop arms`` (as the module's docstring lists them), after listing
    the arms.

    Parameters
    ----------
    args : argparse.Namespace
        The parsed command line.
    """
    from drake_coop.control.arm_plant import description_packages
    from drake_coop.scenario.description import ROBOTS_EXTRA
    from drake_coop.scenario.lab_arms import LAB_ARMS, arm_facts
    from drake_coop.scenario.schema import ScenarioError

    if "example-robot-data" not in description_packages():
        return _error(f"example-robot-data is not installed; install the robots extra: "
                      f"{ROBOTS_EXTRA}")
    if args.yaml is not None:
        if args.yaml not in LAB_ARMS:
            return _error(f"--yaml must be one of {', '.join(LAB_ARMS)}, got {args.yaml!r}")
        try:
            sys.stdout.write(_yaml(args.yaml))
        except ScenarioError as exc:
            print(f"drake-coop: arms: {exc}", file=sys.stderr)
            return 1
        return 0
    failed = 0
    print("arm\tjoints\tbase_frame\tlocked_joints\ttool.flange\ttool axis\teffort_limits\t"
          "mechanicalReduction (ignored by Drake)\ttitle")
    for name, arm in LAB_ARMS.items():
        locked = ",".join(f"{k}={v:g}" for k, v in arm.locked_joints.items()) or "-"
        try:
            facts = arm_facts(name)
        except ScenarioError as exc:
            failed += 1
            print(f"{name}\tFAILED\t{arm.base_frame}\t{locked}\t{arm.flange}\t{exc}")
            continue
        print(f"{name}\t{len(facts.joints)}\t{arm.base_frame}\t{locked}\t{arm.flange}\t"
              f"{facts.tool_axis}\t{_numbers(facts.effort_limits)}\t{_numbers(facts.reductions)}\t{arm.title}")
    return 1 if failed else 0
