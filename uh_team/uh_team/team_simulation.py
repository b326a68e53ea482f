"""In-process reference simulation of a whole team (docs/architecture.md, docs/scenario.md).

Every UH gets a :class:`~uh_sim_node.helicopter.HelicopterPlant` and a
:class:`~uh_controller_node.controller.UHController` — the very objects the distributed nodes use.
Step ``k`` (``t_k = k * dt``):

1. every controller consumes the states ``x_j(t_k)`` of itself and of its neighbours (ascending id)
   and, if it hears the virtual leader, the reference at ``t_k``, and returns ``u_k``;
2. the true lumped faults at ``(x(t_k), u_k, t_k)`` are recorded;
3. every plant holds ``u_k`` over ``[t_k, t_k + dt)`` and integrates (RK4, ``substeps``) to ``x(t_{k+1})``.

After the last step the controllers run once more at ``t_K`` so the per-step arrays have a row for
every state sample (that last command is not applied). The arrays follow the layout of
``uh_report.bag_metrics.read_team_bag`` so the reference run and a recorded distributed run are
compared and scored by the same code (:func:`uh_team.metrics.metrics_from_arrays`).
"""
from __future__ import annotations

import time as _time
from dataclasses import dataclass, field
from typing import Callable

import numpy as np

from uh_controller_node.controller import UHController
from uh_controller_node.gains import CASES, GainsError
from uh_controller_node.impairments import ReceivedStates
from uh_controller_node.proximity_input import ProximityInput
from uh_controller_node.safety import proximity_input
from uh_core.airframe import load_helicopter_params
from uh_core.layout import R_P_SLICE, R_V_SLICE, R_YAW, REFERENCE_SIZE, X_P_SLICE
from uh_core.reference import VirtualLeaderReference
from uh_sim_node.helicopter import plant_from_scenario
from uh_topology.errors import GainsFileError
from uh_topology.scenario import duration_steps

from .metrics import containment_errors, formation_errors
from .reconfiguration import errors_in_force, leaving_rows
from .run_arrays import RUN_REF_POSITION, new_run_arrays

__all__ = ['SimulationError', 'TeamRun', 'run_team_simulation', 'ENGINES']

#: Ways to run the step loop (see :func:`run_team_simulation`).
ENGINES = ('kernel', 'objects')


class SimulationError(ValueError):
    """Bad simulation request (unknown case, bad duration) or a run that produced non-finite values."""


