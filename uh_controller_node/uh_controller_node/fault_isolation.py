"""Causal fault isolation and identification per actuator channel from the lumped-fault estimates.

Described in docs/faults.md#isolation-and-identification.

The controller's observers estimate lumped faults, ``Fhat_p`` (m/s^2, inertial) and ``Fhat_w``
(rad/s^2, body) (docs/control_law.md#learning-and-estimation); they do not say which actuator is
faulty, nor by how much. This module turns them back into per-channel input deviations, decides
which channels are faulty, and fits the fault model of eq. 6 (docs/faults.md#fault-model),
``u_act = rho u + b``, to each channel found faulty. It uses only what one controller has at each
step (its nominal model, its state, its command and its estimates), so it can run beside the
controller, or afterwards over a recorded run (:func:`uh_controller_node.isolation_runs.isolate_run`).
No ROS, deterministic. The per-step arithmetic is the numba kernels of
:mod:`uh_controller_node.isolation_kernels`, the same code online (:meth:`FaultIsolator.update`, one
step) and offline (:func:`~uh_controller_node.isolation_runs.isolate_run`, every step of a run in one
compiled call), so both give the same bits.

1. **Input deviations** (:func:`input_deviation`). Inverting the lumped-fault formulas of
   docs/model.md#lumped-faults with the nominal model gives, per step, an estimate ``d`` (rad) of
   ``u_act - u`` per channel, which eq. 6 says is ``(rho - 1) u + b(t)``.
2. **Isolation** (:class:`FaultIsolator`). Each channel's deviation is low-pass filtered (first
   order, time constant ``filter_tau``); the channel is isolated (reported faulty, latched) once
   ``|filtered d|`` has stayed above the channel's threshold for ``confirmation_time``. The
   threshold is a constant per channel plus a coupling allowance that grows with the estimated
   thrust deviation (the collective leaks into the tail rotor through ``c_Q`` and into the cyclics
   through ``h_M``). Nothing is processed during the controller's learning phase (run time
   ``t < learning_phase``), when the estimates are held at zero.
3. **Identification**. From its isolation on, each isolated channel fits ``d = theta_1 u + theta_2``
   by recursive least squares (exact, no prior; forgetting factor 1 by default), giving
   ``rho = 1 + theta_1`` and the constant bias ``b = theta_2``, and a verdict saying whether the
   fit can be trusted, with the reason when not.

The defaults of :class:`IsolationSettings` and their justification (the healthy deviation
statistics of the bundled scenarios) are in docs/faults.md#isolation-and-identification. Every
controller runs one isolator online (:class:`uh_controller_node.controller.UHController`) and
publishes its verdicts on ``ControllerStatus`` (:data:`IDENTIFICATION_CODES`).
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np

from . import isolation_kernels as K

__all__ = ['CHANNELS', 'IsolationSettings', 'ChannelReport', 'IsolationStatus', 'FaultIsolator', 'input_deviation',
           'IDENTIFICATION_CODES', 'NOT_ISOLATED',
           'FIT_TOO_SHORT', 'BIAS_NOT_CONSTANT', 'CONFOUNDED', 'IDENTIFIABLE', 'IDENTIFICATION_TEXT']

#: Channel names, in input order (docs/faults.md#channels).
CHANNELS = ('collective', 'tail_rotor', 'lateral', 'longitudinal')
_N = len(CHANNELS)

# Verdict codes of a channel (ChannelReport.identification; the IDENTIFICATION_* constants of
# uh_msgs/msg/ControllerStatus.msg, checked equal by a test)
NOT_ISOLATED = 0        #: the channel is not isolated
FIT_TOO_SHORT = 1       #: isolated; the fit spans less than ``min_fit_time``
BIAS_NOT_CONSTANT = 2   #: isolated; the fit's residual says the deviation is not affine in the command
CONFOUNDED = 3          #: isolated; the actual input varies too little to separate rho and b
IDENTIFIABLE = 4        #: isolated; rho and the constant bias are identified within the tolerances
#: Code -> name, in code order.
IDENTIFICATION_CODES = {NOT_ISOLATED: 'not_isolated', FIT_TOO_SHORT: 'fit_too_short',
                        BIAS_NOT_CONSTANT: 'bias_not_constant', CONFOUNDED: 'confounded',
                        IDENTIFIABLE: 'identifiable'}
#: Code -> what it means, for reports (ChannelReport.reason adds the numbers).
IDENTIFICATION_TEXT = {
    NOT_ISOLATED: 'not isolated',
    FIT_TOO_SHORT: 'fit too short',
    BIAS_NOT_CONSTANT: 'bias not constant (deviation not affine in the command)',
    CONFOUNDED: 'actual input nearly constant: (rho - 1) u and b confounded',
    IDENTIFIABLE: 'identifiable',
}


@dataclass(frozen=True)
class IsolationSettings:
    """Settings of a :class:`FaultIsolator`.

    The defaults are justified in docs/faults.md#isolation-and-identification.

    Attributes
    ----------
    learning_phase : float
        Run time, s, before which nothing is processed (the controller's observers hold zero
        then; docs/control_law.md#learning-phase). The paper gains' 8 s;
        :func:`~uh_controller_node.isolation_runs.isolate_run` takes the scenario's own value.
    filter_tau : float
        Time constant of the first-order low-pass filter on each deviation, s (0.2: smooths the
        observers' onset transients, a few of their 1/20 s and 1/40 s time constants).
    thresholds : tuple of 4 float
        Constant part of the isolation threshold per channel, rad: three times the largest
        filtered healthy deviation after the learning phase on the bundled scenarios
        (:func:`~uh_controller_node.isolation_runs.healthy_deviation_statistics`), rounded up to two digits.
    confirmation_time : float
        How long ``|filtered d|`` must stay above its threshold, without a break, before the
        channel is isolated, s (0.5: 25 times the longest excursion of a healthy channel, and
        within the 2 s detection budget).
    coupling_window : float
        Window over which the range of the thrust-deviation estimate counts as not yet settled
        between the outer and inner observers, s (0.3: the length of their transient after a
        thrust step; the coupling allowances, see :class:`FaultIsolator`).
    forgetting : float
        Forgetting factor of the least-squares fit per step, in (0, 1]; 1: none (the fault model's
        ``rho`` and constant bias are constants, and forgetting would shrink the command spread
        the fit needs).
    noise_rms : tuple of 4 float
        RMS of the healthy deviation per channel, rad: the largest per-UH RMS on the bundled
        scenarios from one second after the learning phase, rounded up to two digits. The
        a priori size of what in ``d`` is not the fault, used in the fit's error bounds.
    residual_max : tuple of 4 float
        Largest RMS residual of the fit per channel for which the fault counts as affine in the
        command (``rho`` and a constant bias), rad: five times ``noise_rms``.
    rho_tolerance, bias_tolerance : float
        A fit is called identifiable only if its worst-case error bounds are within these
        (-, rad).
    min_fit_time : float
        Shortest fit, s, before a verdict can be identifiable.
    """

    learning_phase: float = 8.0
    filter_tau: float = 0.2
    thresholds: tuple = (9.1e-4, 8.6e-4, 1.1e-4, 2.7e-4)
    confirmation_time: float = 0.5
    coupling_window: float = 0.3
    forgetting: float = 1.0
    noise_rms: tuple = (2.1e-4, 1.1e-4, 6.6e-6, 1.1e-5)
    residual_max: tuple = (1.05e-3, 5.5e-4, 3.3e-5, 5.5e-5)
    rho_tolerance: float = 0.05
    bias_tolerance: float = 0.003
    min_fit_time: float = 2.0

    def __post_init__(self):
        for name in ('learning_phase', 'filter_tau', 'confirmation_time', 'coupling_window',
                     'rho_tolerance', 'bias_tolerance', 'min_fit_time'):
            value = getattr(self, name)
            if not (isinstance(value, (int, float)) and math.isfinite(value) and value >= 0.0):
                raise ValueError(f'{name} must be a finite number >= 0, got {value!r}')
        if not self.filter_tau > 0.0:
            raise ValueError(f'filter_tau must be > 0, got {self.filter_tau!r}')
        if not (isinstance(self.forgetting, (int, float)) and 0.0 < self.forgetting <= 1.0):
            raise ValueError(f'forgetting must be in (0, 1], got {self.forgetting!r}')
        for name in ('thresholds', 'noise_rms', 'residual_max'):
            value = tuple(float(v) for v in getattr(self, name))
            if len(value) != _N or not all(math.isfinite(v) and v > 0.0 for v in value):
                raise ValueError(f'{name} must be 4 finite numbers > 0, got {getattr(self, name)!r}')
            object.__setattr__(self, name, value)


@dataclass(frozen=True)
class ChannelReport:
    """What a :class:`FaultIsolator` says about one channel.

    Attributes
    ----------
    channel : str
        Name (:data:`CHANNELS`).
    isolated : bool
        Reported faulty (latched).
    detection_time : float
        Time of the isolation, s (NaN if not isolated).
    rho, bias : float
        Effectiveness (-) and constant bias (rad) of the fit; NaN unless ``identifiable``.
    rho_fit, bias_fit : float
        The fit's values whatever the verdict (NaN while the command has not varied).
    identifiable : bool
        The fit's worst-case error bounds are within the tolerances and its residual is small.
    reason : str
        Why not identifiable (``'identifiable'`` when it is).
    identification : int
        The verdict as a code (:data:`IDENTIFICATION_CODES`).
    fit_time : float
        Time span of the fit, s.
    command_std, actual_std : float
        Standard deviation over the fit of the command ``u_c`` and of the estimated actual input
        ``u_c + d_c``, rad.
    residual_rms : float
        RMS residual of the fit, rad.
    rho_bound, bias_bound : float
        Worst-case error bounds of ``rho`` (-) and ``bias`` (rad) (see :class:`FaultIsolator`;
        infinite when the actual input's spread does not exceed the noise).
    mean_command, mean_deviation : float
        Means over the fit of ``u_c`` and ``d_c``, rad: what is known even when ``rho`` and ``b``
        are not, the deviation ``(rho - 1) u + b`` at the operating point.
    """

    channel: str
    isolated: bool
    detection_time: float
    rho: float
    bias: float
    rho_fit: float
    bias_fit: float
    identifiable: bool
    reason: str
    identification: int
    fit_time: float
    command_std: float
    actual_std: float
    residual_rms: float
    rho_bound: float
    bias_bound: float
    mean_command: float
    mean_deviation: float

    def as_dict(self) -> dict:
        """Return the report as a plain dict (JSON-ready: NaN and infinite floats as None)."""
        out = {}
        for key, value in self.__dict__.items():
            out[key] = None if isinstance(value, float) and not math.isfinite(value) else value
        return out


class IsolationStatus(NamedTuple):
    """What a :class:`FaultIsolator` publishes each step: one entry per channel, in :data:`CHANNELS` order.

    These are the fault-isolation fields of ``uh_msgs/ControllerStatus``.

    Attributes
    ----------
    isolated : tuple of 4 bool
        Reported faulty (latched).
    detection_time : tuple of 4 float
        Run time of the isolation, s (NaN while not isolated).
    deviation : tuple of 4 float
        Low-pass filtered input deviation, rad.
    threshold : tuple of 4 float
        Current isolation threshold, rad.
    effectiveness, bias : tuple of 4 float
        The fit's ``rho`` (-) and constant bias (rad) whatever the verdict (NaN while not
        isolated or while the command has not varied); to be trusted only where
        ``identification`` is :data:`IDENTIFIABLE`.
    identification : tuple of 4 int
        Verdict codes (:data:`IDENTIFICATION_CODES`).
    """

    isolated: tuple
    detection_time: tuple
    deviation: tuple
    threshold: tuple
    effectiveness: tuple
    bias: tuple
    identification: tuple


def input_deviation(nominal, x, u, fhat_p, fhat_w):
    """Return the per-channel input deviations ``d ~ u_act - u`` (rad) that the lumped-fault estimates imply.

    The deviations are those implied under the nominal model: this inverts docs/model.md#lumped-faults
    with the nominal parameters::

        1. dT    = m (R e3 . Fhat_p)                         thrust deviation, N
        2. T     = c_M1 u_col + c_M2,  Ta = T + dT            commanded / actual thrust, N
        3. kT    = K_beta + T h_M,     kTa = K_beta + Ta h_M  flapping stiffness, N m/rad
        4. d_col = dT / c_M1
        5. d_tr  = (J_z Fhat_w,z + c_Q dT) / K_tr
        6. d_lat = (J_x Fhat_w,x - (kTa - kT)(B_lat u_lat - tau_f p)) / (kTa B_lat)
        7. d_lon = (J_y Fhat_w,y - (kTa - kT)(A_lon u_lon - tau_f q)) / (kTa A_lon)

    Parameters
    ----------
    nominal : uh_core.airframe.HelicopterParams
        The controller's nominal model (:func:`uh_controller_node.nominal_model.nominal_model`).
    x : array (12,)
        State ``[p m, v m/s, (phi, theta, psi) rad, (p, q, r) rad/s]``.
    u : array (4,)
        Command ``(theta_col, theta_tr, delta_lat, delta_lon)``, rad (the limited command).
    fhat_p : array (3,)
        Position-loop lumped-fault estimate, m/s^2, inertial.
    fhat_w : array (3,)
        Attitude-loop lumped-fault estimate, rad/s^2, body.

    Returns
    -------
    d : ndarray (4,)
        Deviations ``(d_col, d_tr, d_lat, d_lon)``, rad.
    dT : float
        Thrust deviation, N.
    """
    params = np.zeros(K.ISO_PARAMS_SIZE)
    params[K.IP_MASS:K.IP_C_Q + 1] = _constants(nominal)
    d = np.empty(_N)
    dT = K.input_deviations(params, _array(x), _array(u), _array(fhat_p), _array(fhat_w), d)
    return d, dT


def _array(values) -> np.ndarray:
    """``values`` as a C-contiguous float64 array (the array itself when it is one)."""
    return np.ascontiguousarray(values, dtype=np.float64)


def _constants(P) -> tuple:
    """Return the nominal constants of :func:`input_deviation`, as floats (``IP_MASS`` .. ``IP_C_Q`` of the kernels)."""
    jx, jy, jz = (float(v) for v in P.inertia)
    return (float(P.mass), jx, jy, jz, float(P.c_M1), float(P.c_M2), float(P.K_beta), float(P.h_M),
            float(P.B_lat), float(P.A_lon), float(P.tau_f), float(P.K_tr), float(P.c_Q))


class FaultIsolator:
    """Causal fault isolation and identification for one UH (module docstring, steps 1-3).

    Per :meth:`update` (after the learning phase):

    1. ``d, dT`` from :func:`input_deviation`.
    2. Coupling allowances (rad), for what the nominal model and the observers' different speeds
       let a thrust deviation leak into the other channels' deviations, with ``mu`` the model
       mismatch and ``DeltaT`` the range (max - min) of ``dT`` over the last ``coupling_window``::

           tail rotor:  c_Q (|1/mu - 1| |dT| + DeltaT) / K_tr
           cyclics:     h_M DeltaT |B_lat u_lat - tau_f p| / (kTa B_lat)   (A_lon, u_lon, q)

       The first term of the tail rotor's is the ``c_Q`` error of the nominal model (the true
       ``c_Q`` is the nominal one over ``mu``); the ``DeltaT`` terms cover the observer transient
       after a thrust change: the inner observer (bandwidth 40 rad/s in the paper gains) sees the
       torque reaction of a thrust change before the outer one (20 rad/s) sees the thrust, so
       for a few tenths of a second ``dT`` is behind by up to its whole recent change.
    3. ``y <- y + a (d - y)`` and ``e <- e + a (allowance - e)``, ``a = 1 - exp(-dt / filter_tau)``
       (exact first-order low pass). Since the filter's weights are positive, the filtered
       coupling is at most the filtered allowance, so the threshold is ``threshold_c + e_c``.
    4. A channel with ``|y_c| > threshold_c + e_c`` for ``confirmation_time`` without a break is
       isolated, at that step's time; isolation is latched.
    5. Every isolated channel adds ``(u_c, d_c)`` to its least-squares fit from the step after
       its isolation on.

    The verdict of a fit (:meth:`channel`), with ``s_a`` the standard deviation of the estimated
    actual input ``u_c + d_c`` over the fit, ``r`` the residual RMS, ``n_c`` the healthy noise RMS
    (``noise_rms``) and ``sigma = max(n_c, r)``:

    - Assumption: the part ``e`` of ``d`` that is not ``(rho - 1) u + b`` has ``std(e) <= sigma``
      (the healthy noise, or more if the fit leaves more unexplained).
    - ``rho_bound = sigma / (s_a - sigma)``: the slope's error is ``cov(u, e) / var(u)``, at most
      ``std(e) / std(u)`` (Cauchy-Schwarz); the true actual input ``rho u + b`` has
      ``std = rho std(u) <= std(u)`` and differs from ``u + d`` by ``e``, so
      ``std(u) >= s_a - sigma``. Using the actual input rather than the command also catches a
      command that varies only to cancel a time-varying bias or a disturbance: the actual input
      then stays still, the fit finds a slope near -1 (``rho`` near 0) with a small residual, and
      ``rho`` and ``b(t)`` cannot be separated at all.
    - ``bias_bound = sigma + rho_bound |mean u_c|`` (the intercept's error: ``mean(e)`` plus the
      slope's error times the mean command).
    - identifiable iff the fit spans ``min_fit_time``, ``r <= residual_max_c``, ``rho_bound <=
      rho_tolerance`` and ``bias_bound <= bias_tolerance``.

    Parameters
    ----------
    nominal : uh_core.airframe.HelicopterParams
        The controller's nominal model.
    mismatch : float
        The scenario's ``model_mismatch`` (> 0, -): the nominal ``c_Q`` is ``mismatch`` times the
        true one.
    dt : float
        Control period, s (> 0).
    settings : IsolationSettings, optional
        Default :class:`IsolationSettings()`.
    """

    def __init__(self, nominal, mismatch: float, dt: float, settings: IsolationSettings | None = None):
        if not (isinstance(mismatch, (int, float)) and math.isfinite(mismatch) and mismatch > 0.0):
            raise ValueError(f'mismatch must be a finite number > 0, got {mismatch!r}')
        if not (isinstance(dt, (int, float)) and math.isfinite(dt) and dt > 0.0):
            raise ValueError(f'dt must be a finite number > 0, got {dt!r}')
        self._dt = float(dt)
        self._s = s = settings if settings is not None else IsolationSettings()
        params = np.zeros(K.ISO_PARAMS_SIZE)
        params[K.IP_MASS:K.IP_C_Q + 1] = _constants(nominal)
        params[K.IP_LOWER:K.IP_LOWER + _N] = [float(v) for v in nominal.input_lower]
        params[K.IP_UPPER:K.IP_UPPER + _N] = [float(v) for v in nominal.input_upper]
        params[K.IP_THRESHOLDS:K.IP_THRESHOLDS + _N] = s.thresholds
        params[K.IP_NOISE_RMS:K.IP_NOISE_RMS + _N] = s.noise_rms
        params[K.IP_RESIDUAL_MAX:K.IP_RESIDUAL_MAX + _N] = s.residual_max
        params[K.IP_LEARNING_PHASE], params[K.IP_CONFIRMATION] = s.learning_phase, s.confirmation_time
        params[K.IP_ALPHA] = 1.0 - math.exp(-self._dt / s.filter_tau)
        params[K.IP_CQ_ERROR] = abs(1.0 / float(mismatch) - 1.0)
        params[K.IP_FORGETTING], params[K.IP_DT] = s.forgetting, self._dt
        params[K.IP_RHO_TOLERANCE], params[K.IP_BIAS_TOLERANCE] = s.rho_tolerance, s.bias_tolerance
        params[K.IP_MIN_FIT_TIME] = s.min_fit_time
        self._params = params
        self._state = K.new_isolation_state(max(1, int(round(s.coupling_window / self._dt)) + 1))
        self._verdict_out = np.empty(K.VERDICT_SIZE)
        self._status_out = np.empty((K.STATUS_ROWS, _N))

    # -- per step -------------------------------------------------------------------------------
    def update(self, t: float, x, u, fhat_p, fhat_w) -> None:
        """Process one control step (:func:`uh_controller_node.isolation_kernels.isolation_step`).

        Parameters
        ----------
        t : float
            Run time of the step, ``k dt``, s (increasing; nothing is processed while it is below
            the learning phase).
        x : array (12,)
            State ``[p m, v m/s, (phi, theta, psi) rad, (p, q, r) rad/s]``.
        u : array (4,)
            Command ``(theta_col, theta_tr, delta_lat, delta_lon)``, rad; limited here to the
            nominal model's input limits (the faults act on the limited command).
        fhat_p, fhat_w : array (3,)
            The lumped-fault estimates the controller used at this step, m/s^2 (inertial) and
            rad/s^2 (body).
        """
        K.isolation_step(self._params, self._state, float(t), _array(x), _array(u), _array(fhat_p), _array(fhat_w))

    def run(self, times, states, commands, fhat_p, fhat_w, trace=None) -> None:
        """Process many steps in one compiled call: :meth:`update` for every row ``k``.

        Parameters
        ----------
        times : array (K,)
            Run times of the steps, s (increasing).
        states, commands, fhat_p, fhat_w : arrays (K, 12), (K, 4), (K, 3), (K, 3)
            Row ``k``: :meth:`update`'s arguments of step ``k`` (same units).
        trace : ndarray (K, 12), optional
            Receives after each step the filtered deviations (4), the thresholds (4) and the
            deviations (4), rad: :attr:`filtered_deviation`, :attr:`threshold` and
            :attr:`deviation` after that step.
        """
        times = _array(times)
        if trace is None:
            trace = np.empty((0, K.TRACE_COLUMNS))
        elif trace.shape != (times.shape[0], K.TRACE_COLUMNS) or trace.dtype != np.float64:
            raise ValueError(f'trace must be a float64 array of shape ({times.shape[0]}, {K.TRACE_COLUMNS})')
        K.isolation_run(self._params, self._state, times, _array(states), _array(commands), _array(fhat_p),
                        _array(fhat_w), trace)

    # -- results ----------------------------------------------------------------------------------
    @property
    def settings(self) -> IsolationSettings:
        """The settings in use."""
        return self._s

    @property
    def filtered_deviation(self) -> tuple:
        """Low-pass filtered deviations per channel, rad."""
        return tuple(self._state[K.IS_Y:K.IS_Y + _N].tolist())

    @property
    def deviation(self) -> tuple:
        """The last step's deviations per channel, rad (zero during the learning phase)."""
        return tuple(self._state[K.IS_D:K.IS_D + _N].tolist())

    @property
    def threshold(self) -> tuple:
        """The current isolation threshold per channel (constant + filtered allowance), rad."""
        return tuple(th + e for th, e in zip(self._s.thresholds, self._state[K.IS_E:K.IS_E + _N].tolist(), strict=True))

    @property
    def isolated(self) -> tuple:
        """Per channel: reported faulty (latched)."""
        return tuple(v != 0.0 for v in self._state[K.IS_ISOLATED:K.IS_ISOLATED + _N].tolist())

    @property
    def detection_time(self) -> tuple:
        """Per channel: time of isolation, s (NaN if not isolated)."""
        # NaN as the one math.nan object, so that equal statuses compare equal (== on tuples tries identity first)
        times = self._state[K.IS_DETECTION:K.IS_DETECTION + _N].tolist()
        return tuple(t if isolated else math.nan for t, isolated in zip(times, self.isolated, strict=True))

    def channel(self, c: int) -> ChannelReport:
        """Return the report of channel ``c`` (0..3) now (see the class docstring for the verdict)."""
        c = int(c)
        if not 0 <= c < _N:
            raise ValueError(f'channel must be 0..3, got {c}')
        s = self._s
        name = CHANNELS[c]
        nan = math.nan
        if self._state[K.IS_ISOLATED + c] == 0.0:
            return ChannelReport(name, False, nan, nan, nan, nan, nan, False, 'not isolated',
                                 NOT_ISOLATED, 0.0, nan, nan, nan, nan, nan, nan, nan)
        code, rho_fit, bias_fit, fit_time, std_u, std_a, resid, rho_bound, bias_bound = self._verdict(c)
        if code == FIT_TOO_SHORT:
            reason = f'fit too short ({fit_time:.2g} s < {s.min_fit_time:g} s)'
        elif code == BIAS_NOT_CONSTANT:
            reason = (f'residual {resid:.1e} rad > {s.residual_max[c]:.1e} rad: bias not constant '
                      f'(d not affine in the command)')
        elif code == CONFOUNDED:
            reason = (f'actual input nearly constant (std {std_a:.1e} rad): (rho - 1) u and b '
                      f'confounded (rho bound {rho_bound:.2g}, tolerance {s.rho_tolerance:g}; bias '
                      f'bound {bias_bound:.1e} rad, tolerance {s.bias_tolerance:g} rad)')
            if std_u > 2.0 * std_a:
                reason += (f'; the command varies more (std {std_u:.1e} rad), to cancel a varying '
                           f'deviation (time-varying bias or disturbance)')
        else:
            reason = 'identifiable'
        ok = code == IDENTIFIABLE
        fit = K.IS_FIT + K.FIT_SIZE * c
        w, mu, md = (float(self._state[fit + i]) for i in (K.F_W, K.F_MU, K.F_MD))
        return ChannelReport(name, True, float(self._state[K.IS_DETECTION + c]), rho_fit if ok else nan,
                             bias_fit if ok else nan, rho_fit, bias_fit, ok, reason, code, fit_time, std_u, std_a,
                             resid, rho_bound, bias_bound, mu if w > 0.0 else nan, md if w > 0.0 else nan)

    def _verdict(self, c: int) -> tuple:
        """Return the numbers and verdict code of isolated channel ``c`` (class docstring).

        ``(code, rho_fit, bias_fit, fit_time, std u, std (u + d), residual RMS, rho_bound, bias_bound)``.
        """
        out = self._verdict_out
        K.isolation_verdict(self._params, self._state, c, out)
        v = out.tolist()
        # the "none yet" NaNs as the math.nan object (same bits), as detection_time
        fit = K.IS_FIT + K.FIT_SIZE * c
        if not (self._state[fit + K.F_W] > 0.0 and self._state[fit + K.F_SUU] > 0.0):
            v[K.V_BIAS] = math.nan
        if not self._state[fit + K.F_W] > 0.0:
            v[K.V_STD_U] = v[K.V_STD_A] = v[K.V_RESIDUAL] = math.nan
        return (int(v[K.V_CODE]), v[K.V_RHO], v[K.V_BIAS], v[K.V_FIT_TIME], v[K.V_STD_U], v[K.V_STD_A],
                v[K.V_RESIDUAL], v[K.V_RHO_BOUND], v[K.V_BIAS_BOUND])

    def unable(self, floor: float, spread: float) -> int:
        """Give the first channel found below the effectiveness ``floor`` beyond doubt, or -1.

        ``spread``: rad, the command's standard deviation over the fit must exceed it;
        :func:`uh_controller_node.isolation_kernels.unable_channel` (docs/resilience.md#leaving-the-team).
        """
        return int(K.unable_channel(self._params, self._state, float(floor), float(spread), self._verdict_out))

    def first_unable(self, floor: float, spread: float, times, states, commands, fhat_p, fhat_w) -> tuple:
        """Process rows as :meth:`run` does until :meth:`unable` finds a channel; give ``(row, channel)``.

        ``(-1, -1)`` when no row does; the rows after the one found are not processed.
        """
        k, c = K.first_unable_step(self._params, self._state, _array(times), _array(states), _array(commands),
                                   _array(fhat_p), _array(fhat_w), float(floor), float(spread), self._verdict_out)
        return int(k), int(c)

    def report(self) -> tuple:
        """:class:`ChannelReport` of every channel, in channel order."""
        return tuple(self.channel(c) for c in range(_N))

    def status(self) -> IsolationStatus:
        """Return the per-step summary a controller publishes (:class:`IsolationStatus`).

        The same numbers as :meth:`report`, without its texts: this runs every control step.
        """
        out = self._status_out
        K.isolation_status(self._params, self._state, self._verdict_out, out)
        isolated, detection, deviation, threshold, rho, bias, code, spread = out.tolist()
        isolated = tuple(v != 0.0 for v in isolated)
        nan = math.nan
        for c in range(_N):   # the "none" NaNs as the one math.nan object (same bits), as detection_time
            if not isolated[c]:
                detection[c] = rho[c] = bias[c] = nan
            elif spread[c] == 0.0:
                bias[c] = nan
        return IsolationStatus(isolated, tuple(detection), tuple(deviation), tuple(threshold), tuple(rho),
                               tuple(bias), tuple(int(v) for v in code))
