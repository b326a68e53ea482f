"""The controller of one UH: consensus errors from neighbours' data, outer and inner loops.

See docs/graph.md and docs/control_law.md.

One :class:`UHController` per helicopter, built from the scenario only (its neighbours, weights,
virtual-leader link and formation offsets come from the communication graph). Each control step
it takes its own state, the states of its graph neighbours, and the virtual leader's reference if
it hears the virtual leader, and returns the four physical inputs and a status record.

Consensus errors (docs/graph.md), with ``h_j`` the formation offsets (leaders) or zero (followers)::

    leader i:    z1 = sum_{j in N_i} a_ij [(p_i - h_i) - (p_j - h_j)] + a_i0 [(p_i - h_i) - p_0]
    follower k:  z1 = sum_{j in N_k} a_kj (p_k - p_j)
    d = sum_j a_ij + a_i0 ,   feed-forward velocity f = sum_j a_ij v_j + a_i0 v_0

Yaw: a UH that hears the virtual leader tracks ``psi_0``; every other UH tracks the a-weighted
mean of its neighbours' yaw, computed as ``psi_i + sum_j a_ij wrap(psi_j - psi_i) / sum_j a_ij`` so
the mean is taken the short way around the circle.

Per step the order is fixed: consensus error -> outer law (u_p) -> thrust and attitude extraction
(tilt and collective limits) -> inner law (u_m, cyclic and pedal limits) -> explicit-Euler update
of every internal state from t_k to t_{k+1}. Neighbours are visited in ascending id order and the
controller uses no randomness, so two runs with the same inputs give bit-identical outputs.

After the law, the step's own state, limited command and fault estimates go to this UH's
:class:`~uh_controller_node.fault_isolation.FaultIsolator` (docs/faults.md#isolation-and-identification),
whose verdicts ride on the status record; they never feed back into the law.

The law itself is :func:`uh_controller_node.control_kernels.uh_control_step` (numba); this class
checks the inputs, copies them into float64 arrays, makes one kernel call per step and turns the
kernel's status vector into a :class:`ControllerStatusData`. :meth:`UHController.kernel_arrays`
gives the arrays for calling the kernel from other njit code.
"""
from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from uh_core.airframe import load_helicopter_params
from uh_topology.graph import reachable_from

from .control_kernels import (
    FLAG_STARTED,
    FLAG_TIME,
    INPUT_SIZE,
    M_ALPHA_F,
    M_ALPHA_WF,
    M_F_HAT_P,
    M_F_HAT_W,
    M_FLAGS,
    M_OMEGA_HAT,
    M_V_HAT,
    MEMORY_ROWS,
    R_P,
    R_V,
    R_YAW,
    REFERENCE_SIZE,
    STATE_SIZE,
    STATUS_SIZE,
    STEP_DONE,
    ControlArrays,
    compile_control_kernels,
    control_parameters,
    uh_control_step,
)
from .controller_status import ControllerStatusData, status_record
from .fault_isolation import FaultIsolator, IsolationSettings
from .gains import ControllerGains, scenario_gains
from .isolation_kernels import compile_isolation_kernels
from .nominal_model import nominal_model
from .safety import safety_parameters
from .safety_kernels import PROXIMITY_COLUMNS

__all__ = ['ControllerError', 'ControllerStatusData', 'LoopState', 'UHController', 'load_controller_kernels']

_STATE_SHAPE = (STATE_SIZE,)



def load_controller_kernels() -> float:
    """Load (or compile) every numba kernel a controller calls, the law's and the fault isolator's; seconds spent.

    A kernel is otherwise loaded at its first call (0.05-0.4 s): a node calls this before it can be
    stepped, so no step of a run is late for it.
    """
    return compile_control_kernels() + compile_isolation_kernels()


class ControllerError(ValueError):
    """Bad controller construction or step input (unknown UH, missing neighbour data, bad shapes)."""


class LoopState(NamedTuple):
    """Live views of one loop's internal states (read them; the kernel updates them in place).

    Attributes
    ----------
    weights : ndarray (mu, 3)
        Network weights W (column a = axis a).
    fault_estimate : ndarray (3,)
        Fhat: m/s^2 inertial (outer), rad/s^2 body (inner).
    model_estimate : ndarray (3,)
        State of the serial-parallel estimation model: vhat m/s (outer), omegahat rad/s (inner).
    command_filter : ndarray (3,)
        Filtered virtual control: alpha_f m/s (outer), alpha_wf rad/s (inner).
    """

    weights: np.ndarray
    fault_estimate: np.ndarray
    model_estimate: np.ndarray
    command_filter: np.ndarray