@dataclass
class TeamRun:
    """Time series of one team run. UH axis ordered as ``ids`` (leaders first); ``K`` control steps.

    Attributes
    ----------
    scenario_name, case : str
    ids : tuple of int
    dt : float
        Control period, s.
    time : ndarray (K+1,)
        t_k = k dt, s.
    states : ndarray (K+1, n, 12)
        ``[p, v, Theta, omega]`` per UH, SI units.
    commands : ndarray (K+1, n, 4)
        ``(theta_col, theta_tr, delta_lat, delta_lon)`` rad; row ``K`` is computed but not applied.
    reference : ndarray (K+1, 5)
        Virtual leader ``(x0, y0, z0, psi0, psi0')`` m, rad, rad/s.
    fault_true_p, fault_true_w : ndarray (K+1, n, 3)
        True lumped faults (m/s^2 inertial, rad/s^2 body) for the command of the row.
    fault_est_p, fault_est_w : ndarray (K+1, n, 3)
        The controllers' estimates used at that step.
    u_p : ndarray (K+1, n, 3)
        Designed accelerations, m/s^2.
    z1 : ndarray (K+1, n, 3)
        Consensus errors, m.
    saturated : ndarray (K+1, n) bool
        Any input limit active.
    safety_active : ndarray (K+1, n) bool
        The safety filter changed the UH's ``u_p`` (docs/safety.md; all False with the filter off).
    errors : ndarray (K+1, n)
        Formation error ``|p_i - h_i - p_0|`` (leaders) or containment error
        ``|p_k - sum_j w_kj p_j|`` (followers), m; with events against the team in force (NaN for a UH
        outside it, docs/resilience.md).
    wall_time : float
        Wall-clock time of the stepping loop, s.
    stuck_uhs : tuple of int
        UHs with a stuck actuator (rho = 0) during the run: outside what the controller compensates.
    events : LossSchedule or None
        With the scenario's ``events``: when each UH learnt of each loss (:class:`~uh_team.team_events.LossSchedule`).
    """

    scenario_name: str
    case: str
    ids: tuple
    dt: float
    time: np.ndarray
    states: np.ndarray
    commands: np.ndarray
    reference: np.ndarray
    fault_true_p: np.ndarray
    fault_true_w: np.ndarray
    fault_est_p: np.ndarray
    fault_est_w: np.ndarray
    u_p: np.ndarray
    z1: np.ndarray
    saturated: np.ndarray
    safety_active: np.ndarray
    errors: np.ndarray
    wall_time: float
    stuck_uhs: tuple = field(default_factory=tuple)
    events: object = None

    ARRAY_KEYS = ('time', 'states', 'commands', 'reference', 'fault_true_p', 'fault_true_w',
                  'fault_est_p', 'fault_est_w', 'u_p', 'z1', 'saturated', 'safety_active', 'errors')

    def arrays(self) -> dict:
        """Return the time series as a dict (``timeseries.npz`` content, plus ``ids``)."""
        out = {k: getattr(self, k) for k in self.ARRAY_KEYS}
        out['ids'] = np.array(self.ids)
        if self.events is not None and self.events.leaving:   # rows [uh, step, channel] of the UHs that left
            out['leaving'] = leaving_rows(self.events.leaving)
        return out

    def all_finite(self) -> bool:
        """Tell whether no array holds NaN or infinity (``errors`` aside: NaN for a UH outside the team in force)."""
        return all(np.isfinite(getattr(self, k)).all() for k in self.ARRAY_KEYS
                   if k not in ('saturated', 'safety_active', 'errors'))


def _errors(states, reference, scenario, happened=None):
    """Compute the formation errors of the leaders, then the containment errors of the followers (K+1, n), m.

    With ``happened`` (a run with events: its :class:`~uh_team.team_events.LossSchedule`) against the team in
    force at each step, NaN for a UH outside it
    (:func:`uh_team.reconfiguration.errors_in_force`).
    """
    if happened is not None:
        return errors_in_force(states, reference[:, RUN_REF_POSITION], scenario, happened)
    n_lead = len(tuple(scenario.leaders))
    pos = states[:, :, X_P_SLICE]
    out = np.empty(states.shape[:2])
    offsets = np.array([scenario.offsets[i] for i in scenario.leaders])
    out[:, :n_lead] = formation_errors(pos[:, :n_lead], reference[:, RUN_REF_POSITION], offsets)
    if tuple(scenario.followers):
        out[:, n_lead:] = containment_errors(pos[:, n_lead:], pos[:, :n_lead], scenario.containment_weights)
    return out


