"""Force sources of the reference table that no scenario field selects: built in the worker.

Two rows of the table are force sources the control block can hold but a scenario cannot
name (the experiment's diagram passes neither option):

* ``applied_torque`` — the applied-torque residual: the generalized-momentum observer
  integrating the torque actually applied, ``clip(τ, −τ_max, τ_max)``, instead of the
  commanded one (:class:`~drake_coop.control.momentum.MomentumObserver`'s ``torque_limits``,
  ``AddCooperativeController(..., momentum_torque_limits=τ_max)``). With no torque limits the
  two are the same system: the case is the momentum row's own (the same hash, run once).
* ``online`` — the online identification (:class:`~drake_coop.identification.online.
  OnlineIdentification`): recursive least squares on the arm's regressor from the prior of
  the controller's model, feeding the momentum observer and the controller's model (the
  control law) with its refined parameters.
* ``online_prior`` — the same block with its Coulomb friction's prior standard deviation at
  least :data:`ONLINE_OPTIONS`' 0.5 N·m (the block's ``coulomb_prior``; the batch
  identification's floor), the identified friction written into the controller's model too.
  Not a default row of the table (its cells are an option's, not the block's default).

A case of such a row is its scenario with ``force_source: momentum`` and a *variant*
(:func:`variant_hash` keeps its hash apart from the momentum row's). The worker builds the
diagram inside :func:`variant_built`, which swaps the momentum source's construction for the
variant's while the experiment is built (the same ports: ``q``, ``qdot_hat``, ``tau``,
``reference``), and restores it after.
"""

from __future__ import annotations

import contextlib
import dataclasses
import hashlib
from typing import Iterator

from drake_coop.scenario.schema import Scenario

__all__ = ["ONLINE_OPTIONS", "VARIANTS", "run_variant_case", "variant_built", "variant_hash",
           "variant_matters"]

#: The reachability check's outcomes in this worker process, by what the check reads
#: (:func:`~drake_coop.scenario.validation.reach_inputs`): a cell's draws that change only
#: the controller's model, the friction or the limits are checked once per worker. The
#: outcome is that of an uncached check.
REACH_CACHE: dict = {}

#: The variants and what each is.
VARIANTS = {
    "applied_torque": "the momentum observer integrating the applied (clipped) torque",
    "online": "the momentum observer on the online identification's parameters",
    "online_prior": "the momentum observer on the online identification's parameters, the "
                    "friction's prior standard deviation at least 0.5 N·m",
}

#: The online identification variants: each one's further keyword arguments of
#: :class:`~drake_coop.identification.online.OnlineIdentification` (its other arguments the
#: same: the controller's model as the prior, the momentum observer's gain, the run's period).
ONLINE_OPTIONS: dict[str, dict] = {"online": {}, "online_prior": {"coulomb_prior": 0.5}}


def variant_matters(scenario: Scenario, variant: str | None) -> bool:
    """Whether ``variant`` changes the run of ``scenario`` (``force_source: momentum``).

    Parameters
    ----------
    scenario : Scenario
        The case's scenario.
    variant : str or None
        A key of :data:`VARIANTS`, ``open_loop:<row>``
        (:mod:`~drake_coop.studies.reference_open_loop`), a clock
        (:func:`~drake_coop.studies.reference_clock.clock_variant`), or None.

    Returns
    -------
    bool
        False for None, and for ``applied_torque`` when no robot has torque limits (the
        applied torque is then the commanded one).

    Raises
    ------
    ValueError
        An unknown variant.
    """
    if variant is None:
        return False
    if variant.startswith(("open_loop:", "clock:")):   # beside the sensor loop; a clock
        return True
    if variant not in VARIANTS:
        raise ValueError(f"variant: unknown {variant!r}; allowed: {', '.join(VARIANTS)}")
    if variant == "applied_torque":
        return any(r.actuators.torque_limits for r in scenario.robots)
    return True


def variant_hash(base_hash: str, variant: str) -> str:
    """The hash of a variant's case: 16 hex digits of SHA-256 over the scenario's hash and
    the variant's name.

    Parameters
    ----------
    base_hash : str
        The scenario's :func:`~drake_coop.studies.expand.case_hash`.
    variant : str
        The variant.

    Returns
    -------
    str
        The case's hash.
    """
    return hashlib.sha256(f"{base_hash}\n# variant: {variant}\n".encode()).hexdigest()[:16]