def _state(x, what: str) -> list:
    """``x`` as a list of 12 finite floats, or a ControllerError naming ``what``."""
    if isinstance(x, np.ndarray):
        if x.shape != _STATE_SHAPE:
            raise ControllerError(f'{what} must be a state vector of shape (12,), got shape {x.shape}')
        values = x.tolist()
    else:
        try:
            values = [float(v) for v in x]
        except (TypeError, ValueError):
            raise ControllerError(f'{what} must be a state vector of 12 numbers, got {x!r}') from None
        if len(values) != STATE_SIZE:
            raise ControllerError(f'{what} must be a state vector of shape (12,), got shape ({len(values)},)')
    try:
        finite = all(map(math.isfinite, values))
    except TypeError:
        raise ControllerError(f'{what} must be a state vector of 12 numbers, got {x!r}') from None
    if not finite:
        raise ControllerError(f'{what} contains NaN or infinity: {values}')
    return values


def _vector3(value, what: str) -> tuple:
    arr = np.asarray(value, dtype=float).reshape(-1)
    if arr.shape != (3,) or not np.isfinite(arr).all():
        raise ControllerError(f'{what} must be 3 finite numbers, got {value!r}')
    return tuple(arr.tolist())


def _check_dt(dt) -> float:
    if isinstance(dt, bool) or not (isinstance(dt, (int, float)) and math.isfinite(dt) and dt > 0.0):
        raise ControllerError(f'control period dt must be a finite number > 0 s, got {dt!r}')
    return float(dt)


