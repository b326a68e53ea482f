"""Causal fault isolation and identification per actuator channel from the lumped-fault estimates
(docs/faults.md#isolation-and-identification).

The controller's observers estimate lumped faults, ``Fhat_p`` (m/s^2, inertial) and ``Fhat_w``
(rad/s^2, body) (docs/control_law.md#learning-and-estimation); they do not say which actuator is
faulty, nor by how much. This module turns them back into per-channel input deviations, decides
which channels are faulty, and fits the fault model of eq. 6 (docs/faults.md#fault-model),
``u_act = rho u + b``, to each channel found faulty. It uses only what one controller has at each
step (its nominal model, its state, its command and its estimates), so it can run beside the
controller, or afterwards over a recorded run (:func:`isolate_run`). No ROS, numpy and floats
only, deterministic.

1. **Input deviations** (:func:`input_deviation`). Inverting the lumped-fault formulas of
   docs/model.md#lumped-faults with the nominal model gives, per step, an estimate ``d`` (rad) of
   ``u_act - u`` per channel, which eq. 6 says is ``(rho - 1) u + b(t)``.
2. **Isolation** (:class:`FaultIsolator`). Each channel's deviation is low-pass filtered (first
   order, time constant ``filter_tau``); the channel is isolated (reported faulty, latched) once
   ``|filtered d|`` has stayed above the channel's threshold for ``confirmation_time``. The
   threshold is a constant per channel plus a coupling allowance that grows with the estimated
   thrust deviation (the collective leaks into the tail rotor through ``c_Q`` and into the cyclics
   through ``h_M``). Nothing is processed during the controller's learning phase, when the
   estimates are held at zero.
3. **Identification**. From its isolation on, each isolated channel fits ``d = theta_1 u + theta_2``
   by recursive least squares (exact, no prior; forgetting factor 1 by default), giving
   ``rho = 1 + theta_1`` and the constant bias ``b = theta_2``, and a verdict saying whether the
   fit can be trusted, with the reason when not.

The defaults of :class:`IsolationSettings` and their justification (the healthy deviation
statistics of the bundled scenarios) are in docs/faults.md#isolation-and-identification.
"""
from __future__ import annotations

import math
from collections import deque
from dataclasses import dataclass

import numpy as np

__all__ = ['CHANNELS', 'IsolationSettings', 'ChannelReport', 'FaultIsolator', 'input_deviation',
           'thrust_axis', 'isolate_run']

#: Channel names, in input order (docs/faults.md#channels).
CHANNELS = ('collective', 'tail_rotor', 'lateral', 'longitudinal')
_N = len(CHANNELS)