def _online_builder(scenario: Scenario, feed_controller: bool = True,
                    prior: dict | None = None, options: dict | None = None,
                    variant: str = "online"):
    """``build(cls, law, h, options)`` making each robot's online identification block (the
    robots' blocks are built in the scenario's order: the i-th call is robot i).

    With ``feed_controller`` the block writes its parameters into the controller's model too
    (the row), without it only its own estimate uses them (beside a loop closed on the
    sensor). ``prior`` maps a robot's name to its block's ``θ_0`` (default, and for a robot
    it leaves out: the controller's model's parameters); ``options`` are further keyword
    arguments of every block (e.g. ``v_min=inf``: no update, the prior held), over the
    ``variant``'s own (:data:`ONLINE_OPTIONS`).
    """
    from drake_coop.identification.online import OnlineIdentification
    from drake_coop.identification.regressor import Regressor, load_structure, true_parameters
    from drake_coop.plant.arms import Arm

    robots = iter(scenario.robots)
    prior, extra = prior or {}, {**ONLINE_OPTIONS[variant], **(options or {})}

    def build(cls, law, h, block_options):
        robot = next(robots)
        arm = Arm(robot, scenario.task)
        structure = load_structure(arm.urdf_path, arm.base_frame,
                                   sensor_joint=robot.sensor_joint)
        theta0 = prior.get(robot.name)
        if theta0 is None:
            theta0 = true_parameters(structure, law.model.plant)   # the controller's model's
        return OnlineIdentification(Regressor(structure), theta0, law.model.J_phi,
                                    law.layout, h, law.momentum_gain,
                                    model=law.model if feed_controller else None,
                                    clock=block_options.get("clock"), **extra)
    return build


@contextlib.contextmanager
def variant_built(scenario: Scenario, variant: str | None) -> Iterator[None]:
    """While inside, experiments of ``scenario`` are built with ``variant``'s force source in
    place of the momentum observer.

    Parameters
    ----------
    scenario : Scenario
        The case's scenario (``force_source: momentum`` on every robot).
    variant : str or None
        A key of :data:`VARIANTS`; None changes nothing.

    Yields
    ------
    None
        The swap holds until the block exits.
    """
    if not variant_matters(scenario, variant):
        yield
        return
    import drake_coop.control.block as block
    import drake_coop.control.registry as registry
    import drake_coop.experiment.diagram as diagram

    saved = (registry.SOURCES, block.SOURCES, diagram.AddCooperativeController)
    try:
        if variant == "applied_torque":
            limits = {r.name: r.actuators.torque_limits for r in scenario.robots}
            original = diagram.AddCooperativeController

            def with_applied_torque(*args, **kwargs):
                return original(*args, momentum_torque_limits=limits[kwargs["name"]], **kwargs)
            diagram.AddCooperativeController = with_applied_torque
        else:
            build = _online_builder(scenario, variant=variant)
            swapped = tuple(dataclasses.replace(s, build=build, outputs=("theta_hat",))
                            if (s.kind, s.name) == ("force", "momentum") else s
                            for s in registry.SOURCES)
            registry.SOURCES = block.SOURCES = swapped
        yield
    finally:
        registry.SOURCES, block.SOURCES, diagram.AddCooperativeController = saved


def run_variant_case(scenario_yaml: str, t_end: float, variant: str | None) -> dict:
    """Simulate one case of the table with its variant (as
    :func:`~drake_coop.studies.engines.run_case`).

    The scenario is loaded once (the run reuses it), its reachability check answered from
    :data:`REACH_CACHE` when this worker already checked the same inputs.

    Parameters
    ----------
    scenario_yaml : str
        The case's scenario.
    t_end : float
        Its end, s.
    variant : str or None
        The case's variant (a row's, or ``open_loop:<row>``), possibly after a clock
        (:func:`~drake_coop.studies.reference_clock.clock_variant`).

    Returns
    -------
    dict
        The case's record (``status``, ``message``, ``t_reached``, ``wall_time_s``,
        ``metrics``).
    """
    from drake_coop.scenario.loading import load_scenario
    from drake_coop.studies.engines import run_case
    from drake_coop.studies.reference_clock import arm_clocks, split_clock

    scenario = load_scenario(data=scenario_yaml, cache=REACH_CACHE)
    clock, variant = split_clock(variant)
    if variant is not None and variant.startswith("open_loop:"):
        from drake_coop.studies.reference_open_loop import open_loop_built

        row = variant.split(":", 1)[1]
        built = open_loop_built(scenario, row,
                                _online_builder(scenario, feed_controller=False)
                                if row == "online" else None)
    else:
        built = variant_built(scenario, variant)
    with built:
        return run_case(scenario_yaml, t_end, arm_clocks(scenario, clock), scenario)