def run_team_simulation(scenario, case: str = 'proposed', duration: float | None = None,
                        progress: Callable[[int, int], None] | None = None, engine: str = 'kernel') -> TeamRun:
    """Run the whole team in one process with the per-UH controllers (see module docstring).

    Parameters
    ----------
    scenario : uh_topology.scenario.Scenario
    case : str
        ``'proposed'``, ``'case1'`` or ``'case2'`` (docs/control_law.md#comparison-cases).
    duration : float, optional
        Simulated time, s (default ``scenario.duration``): a whole number of control periods
        (:func:`uh_topology.scenario.duration_steps`).
    progress : callable, optional
        ``progress(k, K)`` called now and then (about every 1 % of the steps and at the end).
    engine : str
        ``'kernel'`` (default): the whole step loop in one native kernel
        (:func:`uh_team.team_kernel.run_team_steps`); ``'objects'``: a Python loop calling
        ``UHController.step`` and ``HelicopterPlant.step`` per UH, as the distributed nodes do. Both
        call the same kernels and give bit-identical results.

    Returns
    -------
    TeamRun

    Raises
    ------
    SimulationError
        Unknown case, a duration that is not a positive finite number of at least one step, or a
        state that became non-finite (the step and UH are named).
    """
    if case not in CASES:
        raise SimulationError(f'unknown controller case {case!r}; allowed: {", ".join(CASES)}')
    if engine not in ENGINES:
        raise SimulationError(f'unknown engine {engine!r}; allowed: {", ".join(ENGINES)}')
    dt = float(scenario.dt)
    if duration is None:
        duration = float(scenario.duration)
    try:
        K = duration_steps(duration, dt)
    except ValueError as exc:
        raise SimulationError(f'duration {exc}') from None

    ids = tuple(scenario.ids)
    n = len(ids)
    params = load_helicopter_params(scenario.helicopter)
    plants = [plant_from_scenario(scenario, i, params) for i in ids]
    try:
        controllers = [UHController(i, scenario, case, helicopter_params=params) for i in ids]
    except (GainsError, GainsFileError) as exc:
        raise SimulationError(str(exc)) from None
    reference = VirtualLeaderReference(scenario.reference)
    arrays, happened = None, None
    if engine == 'kernel':
        # imported here: the object loop also runs where the kernels are compiled ahead of time,
        # without numba, and the team loop is numba code (uh_core.compiled_kernels)
        from .team_kernel import team_arrays
        arrays = team_arrays(ids, controllers, plants, scenario.impairments, dt)

    out = new_run_arrays(K + 1, n, with_z1=True)
    ref = out.pop('reference')
    stuck = {ids[c] for c, plant in enumerate(plants) if plant.stuck(K * dt)}  # rho = 0 from an onset on
    stuck |= {e.uh for e in scenario.events if e.kind == 'stuck' and e.step <= K}   # and stuck events
    every = max(1, K // 100)

    if scenario.events and engine != 'kernel':
        raise SimulationError('a scenario with events runs on the kernel engine only (docs/resilience.md)')
    if arrays is not None:
        # load (or compile) the kernel before the clock starts: that is start-up, like imports
        _run_kernel(K, dt, ids, arrays, np.empty((1, REFERENCE_SIZE)), out, every, None, load_only=True)
    start = _time.perf_counter()
    samples = [reference.at(k * dt) for k in range(K + 1)]   # the virtual leader at every step
    for k, r in enumerate(samples):
        ref[k] = (r.position[0], r.position[1], r.position[2], r.yaw, r.yaw_rate)
    if engine == 'kernel':
        # [p_0, v_0, psi_0] per step, the layout of the controllers' kernel
        references = np.empty((K + 1, REFERENCE_SIZE))
        references[:, R_P_SLICE] = [r.position for r in samples]
        references[:, R_V_SLICE] = [r.velocity for r in samples]
        references[:, R_YAW] = [r.yaw for r in samples]
        if scenario.events:
            from .event_run import run_with_events
            happened = run_with_events(scenario, case, K, dt, ids, arrays, references, out, every, progress,
                                       lambda k: _non_finite(K, dt, ids, out['states'], k))
        else:
            _run_kernel(K, dt, ids, arrays, references, out, every, progress)
    else:
        _run_objects(K, dt, ids, controllers, plants, samples, out, every, progress, scenario.impairments,
                     reference)
    wall = _time.perf_counter() - start

    return TeamRun(
        scenario_name=str(scenario.name), case=case, ids=ids, dt=dt, time=np.arange(K + 1) * dt,
        reference=ref, errors=_errors(out['states'], ref, scenario, happened), wall_time=wall,
        stuck_uhs=tuple(sorted(stuck)), events=happened, **out)


def _non_finite(K, dt, ids, states, k):
    bad = [ids[c] for c in range(states.shape[1]) if not np.isfinite(states[k, c]).all()]
    raise SimulationError(f'state of UH(s) {bad} became non-finite at step {k} (t = {k * dt:g} s)')


def _run_kernel(K, dt, ids, a, references, out, every, progress, load_only=False):
    """Run the step loop in :func:`~uh_team.team_kernel.run_team_steps` on the stacked arrays ``a``.

    It runs in chunks of about 1 % of the steps so ``progress`` is called as often as by the object
    loop (``load_only``: one call that runs no step, which loads or compiles the kernel).
    """
    from .team_kernel import TEAM_DONE, TeamRecord, run_team_steps

    record = TeamRecord(**{name: out[name] for name in TeamRecord._fields})
    for k0 in ([0] if load_only else range(0, K + 1, every)):
        k1 = k0 if load_only else min(K + 1, k0 + every)
        failed = run_team_steps(k0, k1, K, dt, references, a.config, a.impairments, a.state, record)
        if failed != TEAM_DONE:
            _non_finite(K, dt, ids, out['states'], failed)
        if progress is not None and k1 > k0:
            progress(k1 - 1, K)


def _run_objects(K, dt, ids, controllers, plants, samples, out, every, progress, impairments=None, reference=None):
    """Run the step loop in Python over the per-UH objects (what the distributed nodes run).

    ``samples`` are the virtual leader's references of every step; with ``impairments`` every
    controller receives through a :class:`~uh_controller_node.impairments.ReceivedStates`, as a node does
    (``reference``, the virtual leader's trajectory, for ``delay_compensation: reference_motion``).
    """
    col = {i: c for c, i in enumerate(ids)}
    received = ([ReceivedStates(i, ctl.neighbours, impairments, dt, reference)
                 for i, ctl in zip(ids, controllers, strict=False)]
                if impairments is not None else None)
    hears = [tuple(col[j] for j in ctl.neighbours) for ctl in controllers]
    linked = [ctl.leader_link > 0.0 for ctl in controllers]
    sensing = [ProximityInput(i, ctl.safety_parameters, dt) for i, ctl in zip(ids, controllers, strict=True)]
    states, commands = out['states'], out['commands']
    for k in range(K + 1):
        t = k * dt
        r = samples[k]
        xs = [plant.x for plant in plants]
        states[k] = xs
        if not np.isfinite(states[k]).all():
            _non_finite(K, dt, ids, states, k)
        positions, velocities = states[k, :, X_P_SLICE], states[k, :, 3:6]
        for c, ctl in enumerate(controllers):
            if ctl.safety_enabled:    # the plant side's sensing: the true states at t_k (docs/safety.md)
                rows, senders = proximity_input(positions, velocities, c, ctl.sensing_radius)
                sensing[c].use(ctl, (k, tuple(ids[j] for j in senders), rows), k)
            own, nb = xs[c], {ids[j]: xs[j] for j in hears[c]}
            if received is not None:
                own, nb = received[c].receive(k, own, nb)
            u, st = ctl.step(k, own, nb, r if linked[c] else None, dt)
            commands[k, c] = u
            out['fault_est_p'][k, c] = st.fault_estimate_position
            out['fault_est_w'][k, c] = st.fault_estimate_attitude
            out['u_p'][k, c] = st.u_p
            out['z1'][k, c] = st.z1
            out['saturated'][k, c] = st.saturated_tilt or st.saturated_collective or st.saturated_cyclic
            out['safety_active'][k, c] = st.safety_active
        for c, plant in enumerate(plants):
            out['fault_true_p'][k, c], out['fault_true_w'][k, c] = plant.lumped_faults(commands[k, c], t)
            if k < K:
                plant.step(commands[k, c], t, dt)
        if progress is not None and (k % every == 0 or k == K):
            progress(k, K)