@dataclass(frozen=True)
class IsolationSettings:
    """Settings of a :class:`FaultIsolator`; the defaults are justified in
    docs/faults.md#isolation-and-identification.

    Attributes
    ----------
    1. learning_phase : float
        s after the first update during which nothing is processed (the controller's observers
        hold zero then; docs/control_law.md#learning-phase). The paper gains' 8 s;
        :func:`isolate_run` takes the scenario's own value.
    2. filter_tau : float
        Time constant of the first-order low-pass filter on each deviation, s.
    3. thresholds : tuple of 4 float
        Constant part of the isolation threshold per channel, rad: three times the largest
        filtered healthy deviation measured on the bundled scenarios, rounded up.
    4. confirmation_time : float
        How long ``|filtered d|`` must stay above its threshold, without a break, before the
        channel is isolated, s.
    5. coupling_window : float
        Window over which the range of the thrust-deviation estimate counts as not yet settled
        between the outer and inner observers, s (the coupling allowances, see
        :class:`FaultIsolator`).
    6. forgetting : float
        Forgetting factor of the least-squares fit per step, in (0, 1]; 1: none (the fault model's
        ``rho`` and constant bias are constants).
    7. noise_rms : tuple of 4 float
        RMS of the healthy deviation per channel, rad (measured on the bundled scenarios): the
        a priori size of what in ``d`` is not the fault, used in the fit's error bounds.
    8. residual_max : tuple of 4 float
        Largest RMS residual of the fit per channel for which the fault counts as affine in the
        command (``rho`` and a constant bias), rad.
    9. rho_tolerance, bias_tolerance : float
        A fit is called identifiable only if its worst-case error bounds are within these (-, rad).
    10. min_fit_time : float
        Shortest fit, s, before a verdict can be identifiable.
    """

    learning_phase: float = 8.0
    filter_tau: float = 0.2
    thresholds: tuple = (1.0e-3, 7.5e-4, 1.2e-4, 2.7e-4)
    confirmation_time: float = 0.5
    coupling_window: float = 0.3
    forgetting: float = 1.0
    noise_rms: tuple = (2.0e-4, 1.1e-4, 2.0e-5, 1.1e-4)
    residual_max: tuple = (1.0e-3, 5.0e-4, 2.0e-4, 5.0e-4)
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
    1. channel : str
        Name (:data:`CHANNELS`).
    2. isolated : bool
        Reported faulty (latched).
    3. detection_time : float
        Time of the isolation, s (NaN if not isolated).
    4. rho, bias : float
        Effectiveness (-) and constant bias (rad) of the fit; NaN unless ``identifiable``.
    5. rho_fit, bias_fit : float
        The fit's values whatever the verdict (NaN before two distinct commands were seen).
    6. identifiable : bool
        The fit's worst-case error bounds are within the tolerances and its residual is small.
    7. reason : str
        Why not identifiable (``'identifiable'`` when it is).
    8. fit_time : float
        Time span of the fit, s.
    9. command_std, actual_std : float
        Standard deviation over the fit of the command ``u_c`` and of the estimated actual input
        ``u_c + d_c``, rad.
    10. residual_rms : float
        RMS residual of the fit, rad.
    11. rho_bound, bias_bound : float
        Worst-case error bounds of ``rho`` (-) and ``bias`` (rad) (see :class:`FaultIsolator`).
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
    fit_time: float
    command_std: float
    actual_std: float
    residual_rms: float
    rho_bound: float
    bias_bound: float

    def as_dict(self) -> dict:
        """The report as a plain dict (floats, NaN as None)."""
        out = {}
        for key, value in self.__dict__.items():
            out[key] = None if isinstance(value, float) and math.isnan(value) else value
        return out


def thrust_axis(euler) -> np.ndarray:
    """1. The thrust axis ``R(Theta) e3`` in the inertial frame (ZYX Euler angles ``(phi, theta,
    psi)`` in rad; docs/model.md#frames-and-conventions), shape (3,)."""
    phi, theta, psi = float(euler[0]), float(euler[1]), float(euler[2])
    cf, sf, ct, st, cp, sp = (math.cos(phi), math.sin(phi), math.cos(theta), math.sin(theta),
                              math.cos(psi), math.sin(psi))
    return np.array([cp * st * cf + sp * sf, sp * st * cf - cp * sf, ct * cf])


