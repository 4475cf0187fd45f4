"""What the ground truth and the sensor models cost: the plant alone with each of them added,
alternated with the plant alone in one process (:func:`_sensing_attribution`)."""

from __future__ import annotations

import statistics
from collections import defaultdict

from bench.runs import _plant_alone, _spread


def _hold(port_of, offset_of):
    """``extras`` for :func:`_plant_alone`: a C++ ``ZeroOrderHold`` of one plant port, period
    ``h``, at ``offset_of(h, dt)`` (no Python: what a read of that port costs the plant)."""
    def extras(b, coop, h, dt):
        from pydrake.systems.primitives import ZeroOrderHold

        port = port_of(coop.plant)
        hold = b.AddSystem(ZeroOrderHold(h, port.size(), offset_of(h, dt)))
        b.Connect(port, hold.get_input_port())
    return extras


def _ground_truth(with_models: bool):
    """``extras`` for :func:`_plant_alone`: the experiment's ground truth
    (:func:`~drake_coop.plant.wrist.add_force_sensors`, latched at every tick) and, with
    ``with_models``, the F/T sensor models wired as in the experiment."""
    def extras(b, coop, h, dt):
        from drake_coop.plant.wrist import add_force_sensors
        from drake_coop.sensing import force_sensor

        sensors = add_force_sensors(b, coop, h)
        if with_models:
            for i, (handles, sensor) in enumerate(zip(coop.arms, sensors)):
                live = sensor.GetOutputPort("lambda_meas")
                if hasattr(force_sensor, "add_ft_sensor"):
                    force_sensor.add_ft_sensor(b, handles.arm.name, h, dt, None, i,
                                               handles.arm.m, live, sensor.lambda_last_step)
                else:     # the first pass's wiring (for a before/after run of this bench)
                    ft = b.AddSystem(force_sensor.FTSensor(h, dt, None, i, handles.arm.m))
                    b.Connect(live, ft.GetInputPort("lambda_true"))
    return extras


def _contact_reaction_ground_truth(b, coop, h, dt):
    """``extras`` for :func:`_plant_alone` in ``contact`` mode: the ground truth as it was
    before ``pad_forces`` (Newton's law on the reaction forces and body lists,
    :class:`~drake_coop.plant.wrist.WristKinematics`, latched at every tick, and the F/T
    models reading the live force at ``t_k − 3Δt/2``), for the before/after comparison."""
    from drake_coop.plant.wrist import ForceSensor, WristKinematics
    from drake_coop.sensing.force_sensor import FTSensor

    plant = coop.plant
    wrist = b.AddSystem(WristKinematics(plant, coop.arms))
    for name in ("reaction_forces", "body_poses", "body_spatial_velocities",
                 "body_spatial_accelerations"):
        b.Connect(plant.GetOutputPort(name), wrist.GetInputPort(name))
    for i, handles in enumerate(coop.arms):
        sensor = b.AddSystem(ForceSensor(plant, handles, h))
        b.Connect(wrist.GetOutputPort(f"{handles.arm.name}_wrist"), sensor.GetInputPort("wrist"))
        ft = b.AddSystem(FTSensor(h, dt, None, i, handles.arm.m))
        b.Connect(sensor.GetOutputPort("lambda_meas"), ft.GetInputPort("lambda_true"))


