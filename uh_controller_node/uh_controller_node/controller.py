"""The controller of one UH: consensus errors from neighbours' data, outer and inner loops (DESIGN.md 2.3-2.5).

One :class:`UHController` per helicopter, built from the scenario only (its neighbours, weights,
virtual-leader link and formation offsets come from the communication graph). Each control step
it takes its own state, the states of its graph neighbours, and the virtual leader's reference if
it hears the virtual leader, and returns the four physical inputs and a status record.

Consensus errors (DESIGN.md 2.3), with ``h_j`` the formation offsets (leaders) or zero (followers)::

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
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from .command_filter import wrap_angle
from .gains import ControllerGains, GainsError
from .inner_loop import InnerLoop
from .nominal_model import NominalModel
from .outer_loop import OuterLoop, thrust_and_attitude

__all__ = ['ControllerError', 'ControllerStatusData', 'UHController']


class ControllerError(ValueError):
    """Bad controller construction or step input (unknown UH, missing neighbour data, bad shapes)."""


@dataclass
class ControllerStatusData:
    """Internal signals of one UH controller for one step (fields of ``uh_msgs/ControllerStatus``).

    Outer-loop vectors are in the inertial frame; inner-loop vectors in the body frame (Euler-rate
    frame for ``z3``). All arrays are (3,) float64 and owned by this record.

    Attributes
    ----------
    uh_id, step : int
        Helicopter id and step index k.
    stamp : float
        t_k = k dt, s.
    z1 : ndarray
        Consensus position error e, m.
    z2 : ndarray
        Velocity error v - alpha_f, m/s.
    z3 : ndarray
        Attitude error Theta - Theta_df (yaw wrapped), rad.
    z4 : ndarray
        Body-rate error omega - alpha_wf, rad/s.
    fault_estimate_position : ndarray
        Fhat_p used this step, m/s^2.
    fault_estimate_attitude : ndarray
        Fhat_w used this step, rad/s^2.
    prediction_error_position : ndarray
        z_n = v - vhat, m/s.
    prediction_error_attitude : ndarray
        z_n = omega - omegahat, rad/s.
    u_p : ndarray
        Designed acceleration (before the tilt and collective limits), m/s^2.
    euler_desired : ndarray
        Attitude command (phi_d, theta_d, psi_d) before the command filter, rad.
    thrust_command : float
        T_c before the collective limit, N.
    weight_norm_position, weight_norm_attitude : float
        Frobenius norms of W_p and W_w.
    saturated_tilt, saturated_collective, saturated_cyclic : bool
        Tilt (or minimum vertical thrust), collective, and cyclic/tail-rotor limits active.
    cost_rate : float
        ``|z1|^2 + |u_p|^2``, the integrand of the CPI (DESIGN.md 2.8).
    stale_neighbours : tuple of str
        Filled by the node when a neighbour's data is older than its timeout; empty here.
    """

    uh_id: int
    step: int
    stamp: float
    z1: np.ndarray
    z2: np.ndarray
    z3: np.ndarray
    z4: np.ndarray
    fault_estimate_position: np.ndarray
    fault_estimate_attitude: np.ndarray
    prediction_error_position: np.ndarray
    prediction_error_attitude: np.ndarray
    u_p: np.ndarray
    euler_desired: np.ndarray
    thrust_command: float
    weight_norm_position: float
    weight_norm_attitude: float
    saturated_tilt: bool
    saturated_collective: bool
    saturated_cyclic: bool
    cost_rate: float
    stale_neighbours: tuple = field(default_factory=tuple)

    @property
    def saturated(self) -> bool:
        """True when any input limit was active."""
        return self.saturated_tilt or self.saturated_collective or self.saturated_cyclic


@dataclass(frozen=True)
class _HoldTarget:
    """The reference-shaped target of a held position (see :meth:`UHController.step_degraded`)."""

    position: tuple
    velocity: tuple
    yaw: float


def _state(x, what: str) -> list:
    """``x`` as a list of 12 finite floats, or a ControllerError naming ``what``."""
    if isinstance(x, np.ndarray):
        if x.shape != (12,):
            raise ControllerError(f'{what} must be a state vector of shape (12,), got shape {x.shape}')
        values = x.tolist()
    else:
        try:
            values = [float(v) for v in x]
        except (TypeError, ValueError):
            raise ControllerError(f'{what} must be a state vector of 12 numbers, got {x!r}') from None
        if len(values) != 12:
            raise ControllerError(f'{what} must be a state vector of shape (12,), got shape ({len(values)},)')
    if not all(map(math.isfinite, values)):
        raise ControllerError(f'{what} contains NaN or infinity: {values}')
    return values


def _vector3(value, what: str) -> tuple:
    arr = np.asarray(value, dtype=float).reshape(-1)
    if arr.shape != (3,) or not np.isfinite(arr).all():
        raise ControllerError(f'{what} must be 3 finite numbers, got {value!r}')
    return tuple(arr.tolist())


class UHController:
    """Composite-learning inverse-optimal fault-tolerant controller of one UH (DESIGN.md 2.3-2.6).

    Parameters
    ----------
    uh_id : int
        Id of the controlled UH (1..N+M).
    scenario : uh_topology.scenario.Scenario
        Supplies ``ids``, ``leaders``, ``neighbours(i)``, ``weight(i, j)``, ``leader_link(i)``,
        ``offsets``, ``gains`` (raw mapping), ``model_mismatch`` and ``helicopter``.
    case : str
        ``'proposed'``, ``'case1'`` or ``'case2'`` (DESIGN.md 2.6).
    helicopter_params : HelicopterParams, optional
        Airframe parameters; default: loaded from ``scenario.helicopter``. The controller's nominal
        model scales their ``D_v`` and ``c_Q`` by ``scenario.model_mismatch``.

    Raises
    ------
    ControllerError
        Unknown UH id, a UH without neighbours nor virtual-leader link, a leader that hears a
        follower, or a missing formation offset.
    GainsError
        Invalid gains mapping or unknown case.
    """

    def __init__(self, uh_id: int, scenario, case: str = 'proposed', *, helicopter_params=None):
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
                                          'leaders and the virtual leader (DESIGN.md 2.3)')
                if j not in offsets:
                    raise ControllerError(f'no formation offset for leader UH {j} (needed by UH {i})')
            self.offset = _vector3(offsets[i], f'formation offset of leader UH {i}')
            self._neighbour_offsets = tuple(_vector3(offsets[j], f'formation offset of leader UH {j}')
                                            for j in self.neighbours)
        else:
            self.offset = zero
            self._neighbour_offsets = tuple(zero for _ in self.neighbours)
        self._neighbour_set = frozenset(self.neighbours)
        # the whole graph, for the reachability check of a degraded step (Assumption 1)
        self._hears = {int(j): tuple(int(n) for n in scenario.neighbours(j)) for j in ids}
        self._linked = frozenset(int(j) for j in ids if float(scenario.leader_link(j)) > 0.0)
        self.case = case
        self.gains = ControllerGains.from_mapping(scenario.gains, case, source=f'gains of scenario '
                                                  f'{getattr(scenario, "name", "?")!r}')
        if helicopter_params is None:
            from uh_sim_node.helicopter import load_helicopter_params
            helicopter_params = load_helicopter_params(scenario.helicopter)
        self.model = NominalModel.from_params(helicopter_params, float(scenario.model_mismatch))
        self.outer = OuterLoop(self.gains, self.model)
        self.inner = InnerLoop(self.gains, self.model)

    # ------------------------------------------------------------------------------------------
    def _check_inputs(self, neighbour_states, reference, dt):
        keys = set(neighbour_states)
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
        if not (isinstance(dt, (int, float)) and math.isfinite(dt) and dt > 0.0):
            raise ControllerError(f'control period dt must be a finite number > 0 s, got {dt!r}')

    def step(self, k: int, own_state, neighbour_states: dict, reference, dt: float):
        """One control step at ``t_k = k dt`` (DESIGN.md 2.3-2.5).

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
            that is not 12 finite numbers, or a bad ``dt``.
        """
        self._check_inputs(neighbour_states, reference, dt)
        return self._step(k, own_state, neighbour_states, self.neighbours, self.neighbour_weights,
                          self._neighbour_offsets, self.leader_link, reference, self.degree, dt)

    def reachable_without(self, lost) -> bool:
        """Whether this UH still has a directed path from the virtual leader when the UHs in ``lost``
        (ids; ``0`` = the virtual leader's reference) are gone: Assumption 1 for this UH on the
        remaining graph. Leaders never hear followers, so a follower reached from the virtual leader
        is reached through a leader."""
        lost = {int(j) for j in lost}
        reached = set() if 0 in lost else {0}
        grown = True
        while grown:
            grown = False
            for j, hears in self._hears.items():
                if j in reached or j in lost:
                    continue
                if (j in self._linked and 0 in reached) or any(n in reached for n in hears):
                    reached.add(j)
                    grown = True
        return self.uh_id in reached

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
        if not (isinstance(dt, (int, float)) and math.isfinite(dt) and dt > 0.0):
            raise ControllerError(f'control period dt must be a finite number > 0 s, got {dt!r}')
        if hold is not None:
            position, yaw = hold
            p_hold = _vector3(position, f'UH {self.uh_id} hold position')
            if not math.isfinite(float(yaw)):
                raise ControllerError(f'UH {self.uh_id} hold yaw must be finite, got {yaw!r}')
            h = self.offset
            # a pseudo virtual leader of weight 1 at p_hold - h: z1 = (p - h) - (p_hold - h)
            target = _HoldTarget((p_hold[0] - h[0], p_hold[1] - h[1], p_hold[2] - h[2]), (0.0, 0.0, 0.0),
                                 float(yaw))
            return self._step(k, own_state, {}, (), (), (), 1.0, target, 1.0, dt)
        present = [n for n, j in enumerate(self.neighbours) if j in neighbour_states]
        a0 = self.leader_link if reference is not None else 0.0
        weights = tuple(self.neighbour_weights[n] for n in present)
        degree = sum(weights) + a0
        if not degree > 0.0:
            raise ControllerError(f'UH {self.uh_id} has no neighbour data and no reference to follow; '
                                  'give hold=(position, yaw)')
        return self._step(k, own_state, neighbour_states, tuple(self.neighbours[n] for n in present), weights,
                          tuple(self._neighbour_offsets[n] for n in present), a0, reference, degree, dt)

    def _step(self, k, own_state, neighbour_states, neighbours, neighbour_weights, neighbour_offsets,
              leader_link, reference, degree, dt):
        """The control law of one step on the given (sub)graph; see :meth:`step`."""
        x = _state(own_state, f'UH {self.uh_id} own state')
        v, euler, omega = x[3:6], x[6:9], x[9:12]
        h = self.offset
        rel = [x[0] - h[0], x[1] - h[1], x[2] - h[2]]
        z1 = [0.0, 0.0, 0.0]
        ff = [0.0, 0.0, 0.0]
        psi = euler[2]
        yaw_sum = 0.0
        for j, a, hj in zip(neighbours, neighbour_weights, neighbour_offsets):
            xj = _state(neighbour_states[j], f'state of neighbour UH {j}')
            for c in range(3):
                z1[c] += a * (rel[c] - (xj[c] - hj[c]))
                ff[c] += a * xj[3 + c]
            yaw_sum += a * wrap_angle(xj[8] - psi)
        if leader_link > 0.0:
            a0 = leader_link
            p0, v0 = reference.position, reference.velocity
            for c in range(3):
                z1[c] += a0 * (rel[c] - float(p0[c]))
                ff[c] += a0 * float(v0[c])
            psi_d = float(reference.yaw)
        else:
            psi_d = psi + yaw_sum / degree

        outer, inner, model = self.outer, self.inner, self.model
        fhat_p = outer.fault_estimate
        fhat_w = inner.fault_estimate
        u_p, z2, zn_p = outer.command(z1, degree, ff, v)
        att = thrust_and_attitude(u_p, psi_d, model, self.gains.tilt_limit, self.gains.min_vertical_accel)
        euler_d = (att.phi, att.theta, psi_d)
        u_m, z3, z4, zn_w, sat_cyclic = inner.command(euler, omega, euler_d, att.thrust_achieved)

        # acceleration the limited thrust gives at the measured attitude: (T/m) R(Theta) e3 - g e3
        cf, sf = math.cos(euler[0]), math.sin(euler[0])
        ct, st = math.cos(euler[1]), math.sin(euler[1])
        cp, sp = math.cos(psi), math.sin(psi)
        tm = att.thrust_achieved / model.mass
        accel = (tm * (cp * st * cf + sp * sf), tm * (sp * st * cf - cp * sf), tm * ct * cf - model.gravity)
        outer.advance(accel, dt)
        inner.advance(dt)

        u = np.array([att.theta_col, u_m[2], u_m[0], u_m[1]])
        wp, ww = outer.weights, inner.weights
        # one allocation for the ten status vectors; each field is a row of it
        vecs = np.array([z1, z2, z3, z4, fhat_p, fhat_w, zn_p, zn_w, u_p, euler_d])
        status = ControllerStatusData(
            uh_id=self.uh_id, step=int(k), stamp=int(k) * dt, z1=vecs[0], z2=vecs[1], z3=vecs[2],
            z4=vecs[3], fault_estimate_position=vecs[4], fault_estimate_attitude=vecs[5],
            prediction_error_position=vecs[6], prediction_error_attitude=vecs[7], u_p=vecs[8],
            euler_desired=vecs[9], thrust_command=att.thrust,
            weight_norm_position=math.sqrt(float(np.vdot(wp, wp))),
            weight_norm_attitude=math.sqrt(float(np.vdot(ww, ww))),
            saturated_tilt=att.saturated_tilt, saturated_collective=att.saturated_collective,
            saturated_cyclic=sat_cyclic,
            cost_rate=math.fsum(c * c for c in z1) + math.fsum(c * c for c in u_p))
        return u, status