def input_deviation(nominal, x, u, fhat_p, fhat_w):
    """The per-channel input deviations ``d ~ u_act - u`` (rad) that the lumped-fault estimates
    imply under the nominal model.

    Inverts docs/model.md#lumped-faults with the nominal parameters::

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
    P = nominal
    jx, jy, jz = (float(v) for v in P.inertia)
    dT = float(P.mass) * float(np.dot(thrust_axis(x[6:9]), fhat_p))
    T = P.c_M1 * float(u[0]) + P.c_M2
    k_t = P.K_beta + T * P.h_M
    k_ta = P.K_beta + (T + dT) * P.h_M
    d = np.empty(_N)
    d[0] = dT / P.c_M1
    d[1] = (jz * float(fhat_w[2]) + P.c_Q * dT) / P.K_tr
    d[2] = (jx * float(fhat_w[0]) - (k_ta - k_t) * (P.B_lat * float(u[2]) - P.tau_f * float(x[9]))) \
        / (k_ta * P.B_lat)
    d[3] = (jy * float(fhat_w[1]) - (k_ta - k_t) * (P.A_lon * float(u[3]) - P.tau_f * float(x[10]))) \
        / (k_ta * P.A_lon)
    return d, dT


class _AffineFit:
    """Recursive least squares of ``d = theta_1 u + theta_2`` in its exact (sufficient-statistics)
    form: exponentially weighted mean and centred second moments, updated per sample (West's
    weighted Welford recursion). Equivalent to the covariance form of RLS started with an infinite
    covariance (no prior), which that form only approximates with a large ``P_0``."""

    __slots__ = ('lam', 'w', 'mu', 'md', 'suu', 'sud', 'sdd', 't0', 't1')

    def __init__(self, lam: float):
        self.lam = lam
        self.w = 0.0                      # sum of weights
        self.mu = self.md = 0.0           # weighted means of u and d
        self.suu = self.sud = self.sdd = 0.0   # weighted centred sums
        self.t0 = self.t1 = math.nan

    def add(self, t: float, u: float, d: float) -> None:
        lam = self.lam
        self.w *= lam
        self.suu *= lam
        self.sud *= lam
        self.sdd *= lam
        self.w += 1.0
        du = u - self.mu
        dd = d - self.md
        self.mu += du / self.w
        self.md += dd / self.w
        self.suu += du * (u - self.mu)
        self.sud += du * (d - self.md)
        self.sdd += dd * (d - self.md)
        if math.isnan(self.t0):
            self.t0 = t
        self.t1 = t

    def theta(self):
        """``(theta_1, theta_2)``; NaN while the command has not varied."""
        if self.w <= 0.0 or not self.suu > 0.0:
            return math.nan, math.nan
        th1 = self.sud / self.suu
        return th1, self.md - th1 * self.mu

    def stats(self):
        """``(std u, std (u + d), residual RMS)`` over the fit, rad."""
        if self.w <= 0.0:
            return math.nan, math.nan, math.nan
        var_u = max(self.suu, 0.0) / self.w
        var_a = max(self.suu + 2.0 * self.sud + self.sdd, 0.0) / self.w
        if self.suu > 0.0:
            rss = self.sdd - self.sud * self.sud / self.suu
        else:
            rss = self.sdd
        return math.sqrt(var_u), math.sqrt(var_a), math.sqrt(max(rss, 0.0) / self.w)


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

    - ``rho_bound = sigma / s_a``: the slope's error is ``cov(u, e) / var(u)`` for the part ``e``
      of ``d`` that is not the fault; it is at most ``std(e) / std(u)`` (Cauchy-Schwarz), and
      ``std(u) >= s_a`` when the fault is affine (``s_a = rho std(u)``). Using ``s_a`` rather than
      ``std(u)`` also catches a command that varies only to cancel a time-varying bias (the
      actual input then stays still and ``rho`` and ``b(t)`` cannot be separated at all).
    - ``bias_bound = sigma + rho_bound |mean u_c|`` (the intercept's error).
    - identifiable iff the fit spans ``min_fit_time``, ``r <= residual_max_c``, ``rho_bound <=
      rho_tolerance`` and ``bias_bound <= bias_tolerance``.

    Parameters
    ----------
    nominal : uh_core.airframe.HelicopterParams
        The controller's nominal model.
    mismatch : float
        The scenario's ``model_mismatch`` (> 0): the nominal ``c_Q`` is ``mismatch`` times the true one.
    dt : float
        Control period, s (> 0).
    settings : IsolationSettings, optional
    """

    def __init__(self, nominal, mismatch: float, dt: float, settings: IsolationSettings | None = None):
        if not (isinstance(mismatch, (int, float)) and math.isfinite(mismatch) and mismatch > 0.0):
            raise ValueError(f'mismatch must be a finite number > 0, got {mismatch!r}')
        if not (isinstance(dt, (int, float)) and math.isfinite(dt) and dt > 0.0):
            raise ValueError(f'dt must be a finite number > 0, got {dt!r}')
        self._p = nominal
        self._mismatch = float(mismatch)
        self._dt = float(dt)
        self._s = settings if settings is not None else IsolationSettings()
        self._alpha = 1.0 - math.exp(-self._dt / self._s.filter_tau)
        self._cq_error = abs(1.0 / self._mismatch - 1.0)
        self._thr = np.array(self._s.thresholds)
        self._t_first = math.nan
        self._y = np.zeros(_N)                 # filtered deviations, rad
        self._e = np.zeros(_N)                 # filtered coupling allowances, rad
        self._above_since = [math.nan] * _N
        self._isolated = [False] * _N
        self._t_iso = [math.nan] * _N
        self._fits = [None] * _N
        self._dT_window = deque(maxlen=max(1, int(round(self._s.coupling_window / self._dt)) + 1))
        self._last_d = np.zeros(_N)

    # -- per step -------------------------------------------------------------------------------
    def update(self, t: float, x, u, fhat_p, fhat_w) -> None:
        """Process one control step.

        Parameters
        ----------
        t : float
            Step time, s (increasing).
        x : array (12,)
            State ``[p, v, Theta, omega]``, SI units, rad.
        u : array (4,)
            Command ``(theta_col, theta_tr, delta_lat, delta_lon)``, rad; limited here to the
            nominal model's input limits (the faults act on the limited command).
        fhat_p, fhat_w : array (3,)
            The lumped-fault estimates the controller used at this step, m/s^2 (inertial) and
            rad/s^2 (body).
        """
        t = float(t)
        if math.isnan(self._t_first):
            self._t_first = t
        if t - self._t_first < self._s.learning_phase - 1e-9:
            return
        P = self._p
        u = np.clip(np.asarray(u, dtype=float), P.input_lower, P.input_upper)
        x = np.asarray(x, dtype=float)
        d, dT = input_deviation(P, x, u, np.asarray(fhat_p, dtype=float), np.asarray(fhat_w, dtype=float))
        self._last_d = d
        self._dT_window.append(dT)
        spread = max(self._dT_window) - min(self._dT_window)
        k_ta = P.K_beta + (P.c_M1 * u[0] + P.c_M2 + dT) * P.h_M
        allowance = np.array([
            0.0,
            P.c_Q * (self._cq_error * abs(dT) + spread) / P.K_tr,
            P.h_M * spread * abs(P.B_lat * u[2] - P.tau_f * x[9]) / (abs(k_ta) * P.B_lat),
            P.h_M * spread * abs(P.A_lon * u[3] - P.tau_f * x[10]) / (abs(k_ta) * P.A_lon),
        ])
        a = self._alpha
        self._y += a * (d - self._y)
        self._e += a * (allowance - self._e)
        for c in range(_N):
            if self._isolated[c]:
                self._fits[c].add(t, float(u[c]), float(d[c]))
                continue
            if abs(self._y[c]) > self._thr[c] + self._e[c]:
                if math.isnan(self._above_since[c]):
                    self._above_since[c] = t
                if t - self._above_since[c] >= self._s.confirmation_time - 1e-9:
                    self._isolated[c] = True
                    self._t_iso[c] = t
                    self._fits[c] = _AffineFit(self._s.forgetting)
            else:
                self._above_since[c] = math.nan

    # -- results ----------------------------------------------------------------------------------
    @property
    def settings(self) -> IsolationSettings:
        """The settings in use."""
        return self._s

    @property
    def filtered_deviation(self) -> tuple:
        """Low-pass filtered deviations per channel, rad."""
        return tuple(float(v) for v in self._y)

    @property
    def deviation(self) -> tuple:
        """The last step's deviations per channel, rad (zero during the learning phase)."""
        return tuple(float(v) for v in self._last_d)

    @property
    def threshold(self) -> tuple:
        """The current isolation threshold per channel (constant + filtered allowance), rad."""
        return tuple(float(v) for v in self._thr + self._e)

    @property
    def isolated(self) -> tuple:
        """Per channel: reported faulty (latched)."""
        return tuple(self._isolated)

    @property
    def detection_time(self) -> tuple:
        """Per channel: time of isolation, s (NaN if not isolated)."""
        return tuple(self._t_iso)

    @property
    def rho(self) -> tuple:
        """Per channel: identified effectiveness (-), NaN unless identifiable."""
        return tuple(self.channel(c).rho for c in range(_N))

    @property
    def bias(self) -> tuple:
        """Per channel: identified constant bias, rad, NaN unless identifiable."""
        return tuple(self.channel(c).bias for c in range(_N))

    @property
    def identifiable(self) -> tuple:
        """Per channel: the verdict (False when not isolated)."""
        return tuple(self.channel(c).identifiable for c in range(_N))

    @property
    def reason(self) -> tuple:
        """Per channel: the verdict's reason."""
        return tuple(self.channel(c).reason for c in range(_N))

    def channel(self, c: int) -> ChannelReport:
        """The report of channel ``c`` (0..3) now (see the class docstring for the verdict)."""
        c = int(c)
        if not 0 <= c < _N:
            raise ValueError(f'channel must be 0..3, got {c}')
        s = self._s
        name = CHANNELS[c]
        nan = math.nan
        if not self._isolated[c]:
            return ChannelReport(name, False, nan, nan, nan, nan, nan, False, 'not isolated',
                                 0.0, nan, nan, nan, nan, nan)
        fit = self._fits[c]
        fit_time = 0.0 if fit.w == 0.0 else fit.t1 - fit.t0 + self._dt
        th1, th2 = fit.theta()
        std_u, std_a, resid = fit.stats()
        rho_fit, bias_fit = 1.0 + th1, th2
        sigma = max(s.noise_rms[c], resid) if not math.isnan(resid) else nan
        rho_bound = sigma / std_a if std_a > 0.0 else math.inf
        bias_bound = sigma + rho_bound * abs(fit.mu) if not math.isnan(sigma) else nan
        if fit_time < s.min_fit_time - 1e-9 or math.isnan(th1):
            reason = f'fit too short ({fit_time:.2g} s < {s.min_fit_time:g} s)'
        elif resid > s.residual_max[c]:
            reason = (f'residual {resid:.1e} rad > {s.residual_max[c]:.1e} rad: bias not constant '
                      f'(d not affine in the command)')
        elif rho_bound > s.rho_tolerance or bias_bound > s.bias_tolerance:
            reason = (f'actual input nearly constant (std {std_a:.1e} rad, command std {std_u:.1e} rad): '
                      f'(rho - 1) u and b confounded (rho bound {rho_bound:.2g} > {s.rho_tolerance:g} '
                      f'or bias bound {bias_bound:.1e} rad > {s.bias_tolerance:g} rad)')
        else:
            reason = 'identifiable'
        ok = reason == 'identifiable'
        return ChannelReport(name, True, self._t_iso[c], rho_fit if ok else nan, bias_fit if ok else nan,
                             rho_fit, bias_fit, ok, reason, fit_time, std_u, std_a, resid,
                             rho_bound, bias_bound)

    def report(self) -> tuple:
        """:class:`ChannelReport` of every channel, in channel order."""
        return tuple(self.channel(c) for c in range(_N))