def _contact_pad_force_log(b, coop, h, dt):
    """``extras`` for :func:`_plant_alone` in ``contact`` mode: the experiment's ground truth
    (:func:`~drake_coop.plant.ground_truth.add_pad_force_log`: the pads' forces read by a C++
    hold at every plant step and logged) and, after the run, its evaluation of every tick
    (``F_meas``, ``lambda_meas``, ideal F/T models' ``lambda_sensor``)."""
    from drake_coop.plant.ground_truth import add_pad_force_log
    from drake_coop.sensing.force_sensor import FTModel

    truth = add_pad_force_log(b, coop, h, [FTModel.from_settings(None, h, i, a.arm.m)
                                           for i, a in enumerate(coop.arms)])
    steps = int(round(h / dt))

    def finish(context):
        published = truth.logger.FindLog(context).num_samples()
        truth.evaluate(context, max((published - 2) // steps, 0), False)
    return finish


#: :func:`_sensing_attribution`'s additions for a ``contact`` scenario.
_CONTACT_ATTRIBUTION = {
    "contact ground truth now: pad forces held and logged at every plant step (C++), "
    "evaluated after the run":
        _contact_pad_force_log,
    "contact ground truth, first version: reaction forces + body lists at t_k and t_k - 3dt/2":
        _contact_reaction_ground_truth,
}


def _offline_ground_truth(b, coop, h, dt):
    """``extras`` for :func:`_plant_alone`: the offline ground truth's C++ holds and log
    (:func:`~drake_coop.plant.ground_truth.add_ground_truth`, ideal F/T models) and, after
    the run, its evaluation of every tick (``F_meas``, ``lambda_meas``, ``lambda_sensor``)."""
    from drake_coop.plant.ground_truth import add_ground_truth
    from drake_coop.sensing.force_sensor import FTModel

    gt = add_ground_truth(b, coop, h, [FTModel.from_settings(None, h, i, a.arm.m)
                                       for i, a in enumerate(coop.arms)],
                          [b.GetSubsystemByName(f"{a.arm.name}_torque").get_output_port()
                           for a in coop.arms])

    def finish(context):
        published = gt.logger.FindLog(context).num_samples()
        gt.evaluate(context, max(published - 1, 0), False)
    return finish


#: Diagrams of :func:`_sensing_attribution`: the plant alone plus one addition each.
_ATTRIBUTION = {
    "C++ hold of the plant state at t_k - 3dt/2 (an event, no solve)":
        _hold(lambda plant: plant.get_state_output_port(), lambda h, dt: h - 1.5 * dt),
    "C++ hold of the acceleration port at t_k - 3dt/2 (a solve off the plant's update)":
        _hold(lambda plant: plant.get_generalized_acceleration_output_port(),
              lambda h, dt: h - 1.5 * dt),
    "C++ hold of the acceleration port at t_k (the plant's own update's solve)":
        _hold(lambda plant: plant.get_generalized_acceleration_output_port(),
              lambda h, dt: 0.0),
    "ground truth, latched at every tick": _ground_truth(False),
    "ground truth + both F/T sensor models (the live chain, force_source: sensor)":
        _ground_truth(True),
    "offline ground truth: C++ holds + evaluation after the run (the paper's run)":
        _offline_ground_truth,
}



def _sensing_attribution(scenario, t_end: float, repeats: int,
                         additions: dict | None = None) -> dict:
    """CPU seconds of the plant alone and of the plant with each addition of
    :data:`_ATTRIBUTION`, alternated ``repeats`` times in this process; each addition's extra
    cost per control tick (median of its pairs with the plant alone run just before it) and as
    a share of the plant alone's cost per tick."""
    from drake_coop.experiment.ticks import num_ticks_until
    from drake_coop.experiment.ticks import time_grid

    h, _ = time_grid(scenario)
    ticks = num_ticks_until(t_end, h)
    extra: dict[str, list[float]] = defaultdict(list)
    plant: list[float] = []
    for _ in range(max(1, repeats)):
        for label, extras in (_ATTRIBUTION if additions is None else additions).items():
            alone = _plant_alone(scenario, t_end)[1]
            with_it = _plant_alone(scenario, t_end, extras)[1]
            plant.append(alone)
            extra[label].append(1e6 * (with_it - alone) / ticks)
    plant_us = 1e6 * statistics.median(plant) / ticks
    rows = {label: {**_spread(v), "share": statistics.median(v) / plant_us}
            for label, v in extra.items()}
    return {"plant_alone_us_per_tick": plant_us, "extra_us_per_tick": rows}
