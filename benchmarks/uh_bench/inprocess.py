"""In-process measurements: the reference simulation's real-time factor and per-step costs.

:func:`reference_rtf` times :func:`uh_team.team_simulation.run_team_simulation` (its own
``wall_time``: the stepping loop, without loading). :func:`component_costs` repeats that loop
with a timer around each call, giving the cost of one UH-step of the controller
(``UHController.step``), of the helicopter model (``HelicopterPlant.step``: RK4 over one control
period) and of the true-fault computation the simulator publishes (``lumped_faults``): the floor
a distributed run can approach, since every node process runs exactly these calls.
"""
from __future__ import annotations

import statistics
import time

import numpy as np

__all__ = ['reference_rtf', 'component_costs']


def reference_rtf(scenario, duration: float | None = None, case: str = 'proposed') -> dict:
    """Real-time factor of the in-process reference run of ``scenario`` (a Scenario or path/name)."""
    from uh_team.team_simulation import run_team_simulation
    from uh_topology.scenario import load_scenario

    sc = load_scenario(scenario)
    duration = float(sc.duration if duration is None else duration)
    run = run_team_simulation(sc, case=case, duration=duration)
    return {'scenario': str(sc.name), 'uhs': len(sc.ids), 'duration_s': duration,
            'wall_s': run.wall_time, 'rtf': duration / run.wall_time, 'finite': bool(run.all_finite())}


def component_costs(scenario, steps: int = 1000, case: str = 'proposed', safety: bool = False) -> dict:
    """Mean and median microseconds per UH-step of the controller, the model and the fault truth.

    Runs ``steps`` control steps of the whole team in process (the reference simulation's order)
    and times every call with ``perf_counter_ns``; the timer itself costs well under 1 % of a
    call. The first 50 steps (start-up transients, first-call caches) are left out. With
    ``safety`` the controllers run the safety filter (docs/safety.md), its proximity input built
    from the true states before each controller step and timed with it (``controller``).
    """
    from uh_controller_node.controller import UHController
    from uh_controller_node.safety import proximity_input
    from uh_core.airframe import load_helicopter_params
    from uh_core.reference import VirtualLeaderReference
    from uh_sim_node.helicopter import plant_from_scenario
    from uh_topology.scenario import load_scenario

    sc = load_scenario(scenario, safety=safety)
    ids = tuple(sc.ids)
    params = load_helicopter_params(sc.helicopter)
    plants = [plant_from_scenario(sc, i, params) for i in ids]
    ctls = [UHController(i, sc, case, helicopter_params=params) for i in ids]
    col = {i: c for c, i in enumerate(ids)}
    hears = [tuple(col[j] for j in ctl.neighbours) for ctl in ctls]
    linked = [ctl.leader_link > 0.0 for ctl in ctls]
    reference = VirtualLeaderReference(sc.reference)
    dt = float(sc.dt)
    warm = 50
    t_ctl, t_plant, t_truth = [], [], []
    clock = time.perf_counter_ns
    for k in range(steps + warm):
        t = k * dt
        r = reference.at(t)
        xs = [p.x for p in plants]
        stacked = np.array(xs)
        positions, velocities = stacked[:, 0:3], stacked[:, 3:6]
        us = []
        for c, ctl in enumerate(ctls):
            nb = {ids[j]: xs[j] for j in hears[c]}
            ref = r if linked[c] else None
            t0 = clock()
            if safety:
                ctl.set_proximity(proximity_input(positions, velocities, c, ctl.sensing_radius)[0])
            u, _ = ctl.step(k, xs[c], nb, ref, dt)
            t1 = clock()
            us.append(u)
            if k >= warm:
                t_ctl.append(t1 - t0)
        for c, plant in enumerate(plants):
            t0 = clock()
            plant.lumped_faults(us[c], t)
            t1 = clock()
            plant.step(us[c], t, dt)
            t2 = clock()
            if k >= warm:
                t_truth.append(t1 - t0)
                t_plant.append(t2 - t1)

    def stats(ns):
        return {'mean_us': statistics.fmean(ns) / 1000.0, 'median_us': statistics.median(ns) / 1000.0}
    return {'scenario': str(sc.name), 'uhs': len(ids), 'steps': steps, 'substeps': int(sc.substeps), 'safety': safety,
            'controller': stats(t_ctl), 'model': stats(t_plant), 'fault_truth': stats(t_truth)}