def isolate_run(arrays, scenario, case: str = 'proposed', settings: IsolationSettings | None = None) -> dict:
    """Run one :class:`FaultIsolator` per UH over a team run's time series.

    Parameters
    ----------
    arrays : mapping
        ``time`` (K+1,) s, ``states`` (K+1, n, 12), ``commands`` (K or K+1, n, 4) rad,
        ``fault_est_p``, ``fault_est_w`` (K or K+1, n, 3), UH axis in ``scenario.ids`` order, the
        estimates of row ``k`` those the controller used at step ``k``
        (``uh_team.team_simulation.TeamRun.arrays()`` or a recorded run's arrays).
    scenario : uh_topology.scenario.Scenario
        Gives the helicopter, the model mismatch, ``dt`` and the learning phase of its gains.
    case : str
        Controller case whose gains give the learning phase.
    settings : IsolationSettings, optional
        Default: :class:`IsolationSettings` with the scenario's learning phase.

    Returns
    -------
    dict
        ``{"uh<i>": {"isolated": [channel names], "channels": {name: ChannelReport.as_dict()}}}``
        for every UH, plus ``"settings"`` (the settings used, as a dict).
    """
    import dataclasses

    from uh_core.airframe import load_helicopter_params

    from .gains import ControllerGains
    from .nominal_model import nominal_model

    if settings is None:
        phase = ControllerGains.from_mapping(scenario.gains, case).learning_phase
        settings = IsolationSettings(learning_phase=float(phase))
    nominal = nominal_model(load_helicopter_params(scenario.helicopter), scenario.model_mismatch)
    time = np.asarray(arrays['time'], dtype=float)
    states = np.asarray(arrays['states'], dtype=float)
    commands = np.asarray(arrays['commands'], dtype=float)
    est_p = np.asarray(arrays['fault_est_p'], dtype=float)
    est_w = np.asarray(arrays['fault_est_w'], dtype=float)
    rows = min(len(time), len(states), len(commands), len(est_p), len(est_w))
    ids = tuple(scenario.ids)
    if states.shape[1] != len(ids):
        raise ValueError(f'arrays have {states.shape[1]} UHs, the scenario {len(ids)}')
    out = {}
    for j, uh in enumerate(ids):
        iso = FaultIsolator(nominal, scenario.model_mismatch, float(scenario.dt), settings)
        for k in range(rows):
            iso.update(time[k], states[k, j], commands[k, j], est_p[k, j], est_w[k, j])
        reports = iso.report()
        out[f'uh{uh}'] = {
            'isolated': [r.channel for r in reports if r.isolated],
            'channels': {r.channel: r.as_dict() for r in reports},
        }
    out['settings'] = dataclasses.asdict(settings)
    return out