class UHController:
    """Composite-learning inverse-optimal fault-tolerant controller of one UH (docs/graph.md, docs/control_law.md).

    Parameters
    ----------
    uh_id : int
        Id of the controlled UH (1..N+M).
    scenario : uh_topology.scenario.Scenario
        Supplies ``ids``, ``leaders``, ``neighbours(i)``, ``weight(i, j)``, ``leader_link(i)``,
        ``offsets``, ``gains`` (raw mapping), ``model_mismatch`` and ``helicopter``.
    case : str
        ``'proposed'``, ``'case1'`` or ``'case2'`` (docs/control_law.md#comparison-cases).
    helicopter_params : HelicopterParams, optional
        Airframe parameters; default: loaded from ``scenario.helicopter``. The controller's nominal
        model scales their ``D_v`` and ``c_Q`` by ``scenario.model_mismatch``.
    gains : ControllerGains, optional
        Gains of ``case`` (e.g. changed at run time); default: the scenario's gains of ``case``.

    Attributes
    ----------
    uh_id : int
    is_leader : bool
    neighbours : tuple of int
        The UHs heard, ascending id.
    neighbour_weights : tuple of float
        a_ij in the order of ``neighbours``.
    leader_link : float
        a_i0.
    degree : float
        ``sum_j a_ij + a_i0``.
    offset : tuple of 3 float
        Own formation offset h_i, m (zero for followers).
    case : str
    gains : ControllerGains
    model : HelicopterParams
    outer, inner : LoopState
        Live views of the loops' learning states.

    Raises
    ------
    ControllerError
        Unknown UH id, a UH without neighbours nor virtual-leader link, a leader that hears a
        follower, or a missing formation offset.
    GainsError
        Invalid gains mapping or unknown case.
    """

    def __init__(self, uh_id: int, scenario, case: str = 'proposed', *, helicopter_params=None, gains=None):
        ids = tuple(int(i) for i in scenario.ids)
        if isinstance(uh_id, bool) or not isinstance(uh_id, (int, np.integer)) or int(uh_id) not in ids:
            raise ControllerError(f'unknown UH id {uh_id!r}; the scenario has UHs {list(ids)}')
        self.uh_id = i = int(uh_id)
        leaders = tuple(int(j) for j in scenario.leaders)
        self.is_leader = i in leaders
        self.neighbours = tuple(sorted(int(j) for j in scenario.neighbours(i)))
        self.neighbour_weights = tuple(float(scenario.weight(i, j)) for j in self.neighbours)
        self.leader_link = float(scenario.leader_link(i))
        self.degree = sum(self.neighbour_weights) + self.leader_link
        if not self.degree > 0.0:
            raise ControllerError(f'UH {i} hears neither a neighbour nor the virtual leader; '
                                  'every UH needs at least one incoming edge')
        zero = (0.0, 0.0, 0.0)
        if self.is_leader:
            offsets = scenario.offsets
            needed = (i,) + self.neighbours
            for j in needed:
                if j not in leaders:
                    raise ControllerError(f'leader UH {i} hears follower UH {j}; leaders may hear only '
                                          'leaders and the virtual leader (docs/graph.md)')
                if j not in offsets:
                    raise ControllerError(f'no formation offset for leader UH {j} (needed by UH {i})')
            self.offset = _vector3(offsets[i], f'formation offset of leader UH {i}')
            neighbour_offsets = tuple(_vector3(offsets[j], f'formation offset of leader UH {j}')
                                      for j in self.neighbours)
        else:
            self.offset = zero
            neighbour_offsets = tuple(zero for _ in self.neighbours)
        self._neighbour_set = frozenset(self.neighbours)
        # the whole graph (who hears whom, column 0 = the virtual leader), for the reachability
        # check of a degraded step (Assumption 1, docs/graph.md)
        self._ids = frozenset(ids)
        self._graph = np.zeros((max(ids) + 1, max(ids) + 1))
        for j in ids:
            self._graph[j, list(scenario.neighbours(j))] = 1.0
            self._graph[j, 0] = float(scenario.leader_link(j))
        self.case = case
        if gains is None:
            gains = scenario_gains(scenario, case)
        elif gains.case != case:
            raise ControllerError(f'gains are those of case {gains.case!r}, the controller is {case!r}')
        self.gains = gains
        if helicopter_params is None:
            helicopter_params = load_helicopter_params(scenario.helicopter)
        self.model = nominal_model(helicopter_params, float(scenario.model_mismatch))

        # the kernel's arrays (control_kernels module doc): constants of this UH ...
        n_nb = len(self.neighbours)
        self._params = control_parameters(self.gains, self.model)
        self._offset = np.array(self.offset)
        self._nb_weights = np.array(self.neighbour_weights, dtype=float).reshape(n_nb)
        self._nb_offsets = np.array(neighbour_offsets, dtype=float).reshape(n_nb, 3)
        # ... its internal states (all zero: the first step initialises filters and SPEMs) ...
        self._weights_p = np.zeros((self.gains.outer.rbf.nodes, 3))
        self._weights_w = np.zeros((self.gains.inner.rbf.nodes, 3))
        self._memory = np.zeros((MEMORY_ROWS, 3))
        # ... the safety filter's parameters (a layer outside the law, docs/safety.md; empty: off) ...
        self._safety_spec = getattr(scenario, 'safety', None)     # None: a scenario-like object without one
        self._safety = self._safety_parameters()
        # ... and input buffers, refilled every step
        self._proximity = np.empty((0, PROXIMITY_COLUMNS))
        self._own = np.empty(STATE_SIZE)
        self._nb_states = np.empty((n_nb, STATE_SIZE))
        self._reference = np.zeros(REFERENCE_SIZE)
        # fault isolation (made at the first step, when the control period is known)
        self._isolation_settings = IsolationSettings(learning_phase=float(self.gains.learning_phase))
        self._mismatch = float(scenario.model_mismatch)
        self.isolator: FaultIsolator | None = None

    # ------------------------------------------------------------------------------------------
    @property
    def outer(self) -> LoopState:
        """Live views of the outer loop's W_p, Fhat_p, vhat and alpha_f."""
        m = self._memory
        return LoopState(self._weights_p, m[M_F_HAT_P], m[M_V_HAT], m[M_ALPHA_F])

    @property
    def inner(self) -> LoopState:
        """Live views of the inner loop's W_w, Fhat_w, omegahat and alpha_wf.

        Theta_df is ``kernel_arrays().memory[M_THETA_DF]``.
        """
        m = self._memory
        return LoopState(self._weights_w, m[M_F_HAT_W], m[M_OMEGA_HAT], m[M_ALPHA_WF])

    def kernel_arrays(self) -> ControlArrays:
        """Return the arrays :func:`~uh_controller_node.control_kernels.uh_control_step` needs for this UH.

        These are the controller's own arrays, not copies: a kernel that updates ``weights_p``,
        ``weights_w`` and ``memory`` in place carries this controller on; stack copies of them
        (``np.stack``) for a team kernel. ``memory[M_THETA_DF]`` is the filtered attitude command.
        """
        return ControlArrays(self._params, self._offset, self._nb_weights, self._nb_offsets, self.leader_link,
                             self._weights_p, self._weights_w, self._memory, self._safety)

    # ------------------------------------------------------------------------------------------
    def _check_inputs(self, neighbour_states, reference, dt):
        keys = neighbour_states.keys()
        if keys != self._neighbour_set:
            missing = sorted(self._neighbour_set - keys)
            extra = sorted(keys - self._neighbour_set, key=str)
            parts = []
            if missing:
                parts.append(f'missing state of neighbour(s) {missing}')
            if extra:
                parts.append(f'unexpected state of UH(s) {extra} that UH {self.uh_id} does not hear')
            raise ControllerError(f'UH {self.uh_id} controller: {"; ".join(parts)}; '
                                  f'expected exactly the neighbours {list(self.neighbours)}')
        if self.leader_link > 0.0 and reference is None:
            raise ControllerError(f'UH {self.uh_id} hears the virtual leader (a_{self.uh_id}0 = '
                                  f'{self.leader_link:g}): a reference is required')
        if self.leader_link == 0.0 and reference is not None:
            raise ControllerError(f'UH {self.uh_id} does not hear the virtual leader: reference must be None')
        return _check_dt(dt)

    def step(self, k: int, own_state, neighbour_states: dict, reference, dt: float):
        """One control step at ``t_k = k dt`` (docs/graph.md, docs/control_law.md).

        Parameters
        ----------
        k : int
            Step index (>= 0).
        own_state : array_like (12,)
            ``[p m, v m/s, Theta rad, omega rad/s]`` of this UH at t_k.
        neighbour_states : dict[int, array_like (12,)]
            States at t_k of exactly the UHs this one hears.
        reference : Reference or None
            Virtual leader at t_k (``position`` (3,), ``velocity`` (3,), ``yaw``), given iff this UH
            hears the virtual leader.
        dt : float
            Control period, s: the internal states are advanced to t_{k+1}.

        Returns
        -------
        u : ndarray (4,)
            ``(theta_col, theta_tr, delta_lat, delta_lon)`` rad, within the input limits.
        status : ControllerStatusData

        Raises
        ------
        ControllerError
            Missing or extra neighbour state, reference given/missing against the graph, a state
            that is not 12 finite numbers, or a bad ``dt``. Nothing is changed then.
        """
        dt = self._check_inputs(neighbour_states, reference, dt)
        self._load_states(own_state, neighbour_states, self.neighbours, self._nb_states)
        if self.leader_link > 0.0:
            self._load_reference(reference.position, reference.velocity, reference.yaw)
        return self._run(k, self._nb_states, self._nb_weights, self._nb_offsets, self.leader_link, dt,
                         self.neighbours)

    def set_proximity(self, proximity) -> None:
        """Give the safety filter the UHs its proximity input reports, for the next steps (docs/safety.md).

        ``proximity``: array (n, 6) of ``[p m, v m/s]`` rows, inertial frame (any order). Ignored
        while the filter is off.
        """
        rows = np.asarray(proximity, dtype=float).reshape(-1, PROXIMITY_COLUMNS)
        self._proximity = np.ascontiguousarray(rows)

    @property
    def safety_parameters(self) -> np.ndarray:
        """The safety filter's parameter vector (``SF_*`` of :mod:`~uh_controller_node.safety_kernels`; empty: off)."""
        return self._safety

    @property
    def safety_enabled(self) -> bool:
        """Whether this controller runs the safety filter."""
        return self._safety.shape[0] > 0

    @property
    def sensing_radius(self) -> float:
        """Radius of the UH's proximity input, m (``safety.sensing_radius`` of the scenario)."""
        return float(self._safety_spec.sensing_radius) if self._safety_spec is not None else 0.0

    def _safety_parameters(self) -> np.ndarray:
        """Return the filter's parameter vector for the current gains, or an empty one when it is off."""
        if self._safety_spec is None or not self._safety_spec.enabled:
            return np.empty(0)
        return safety_parameters(self._safety_spec, self.model, self.gains.tilt_limit, self.gains.min_vertical_accel)

    def set_gains(self, gains: ControllerGains) -> None:
        """Use ``gains`` from the next step on (a live change, docs/control_law.md#gains-as-parameters).

        The internal states carry on; the RBF networks' size and centres cannot change.

        Raises
        ------
        ControllerError
            ``gains`` of another case, or with other RBF networks.
        """
        if gains.case != self.case:
            raise ControllerError(f'gains are those of case {gains.case!r}, the controller is {self.case!r}')
        if (gains.outer.rbf, gains.inner.rbf) != (self.gains.outer.rbf, self.gains.inner.rbf):
            raise ControllerError('the RBF networks (rbf_*) cannot change while the controller runs')
        self._params = control_parameters(gains, self.model)
        self.gains = gains
        self._safety = self._safety_parameters()

    def reachable_without(self, lost) -> bool:
        """Tell whether this UH still has a directed path from the virtual leader without the UHs ``lost``.

        ``lost`` holds ids; ``0`` is the virtual leader's reference. This is Assumption 1 for this UH on the
        remaining graph (docs/graph.md). Leaders never hear followers, so a follower reached from the
        virtual leader is reached through a leader.
        """
        lost = {int(j) for j in lost}
        sources = () if 0 in lost else (0,)
        return self.uh_id in reachable_from(self._graph, sources, allowed=self._ids - lost)

    def step_degraded(self, k: int, own_state, neighbour_states: dict, reference, dt: float, *,
                      hold=None):
        """One control step with only part of the inputs (a neighbour or the reference is stale).

        The consensus error, the degree and the yaw target are those of :meth:`step` on the
        subgraph of the neighbours present in ``neighbour_states`` (and the reference if given);
        the internal states carry on, so the UH rejoins smoothly when the data comes back. With
        ``hold = (position (3,) m, yaw rad)`` every neighbour and the reference are ignored and the
        UH is regulated to that point instead: the consensus error is ``p - position`` with degree 1,
        zero velocity feed-forward and yaw target ``yaw`` (hold position when the remaining graph
        breaks Assumption 1, see :meth:`reachable_without`).

        Parameters
        ----------
        k, own_state, dt
            As in :meth:`step`.
        neighbour_states : dict[int, array_like (12,)]
            States at (about) t_k of any subset of the neighbours; other keys are an error.
        reference : Reference or None
            The virtual leader, or None when it is stale (ignored unless this UH hears it).
        hold : tuple (array_like (3,), float), optional
            Position (m, inertial) and yaw (rad) to hold.

        Returns
        -------
        u, status
            As in :meth:`step`.

        Raises
        ------
        ControllerError
            A state of a UH this one does not hear, nothing to follow and no ``hold``, bad inputs.
        """
        extra = sorted(set(neighbour_states) - self._neighbour_set, key=str)
        if extra:
            raise ControllerError(f'UH {self.uh_id} controller: unexpected state of UH(s) {extra} that '
                                  f'UH {self.uh_id} does not hear; its neighbours are {list(self.neighbours)}')
        dt = _check_dt(dt)
        if hold is not None:
            position, yaw = hold
            p_hold = _vector3(position, f'UH {self.uh_id} hold position')
            if not math.isfinite(float(yaw)):
                raise ControllerError(f'UH {self.uh_id} hold yaw must be finite, got {yaw!r}')
            h = self.offset
            # a pseudo virtual leader of weight 1 at p_hold - h: z1 = (p - h) - (p_hold - h)
            self._load_states(own_state, {}, (), self._nb_states[:0])
            self._load_reference((p_hold[0] - h[0], p_hold[1] - h[1], p_hold[2] - h[2]), (0.0, 0.0, 0.0),
                                 float(yaw))
            return self._run(k, self._nb_states[:0], self._nb_weights[:0], self._nb_offsets[:0], 1.0, dt, ())
        present = [n for n, j in enumerate(self.neighbours) if j in neighbour_states]
        a0 = self.leader_link if reference is not None else 0.0
        weights = tuple(self.neighbour_weights[n] for n in present)
        if not sum(weights) + a0 > 0.0:
            raise ControllerError(f'UH {self.uh_id} has no neighbour data and no reference to follow; '
                                  'give hold=(position, yaw)')
        ids = tuple(self.neighbours[n] for n in present)
        nb_states = np.empty((len(present), STATE_SIZE))
        self._load_states(own_state, neighbour_states, ids, nb_states)
        if a0 > 0.0:
            self._load_reference(reference.position, reference.velocity, reference.yaw)
        return self._run(k, nb_states, self._nb_weights[present], self._nb_offsets[present], a0, dt, ids)

    def step_row(self, k: int, own_state, neighbour_states: dict, reference, dt: float, row, hold=None):
        """One control step in a re-formed team (docs/resilience.md): the law on ``row``'s graph.

        ``row`` is a :class:`uh_topology.losses.RowTeam`: the neighbours (any UHs, ascending), their
        weights and offsets, the own offset and ``a_i0``; ``neighbour_states`` must hold a state of
        each of them, ``reference`` is read when ``a_i0 > 0``. With ``hold`` (the pseudo virtual
        leader of :func:`uh_topology.losses.hold_reference`, (7,)) the UH holds that point instead:
        no neighbour, ``a_i0 = 1``, own offset zero. The same arrays the team kernel gives the row.
        """
        dt = _check_dt(dt)
        if hold is not None:
            self._load_states(own_state, {}, (), self._nb_states[:0])
            self._reference[:] = hold
            return self._run(k, self._nb_states[:0], self._nb_weights[:0], self._nb_offsets[:0], 1.0, dt, (),
                             offset=np.zeros(3))
        ids = tuple(row.neighbours)
        nb_states = np.empty((len(ids), STATE_SIZE))
        self._load_states(own_state, neighbour_states, ids, nb_states)
        if row.leader_link > 0.0:
            self._load_reference(reference.position, reference.velocity, reference.yaw)
        weights = np.array(row.weights, dtype=float).reshape(len(ids))
        offsets = np.array(row.neighbour_offsets, dtype=float).reshape(len(ids), 3)
        return self._run(k, nb_states, weights, offsets, float(row.leader_link), dt, ids,
                         offset=np.array(row.offset, dtype=float))

    # ------------------------------------------------------------------------------------------
    def _load_states(self, own_state, neighbour_states, ids, nb_states):
        """Copy the own state and the states of ``ids`` (in that order) into the kernel's buffers.

        Only the shape is checked here; finiteness is checked by the kernel. On a bad input the
        inputs are checked one by one in the order the law reads them, so the error reported is
        the first one (also when an earlier state holds NaN).
        """
        try:
            x = own_state
            if type(x) is np.ndarray and x.shape == _STATE_SHAPE:
                self._own[:] = x
            else:
                self._own[:] = _state(x, f'UH {self.uh_id} own state')
            for n, j in enumerate(ids):
                x = neighbour_states[j]
                if type(x) is np.ndarray and x.shape == _STATE_SHAPE:
                    nb_states[n] = x
                else:
                    nb_states[n] = _state(x, f'state of neighbour UH {j}')
        except (ControllerError, TypeError, ValueError):
            _state(own_state, f'UH {self.uh_id} own state')
            for j in ids:
                _state(neighbour_states[j], f'state of neighbour UH {j}')
            raise

    def _load_reference(self, position, velocity, yaw):
        """Copy the virtual leader's position (3,) m, velocity (3,) m/s and yaw rad into the buffer."""
        ref = self._reference
        ref[R_P:R_P + 3] = position
        ref[R_V:R_V + 3] = velocity
        ref[R_YAW] = yaw

    def _run(self, k, nb_states, nb_weights, nb_offsets, leader_link, dt, ids, offset=None):
        """One kernel call on the loaded inputs (own offset ``offset``, default the UH's); command and status."""
        if self._memory[M_FLAGS, FLAG_STARTED] == 0.0:
            # the run's time at this controller's first step: a controller that joins a running team
            # (restarted) after the learning phase starts with its fault observers on
            self._memory[M_FLAGS, FLAG_TIME] = k * dt
        u = np.empty(INPUT_SIZE)
        status = np.empty(STATUS_SIZE)
        done = uh_control_step(self._params, self._own, nb_states, nb_weights, nb_offsets,
                               self._offset if offset is None else offset,
                               leader_link, self._reference, dt, self._weights_p, self._weights_w,
                               self._memory, u, status, self._safety, self._proximity)
        if done != STEP_DONE:
            if done == 0:
                what, values = f'UH {self.uh_id} own state', self._own
            else:
                what, values = f'state of neighbour UH {ids[done - 1]}', nb_states[done - 1]
            raise ControllerError(f'{what} contains NaN or infinity: {values.tolist()}')
        k = int(k)
        t = k * dt
        record = status_record(self.uh_id, k, t, status)
        if self.isolator is None:
            self.isolator = FaultIsolator(self.model, self._mismatch, dt, self._isolation_settings)
        self.isolator.update(t, self._own, u, record.fault_estimate_position, record.fault_estimate_attitude)
        record.isolation = self.isolator.status()
        return u, record
