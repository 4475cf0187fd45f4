"""``drake-coop identify``: identify each robot of a scenario and write the results.

For each robot: design the excitation (:mod:`~drake_coop.identification.excitation`) from the
nominal model (the controller's model of the scenario: its URDF with the scenario's
``model_error`` scales, what the user starts from), run the experiment on the true simulated
arm (:mod:`~drake_coop.identification.collect`), estimate
(:mod:`~drake_coop.identification.estimate`), and write into ``DIR``:

* ``robotN_identified.urdf`` (:mod:`~drake_coop.identification.urdf_writer`);
* ``identify.json``: every parameter's estimate, nominal and (this is a simulation) true value
  and error; which parameters the joint torques determine; the regressor's condition number;
  the residual torque RMS; the data length; the model torque error on a validation trajectory
  (a different excitation) of the identified and of the nominal model against the truth;
* ``identify_fit.png``: measured and predicted torques;
* ``identified.yaml``: the input scenario with each identified robot's ``controller_model``
  set to its identified URDF and its controller-side scales (``mass_scale``,
  ``inertia_scale``, ``damping_scale``) back to 1; the simulated payload and Coulomb friction
  stay (they are the truth).

The folder is written whole: staged in a hidden sibling and renamed into place.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from drake_coop.identification.collect import ExcitationData, simulate_excitation
from drake_coop.identification.estimate import Estimate, estimate_parameters, prepare
from drake_coop.identification.instrumental import (
    ClosedLoop,
    estimate_parameters_didim,
    estimate_parameters_iv,
)
from drake_coop.identification.excitation import FourierExcitation, design_excitation
from drake_coop.identification.regressor import ArmStructure, identifiable_basis
from drake_coop.identification.setup import (
    IdentificationSetup,
    IdentifyInputError,
    design_for,
    identification_setup,
)
from drake_coop.identification.urdf_writer import identified_urdf_text
from drake_coop.results.io import OutputError, check_output_folder, staged_folder
from drake_coop.scenario.schema import Scenario

if TYPE_CHECKING:
    from drake_coop.identification.recording import WireRecording

#: Allowed excitation lengths (s).
DURATION_RANGE = (1.0, 120.0)
#: The estimators, by name: ``map_sdp`` the physically consistent MAP estimate
#: (:func:`~drake_coop.identification.estimate.estimate_parameters`), ``idim_iv`` the iterated
#: instrumental-variable estimate for closed-loop data under the same constraints
#: (:func:`~drake_coop.identification.instrumental.estimate_parameters_iv`), ``didim`` the
#: closed-loop output-error estimate on simulated states, same constraints
#: (:func:`~drake_coop.identification.instrumental.estimate_parameters_didim`).
ESTIMATORS = ("map_sdp", "idim_iv", "didim")
#: Files ``identify`` writes (an existing ``--out`` may hold only these).
OUTPUT_FILES = ("identify.json", "identify_fit.png", "identified.yaml", "recording.npz")


@dataclass
class RobotIdentification:
    """One robot's identification: its data, estimate and the reference values.

    Attributes
    ----------
    name : str
        The robot's name.
    structure : ArmStructure
        Its parameter layout.
    excitation : FourierExcitation
        The excitation run.
    data : ExcitationData
        The recorded experiment.
    estimate : Estimate
        The estimate.
    theta_true : numpy.ndarray
        The simulated arm's parameters (p,).
    theta_nominal : numpy.ndarray
        The nominal model's (p,).
    identifiable : numpy.ndarray
        Per parameter, the norm of its direction's projection on the identifiable subspace
        (0 to 1).
    validation : dict
        The torque prediction on a second excitation: the RMS errors of the identified and
        the nominal model's torques and the true torques' RMS (N·m).
    fit : dict
        The data used (``t``, ``tau``) and the identified and nominal models' torques on it
        (N·m).
    urdf_text : str
        The identified URDF.
    estimator : str
        One of :data:`ESTIMATORS`.
    """

    name: str
    structure: ArmStructure
    excitation: FourierExcitation
    data: ExcitationData
    estimate: Estimate
    theta_true: np.ndarray
    theta_nominal: np.ndarray
    identifiable: np.ndarray   # per parameter: norm of its direction's projection on the
    #                           identifiable subspace (1: the torques determine it; 0: never)
    validation: dict
    fit: dict
    urdf_text: str
    estimator: str = "map_sdp"


def identify_robot(scenario: Scenario, index: int, duration: float = 10.0, seed: int = 0,
                   estimator: str = "map_sdp", q0: np.ndarray | None = None
                   ) -> RobotIdentification:
    """Identify robot ``index`` of ``scenario`` (module docstring): the excitation
    (:func:`design_for`), the simulated experiment, then :func:`identify_from_data`.

    Parameters
    ----------
    scenario : Scenario
        The scenario whose robot is identified (the simulated truth).
    index : int
        The robot (0-based).
    duration : float
        Excitation length (s).
    seed : int
        The excitation's random candidates.
    estimator : str
        One of :data:`ESTIMATORS`.
    q0 : numpy.ndarray or None
        The excitation's centre (default: the middle of the joint range).

    Returns
    -------
    RobotIdentification
        The estimate, the identified URDF's text and its validation.

    Raises
    ------
    IdentifyInputError
        When no excitation fits the arm's limits, or an unknown ``estimator``.
    """
    if estimator not in ESTIMATORS:
        raise IdentifyInputError(f"estimator must be one of {', '.join(ESTIMATORS)}, "
                                 f"got {estimator!r}")
    setup = identification_setup(scenario, index)
    excitation = design_for(setup, duration, seed, q0, scenario.robots[index].name)
    data = simulate_excitation(scenario, index, excitation, setup.nominal)
    return identify_from_data(scenario, setup, excitation, data, seed, estimator)


def identify_from_data(scenario: Scenario, setup: IdentificationSetup,
                       excitation: FourierExcitation, data: ExcitationData, seed: int = 0,
                       estimator: str = "map_sdp") -> RobotIdentification:
    """The estimate from recorded data, whatever recorded it (the simulated experiment, or a
    recording of the wire: :mod:`~drake_coop.identification.recording`): the one path from
    ``q``, ``τ`` at ``h`` to the identified model, its validation and its URDF.

    Parameters
    ----------
    scenario : Scenario
        The scenario (its robot's truth, for the validation's reference).
    setup : IdentificationSetup
        The robot's setup.
    excitation : FourierExcitation
        The excitation the data followed.
    data : ExcitationData
        The recorded ``t``, ``q``, ``τ``, ``h`` and torque limits.
    seed : int
        Seeds the validation trajectory (``seed + 1``).
    estimator : str
        One of :data:`ESTIMATORS`.

    Returns
    -------
    RobotIdentification
        The estimate, the identified URDF's text and its validation.
    """
    from drake_coop.identification.excitation import ExcitationError

    index, structure, regressor = setup.index, setup.structure, setup.regressor
    robot = scenario.robots[index]
    nominal, theta_true, theta_nominal = setup.nominal, setup.theta_true, setup.theta_nominal
    n = structure.n
    duration = excitation.duration
    prepared = prepare(data.t, data.q, data.tau, data.h, data.torque_limits)
    estimate = estimate_parameters(regressor, prepared, theta_nominal)
    if estimator == "idim_iv":
        estimate = estimate_parameters_iv(
            regressor, prepared, theta_nominal,
            closed_loop(scenario, index, excitation, nominal, data), start=estimate)
    elif estimator == "didim":
        estimate = estimate_parameters_didim(
            regressor, data.tau, theta_nominal,
            closed_loop(scenario, index, excitation, nominal, data), start=estimate)
    Y = regressor.matrix(prepared.q, prepared.v, prepared.a)
    scale, V = identifiable_basis(Y)
    identifiable = np.linalg.norm(V, axis=1)
    # Validation: a different excitation, exact states, torques of the truth (no friction
    # term: the Coulomb column's smoothing is the identification's own choice).
    try:
        other, _ = design_excitation(duration, excitation.q0, setup.limits,
                                     setup.nominal_torque, regressor.matrix,
                                     seed=seed + 1, candidates=3)
    except ExcitationError:        # no second trajectory fits: validate on the first one
        other = excitation
    tv = np.linspace(0.0, duration, 400)
    Yv = regressor.matrix(*other.evaluate(tv))
    no_coulomb = np.ones(structure.num_parameters)
    no_coulomb[structure.joint_slice("coulomb")] = 0.0
    tau_true = Yv @ (theta_true * no_coulomb)

    def rms(theta):
        return float(np.sqrt(np.mean((Yv @ (theta * no_coulomb) - tau_true) ** 2)))

    validation = {"torque_error_rms_identified": rms(estimate.theta),
                  "torque_error_rms_nominal": rms(theta_nominal),
                  "torque_rms": float(np.sqrt(np.mean(tau_true ** 2)))}
    fit = {"t": prepared.t, "tau": prepared.tau,
           "identified": (Y @ estimate.theta).reshape(-1, n),
           "nominal": (Y @ theta_nominal).reshape(-1, n)}
    nominal_text = Path(setup.arm.controller_urdf_path).read_text()
    urdf_text = identified_urdf_text(
        nominal_text, structure, estimate.theta,
        note=f"Robot {robot.name}, {duration:g} s of excitation.")
    return RobotIdentification(robot.name, structure, excitation, data, estimate, theta_true,
                               theta_nominal, identifiable, validation, fit, urdf_text,
                               estimator)


def identify_recording(scenario, recording: WireRecording, seed: int = 0,
                       estimator: str = "map_sdp"):
    """Identify the recording's arm (:func:`identify_from_data`, the simulated experiment's
    path).

    Parameters
    ----------
    scenario : Scenario
        The scenario the arm belongs to (its nominal model; its truth for the validation).
    recording : WireRecording
        The arm's rows (:mod:`~drake_coop.identification.recording`).
    seed : int
        Seeds the validation trajectory.
    estimator : str
        One of :data:`~drake_coop.identification.report.ESTIMATORS`.

    Returns
    -------
    RobotIdentification
        The estimate, the identified URDF's text and its validation.

    Raises
    ------
    IdentifyInputError
        The recording does not fit the scenario (robot, joints, control period).
    """
    import math

    from drake_coop.experiment.ticks import time_grid

    names = [r.name for r in scenario.robots]
    i = recording.index
    if not (0 <= i < len(names)) or names[i] != recording.robot:
        raise IdentifyInputError(f"--recording: robot {recording.robot!r} (index {i}) is not "
                                 f"in the scenario ({', '.join(names)})")
    setup = identification_setup(scenario, i)
    if recording.q.shape[1] != setup.structure.n:
        raise IdentifyInputError(f"--recording: {recording.robot} has {recording.q.shape[1]} "
                                 f"joints, the scenario's arm {setup.structure.n}")
    h, _ = time_grid(scenario)
    if not math.isclose(recording.h, h, rel_tol=1e-9):
        raise IdentifyInputError(f"--recording: {recording.robot} was recorded at h = "
                                 f"{recording.h:g} s, the scenario's control_period is {h:g} s")
    return identify_from_data(scenario, setup, recording.excitation, recording.data(), seed,
                              estimator)


def closed_loop(scenario: Scenario, index: int, excitation: FourierExcitation, nominal,
                data: ExcitationData) -> ClosedLoop:
    """The identification experiment's closed loop as the IV instruments simulate it: the
    reference and the tracking law's nominal feedforward at the recorded ticks, its gains
    (:func:`~drake_coop.identification.collect.tracking_gains`), the plant steps per tick,
    the torque limits and the encoders' delay.

    Parameters
    ----------
    scenario : Scenario
        The scenario (the robot's torque limits and encoders).
    index : int
        The robot (0-based).
    excitation : FourierExcitation
        The excitation run.
    nominal : ArmModel
        The model of the tracking law's feedforward.
    data : ExcitationData
        The recorded experiment (its ticks and torque limits).
    """
    from drake_coop.experiment.ticks import time_grid
    from drake_coop.identification.collect import tracking_gains

    h, dt = time_grid(scenario)
    q_d, v_d, a_d = excitation.evaluate(data.t)
    feedforward = np.array([nominal.inverse_dynamics_terms(q_d[k], v_d[k], a_d[k])
                            for k in range(len(data.t))])
    kp, kv = tracking_gains(nominal, excitation.q0)
    return ClosedLoop(q_d=q_d, v_d=v_d, feedforward=feedforward, kp=kp, kv=kv, h=h,
                      substeps=max(1, int(round(h / dt))), torque_limits=data.torque_limits,
                      encoder_delay=int(scenario.robots[index].encoders.delay_samples))


def masses(ident: RobotIdentification) -> dict:
    """Each composite body's mass: identified, nominal, true, relative error, identifiable.

    Parameters
    ----------
    ident : RobotIdentification
        One robot's identification.

    Returns
    -------
    dict
        Link → its masses (kg) and relative error.
    """
    out = {}
    for i, link in enumerate(ident.structure.links):
        k = 10 * i
        true = float(ident.theta_true[k])
        out[link] = {"identified": float(ident.estimate.theta[k]),
                     "nominal": float(ident.theta_nominal[k]), "true": true,
                     "relative_error": float(ident.estimate.theta[k] / true - 1.0),
                     "identifiability": float(ident.identifiable[k]),
                     "bodies": ident.structure.members[link]}
    return out


def summary(ident: RobotIdentification, duration: float) -> dict:
    """The ``identify.json`` entry of one robot.

    Parameters
    ----------
    ident : RobotIdentification
        One robot's identification.
    duration : float
        The excitation's length, s.
    """
    s = ident.structure
    e = ident.estimate
    params = {}
    for k, name in enumerate(s.parameter_names()):
        params[name] = {"identified": float(e.theta[k]), "nominal": float(ident.theta_nominal[k]),
                        "true": float(ident.theta_true[k]),
                        "error": float(e.theta[k] - ident.theta_true[k]),
                        "identifiability": float(ident.identifiable[k])}
    return {
        "urdf": f"{ident.name}_identified.urdf",
        "duration_s": duration, "samples_recorded": int(ident.data.t.size),
        "samples_used": e.samples, "control_period_s": ident.data.h,
        "regressor_condition_number": e.condition_number,
        "identifiable_combinations": e.rank, "parameters_total": s.num_parameters,
        "residual_torque_rms": e.residual_rms.tolist(), "solver": e.solver,
        "estimator": ident.estimator,
        "estimator_stopped": getattr(e, "stopped", ""),
        "validation": ident.validation, "masses": masses(ident), "parameters": params,
        "excitation": {"q0": ident.excitation.q0.tolist(), "period_s": ident.excitation.period,
                       "harmonics": int(ident.excitation.a.shape[1]),
                       "a": ident.excitation.a.tolist(), "b": ident.excitation.b.tolist()},
        "velocity_source": "offline Savitzky-Golay (window 15 samples, order 3, zero phase)",
    }


def fit_figure(idents: list[RobotIdentification], path: Path) -> None:
    """Measured (filtered) torques against the identified and nominal models' predictions.

    Parameters
    ----------
    idents : list of RobotIdentification
        The robots.
    path : Path
        The figure's file.
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    n = max(i.structure.n for i in idents)
    fig, axes = plt.subplots(n, len(idents), figsize=(5.5 * len(idents), 1.9 * n),
                             sharex=True, squeeze=False)
    for c, ident in enumerate(idents):
        f = ident.fit
        for j in range(ident.structure.n):
            ax = axes[j, c]
            ax.plot(f["t"], f["tau"][:, j], "k", lw=1.2, label="commanded (filtered)")
            ax.plot(f["t"], f["identified"][:, j], "C0--", lw=1, label="identified model")
            ax.plot(f["t"], f["nominal"][:, j], "C3:", lw=1, label="nominal model")
            ax.set_ylabel(f"τ{j + 1} [N·m]")
            if j == 0:
                ax.set_title(f"{ident.name}: residual RMS "
                             + ", ".join(f"{r:.3f}" for r in ident.estimate.residual_rms))
        axes[-1, c].set_xlabel("t [s]")
    axes[0, 0].legend(fontsize=7, loc="upper right")
    fig.tight_layout()
    fig.savefig(path, dpi=80)
    plt.close(fig)


def identified_scenario(scenario: Scenario, idents: dict[int, RobotIdentification]
                        ) -> Scenario:
    """``identified.yaml``'s scenario (module docstring).

    Parameters
    ----------
    scenario : Scenario
        The scenario identified.
    idents : dict of int to RobotIdentification
        Robot index → its identification.

    Returns
    -------
    Scenario
        The scenario with the identified controller models.
    """
    import copy

    out = copy.deepcopy(scenario)
    for i, ident in idents.items():
        robot = out.robots[i]
        robot.controller_model = f"{ident.name}_identified.urdf"
        robot.model_error.mass_scale = 1.0
        robot.model_error.inertia_scale = 1.0
        robot.model_error.damping_scale = 1.0
    return out


def _check_out(out: Path) -> None:
    if out.exists() and not out.is_dir():
        raise IdentifyInputError(f"--out {out} exists and is not a folder")
    if out.is_dir():
        ours = set(OUTPUT_FILES)
        for e in out.iterdir():
            if not (e.is_file() and (e.name in ours or e.name.endswith("_identified.urdf"))):
                raise IdentifyInputError(f"--out {out} holds {e.name!r}, which identify did "
                                         f"not write; use an empty or new folder")
    try:
        check_output_folder(out)
    except OutputError as exc:
        raise IdentifyInputError(str(exc)) from None


def parse_robots(text: str | None, count: int) -> list[int]:
    """``--robots 1,2`` as 0-based indices (all robots when None).

    Parameters
    ----------
    text : str or None
        ``--robots``' value (1-based, comma-separated).
    count : int
        The scenario's robots.
    """
    if text is None:
        return list(range(count))
    try:
        numbers = [int(x) for x in text.split(",") if x.strip()]
    except ValueError:
        numbers = []
    if not numbers or any(not 1 <= k <= count for k in numbers) or len(set(numbers)) != len(numbers):
        raise IdentifyInputError(f"--robots must list distinct robot numbers from 1 to {count} "
                                 f"separated by commas, got {text!r}")
    return [k - 1 for k in numbers]


def run_identify(scenario: Scenario, out: str | Path, robots: list[int],
                 duration: float = 10.0, seed: int = 0, log=print,
                 estimator: str = "map_sdp", recordings: dict | None = None,
                 source: str = "simulation") -> dict:
    """Identify ``robots`` of ``scenario`` and write ``out`` whole (module docstring).

    Parameters
    ----------
    scenario : Scenario
        The scenario.
    out : str or Path
        The output folder (new, or one of ours).
    robots : list of int
        The robots (0-based).
    duration : float
        The excitation's length, s.
    seed : int
        Seeds the excitation's candidates.
    log : Callable[[str], None]
        Receives progress lines.
    estimator : str
        One of :data:`ESTIMATORS`.
    recordings : dict of int to WireRecording or None
        Identify each robot from its recording
        (:func:`identify_recording`) instead of the
        simulated experiment; written to ``recording.npz`` when ``source`` is ``wire``.
    source : str
        Where the data came from, for ``identify.json``: ``simulation``, ``wire`` (driven
        now) or ``recording FILE``.

    Returns
    -------
    dict
        The contents of ``identify.json``.
    """
    from drake_coop.scenario.loading import dump_scenario

    lo, hi = DURATION_RANGE
    if not lo <= duration <= hi:
        raise IdentifyInputError(f"--duration must be in [{lo:g}, {hi:g}] s, got {duration:g}")
    if isinstance(seed, bool) or not isinstance(seed, int) or not 0 <= seed < 2**32 - 1:
        raise IdentifyInputError(f"--seed must be an integer from 0 to {2**32 - 2}, got {seed!r}")
    if estimator not in ESTIMATORS:
        raise IdentifyInputError(f"--estimator must be one of {', '.join(ESTIMATORS)}, "
                                 f"got {estimator!r}")
    out = Path(out)
    _check_out(out)
    idents = {}
    for i in robots:
        if recordings is not None:
            log(f"drake-coop: identifying {scenario.robots[i].name} from its recording "
                f"({source})")
            idents[i] = identify_recording(scenario, recordings[i], seed, estimator)
            continue
        log(f"drake-coop: identifying {scenario.robots[i].name} ({duration:g} s of excitation)")
        idents[i] = identify_robot(scenario, i, duration, seed, estimator)
    report = {"scenario_robots": [r.name for r in scenario.robots], "data_source": source,
              "robots": {ident.name: summary(ident, ident.excitation.duration)
                         for ident in idents.values()}}
    with staged_folder(out) as staging:
        kept = source.startswith("recording ") and (out / "recording.npz").resolve() == \
            Path(source[len("recording "):]).resolve()     # the folder replaced holds it
        if recordings is not None and (source == "wire" or kept):
            from drake_coop.identification.recording import write_recording

            write_recording(staging / "recording.npz",
                            [recordings[i] for i in sorted(recordings)])
        for ident in idents.values():
            (staging / f"{ident.name}_identified.urdf").write_text(ident.urdf_text)
        (staging / "identify.json").write_text(json.dumps(report, indent=1))
        fit_figure(list(idents.values()), staging / "identify_fit.png")
        (staging / "identified.yaml").write_text(
            "# Written by drake-coop identify: the input scenario with the identified "
            "controller models.\n" + dump_scenario(identified_scenario(scenario, idents)))
    return report
