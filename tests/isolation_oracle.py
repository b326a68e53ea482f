"""Frozen pure-Python fault isolator, the oracle of the tests of the compiled one.

A copy of ``uh_controller_node.fault_isolation`` as it was before its per-step arithmetic moved to
numba kernels (:mod:`uh_controller_node.isolation_kernels`): ``_deviation``, ``_AffineFit``,
``FaultIsolator`` and ``isolate_run`` step by step in Python floats. The compiled isolator must
give exactly the same numbers (every bit), since the kernels keep numba's default IEEE double
arithmetic (no fastmath) and the same order of operations. Do not edit the arithmetic here: it is
the reference. Described in docs/faults.md#isolation-and-identification.
"""
from __future__ import annotations

import math
from collections import deque
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np

from uh_controller_node.gains import ControllerGains
from uh_controller_node.nominal_model import nominal_model
from uh_core.airframe import load_helicopter_params
from uh_core.layout import X_OMEGA, X_THETA_SLICE

__all__ = ['CHANNELS', 'IsolationSettings', 'ChannelReport', 'IsolationStatus', 'FaultIsolator', 'input_deviation',
           'isolate_run', 'healthy_deviation_statistics', 'IDENTIFICATION_CODES', 'NOT_ISOLATED',
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
        :func:`isolate_run` takes the scenario's own value.
    filter_tau : float
        Time constant of the first-order low-pass filter on each deviation, s (0.2: smooths the
        observers' onset transients, a few of their 1/20 s and 1/40 s time constants).
    thresholds : tuple of 4 float
        Constant part of the isolation threshold per channel, rad: three times the largest
        filtered healthy deviation after the learning phase on the bundled scenarios
        (:func:`healthy_deviation_statistics`), rounded up to two digits.
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
    d, dT, _ = _deviation(_constants(nominal), [float(v) for v in x[X_OMEGA:X_OMEGA + 2]], [float(v) for v in u],
                          [float(v) for v in x[X_THETA_SLICE]], [float(v) for v in fhat_p], [float(v) for v in fhat_w])
    return np.array(d), dT


def _floats(values) -> list:
    """Python floats of a numpy array (one ``tolist``) or of any sequence of numbers."""
    return values.tolist() if isinstance(values, np.ndarray) else [float(v) for v in values]


def _constants(P) -> tuple:
    """Return the nominal constants :func:`_deviation` uses, as floats."""
    jx, jy, jz = (float(v) for v in P.inertia)
    return (float(P.mass), jx, jy, jz, float(P.c_M1), float(P.c_M2), float(P.K_beta), float(P.h_M),
            float(P.B_lat), float(P.A_lon), float(P.tau_f), float(P.K_tr), float(P.c_Q))


def _deviation(k, pq, u, euler, fp, fw):
    """Compute :func:`input_deviation` on floats.

    ``k`` from :func:`_constants`, ``pq`` the body rates ``(p, q)``; returns
    ``([d_col, d_tr, d_lat, d_lon], dT, kTa)``.
    """
    m, jx, jy, jz, c_m1, c_m2, k_beta, h_m, b_lat, a_lon, tau_f, k_tr, c_q = k
    phi, theta, psi = euler
    cf, sf, ct, st, cp, sp = (math.cos(phi), math.sin(phi), math.cos(theta), math.sin(theta),
                              math.cos(psi), math.sin(psi))
    dT = m * ((cp * st * cf + sp * sf) * fp[0] + (sp * st * cf - cp * sf) * fp[1] + ct * cf * fp[2])
    T = c_m1 * u[0] + c_m2
    k_t = k_beta + T * h_m
    k_ta = k_beta + (T + dT) * h_m
    d = [dT / c_m1,
         (jz * fw[2] + c_q * dT) / k_tr,
         (jx * fw[0] - (k_ta - k_t) * (b_lat * u[2] - tau_f * pq[0])) / (k_ta * b_lat),
         (jy * fw[1] - (k_ta - k_t) * (a_lon * u[3] - tau_f * pq[1])) / (k_ta * a_lon)]
    return d, dT, k_ta


class _AffineFit:
    """Recursive least squares of ``d = theta_1 u + theta_2`` in its exact (sufficient-statistics) form.

    Exponentially weighted mean and centred second moments, updated per sample (West's
    weighted Welford recursion). Equivalent to the covariance form of RLS started with an infinite
    covariance (no prior), which that form only approximates with a large ``P_0``.
    """

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
        self._mismatch = float(mismatch)
        self._dt = float(dt)
        self._s = settings if settings is not None else IsolationSettings()
        self._alpha = 1.0 - math.exp(-self._dt / self._s.filter_tau)
        self._cq_error = abs(1.0 / self._mismatch - 1.0)
        self._k = _constants(nominal)
        self._lower = [float(v) for v in nominal.input_lower]
        self._upper = [float(v) for v in nominal.input_upper]
        self._thr = list(self._s.thresholds)
        self._y = [0.0] * _N                   # filtered deviations, rad
        self._e = [0.0] * _N                   # filtered coupling allowances, rad
        self._above_since = [math.nan] * _N
        self._isolated = [False] * _N
        self._t_iso = [math.nan] * _N
        self._fits = [None] * _N
        self._dT_window = deque(maxlen=max(1, int(round(self._s.coupling_window / self._dt)) + 1))
        self._last_d = [0.0] * _N

    # -- per step -------------------------------------------------------------------------------
    def update(self, t: float, x, u, fhat_p, fhat_w) -> None:
        """Process one control step.

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
        t = float(t)
        if t < self._s.learning_phase - 1e-9:
            return
        u = [min(max(v, lo), hi) for v, lo, hi in zip(_floats(u), self._lower, self._upper, strict=False)]
        x = _floats(x)
        d, dT, k_ta = _deviation(self._k, x[X_OMEGA:X_OMEGA + 2], u, x[X_THETA_SLICE], _floats(fhat_p), _floats(fhat_w))
        self._last_d = d
        window = self._dT_window
        window.append(dT)
        spread = max(window) - min(window)
        _, _, _, _, _, _, _, h_m, b_lat, a_lon, tau_f, k_tr, c_q = self._k
        allowance = (0.0,
                     c_q * (self._cq_error * abs(dT) + spread) / k_tr,
                     h_m * spread * abs(b_lat * u[2] - tau_f * x[9]) / (abs(k_ta) * b_lat),
                     h_m * spread * abs(a_lon * u[3] - tau_f * x[10]) / (abs(k_ta) * a_lon))
        a = self._alpha
        y, e = self._y, self._e
        for c in range(_N):
            y[c] += a * (d[c] - y[c])
            e[c] += a * (allowance[c] - e[c])
        for c in range(_N):
            if self._isolated[c]:
                self._fits[c].add(t, u[c], d[c])
                continue
            if abs(y[c]) > self._thr[c] + e[c]:
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
        return tuple(th + e for th, e in zip(self._thr, self._e, strict=False))

    @property
    def isolated(self) -> tuple:
        """Per channel: reported faulty (latched)."""
        return tuple(self._isolated)

    @property
    def detection_time(self) -> tuple:
        """Per channel: time of isolation, s (NaN if not isolated)."""
        return tuple(self._t_iso)

    def channel(self, c: int) -> ChannelReport:
        """Return the report of channel ``c`` (0..3) now (see the class docstring for the verdict)."""
        c = int(c)
        if not 0 <= c < _N:
            raise ValueError(f'channel must be 0..3, got {c}')
        s = self._s
        name = CHANNELS[c]
        nan = math.nan
        if not self._isolated[c]:
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
        fit = self._fits[c]
        return ChannelReport(name, True, self._t_iso[c], rho_fit if ok else nan, bias_fit if ok else nan,
                             rho_fit, bias_fit, ok, reason, code, fit_time, std_u, std_a, resid,
                             rho_bound, bias_bound, fit.mu if fit.w > 0.0 else nan,
                             fit.md if fit.w > 0.0 else nan)

    def _verdict(self, c: int) -> tuple:
        """Return the numbers and verdict code of isolated channel ``c`` (class docstring).

        ``(code, rho_fit, bias_fit, fit_time, std u, std (u + d), residual RMS, rho_bound, bias_bound)``.
        """
        s = self._s
        fit = self._fits[c]
        fit_time = 0.0 if fit.w == 0.0 else fit.t1 - fit.t0 + self._dt
        th1, th2 = fit.theta()
        std_u, std_a, resid = fit.stats()
        sigma = max(s.noise_rms[c], resid) if not math.isnan(resid) else math.nan
        rho_bound = sigma / (std_a - sigma) if std_a > sigma else math.inf
        bias_bound = sigma + rho_bound * abs(fit.mu) if math.isfinite(rho_bound) else math.inf
        if fit_time < s.min_fit_time - 1e-9:
            code = FIT_TOO_SHORT
        elif resid > s.residual_max[c]:
            code = BIAS_NOT_CONSTANT
        elif rho_bound > s.rho_tolerance or bias_bound > s.bias_tolerance:
            code = CONFOUNDED
        else:
            code = IDENTIFIABLE
        return code, 1.0 + th1, th2, fit_time, std_u, std_a, resid, rho_bound, bias_bound

    def report(self) -> tuple:
        """:class:`ChannelReport` of every channel, in channel order."""
        return tuple(self.channel(c) for c in range(_N))

    def status(self) -> IsolationStatus:
        """Return the per-step summary a controller publishes (:class:`IsolationStatus`).

        The same numbers as :meth:`report`, without its texts: this runs every control step.
        """
        rho, bias, code = [math.nan] * _N, [math.nan] * _N, [NOT_ISOLATED] * _N
        for c in range(_N):
            if self._isolated[c]:
                code[c], rho[c], bias[c] = self._verdict(c)[:3]
        return IsolationStatus(tuple(self._isolated), tuple(self._t_iso), tuple(self._y),
                               tuple(th + e for th, e in zip(self._thr, self._e, strict=False)), tuple(rho),
                               tuple(bias), tuple(code))


def _setup(arrays, scenario, case, settings):
    """Return the nominal model, the settings and the run's arrays.

    The settings default to the scenario's learning phase; the arrays are float arrays, rows cut to
    the shortest.
    """
    if settings is None:
        phase = ControllerGains.from_mapping(scenario.gains, case).learning_phase
        settings = IsolationSettings(learning_phase=float(phase))
    nominal = nominal_model(load_helicopter_params(scenario.helicopter), scenario.model_mismatch)
    keys = ('time', 'states', 'commands', 'fault_est_p', 'fault_est_w')
    data = {key: np.asarray(arrays[key], dtype=float) for key in keys}
    rows = min(len(v) for v in data.values())
    n = len(tuple(scenario.ids))
    if data['states'].ndim != 3 or data['states'].shape[1] != n:
        raise ValueError(f'arrays have UH axis {data["states"].shape[1:2]}, the scenario {n} UHs')
    return nominal, settings, {key: v[:rows] for key, v in data.items()}


def _steps(data, j):
    """Per-step arguments of :meth:`FaultIsolator.update` for UH column ``j``."""
    return zip(data['time'].tolist(), data['states'][:, j].tolist(), data['commands'][:, j].tolist(),
               data['fault_est_p'][:, j].tolist(), data['fault_est_w'][:, j].tolist(), strict=False)


def isolate_run(arrays, scenario, case: str = 'proposed', settings: IsolationSettings | None = None) -> dict:
    """Run one :class:`FaultIsolator` per UH over a team run's time series.

    Parameters
    ----------
    arrays : mapping
        ``time`` (K+1,) s, ``states`` (K+1, n, 12), ``commands`` (K or K+1, n, 4) rad,
        ``fault_est_p`` m/s^2, ``fault_est_w`` rad/s^2 (K or K+1, n, 3); UH axis in
        ``scenario.ids`` order; the estimates of row ``k`` are those the controller used at step
        ``k`` (``uh_team.team_simulation.TeamRun.arrays()``, or a recorded run's arrays). Rows
        beyond the shortest array are ignored.
    scenario : uh_topology.scenario.Scenario
        Gives the helicopter, the model mismatch, ``dt`` and (with ``case``) the learning phase.
    case : str
        Controller case whose gains give the learning phase.
    settings : IsolationSettings, optional
        Default: :class:`IsolationSettings` with the scenario's learning phase.

    Returns
    -------
    dict
        ``{"uh<i>": {"isolated": [channel names], "channels": {name: ChannelReport.as_dict()}}}``
        for every UH, and ``"settings"``: the settings used, as a dict. Deterministic.
    """
    import dataclasses

    nominal, settings, data = _setup(arrays, scenario, case, settings)
    out = {}
    for j, uh in enumerate(tuple(scenario.ids)):
        iso = FaultIsolator(nominal, scenario.model_mismatch, float(scenario.dt), settings)
        for step in _steps(data, j):
            iso.update(*step)
        reports = iso.report()
        out[f'uh{uh}'] = {
            'isolated': [r.channel for r in reports if r.isolated],
            'channels': {r.channel: r.as_dict() for r in reports},
        }
    out['settings'] = dataclasses.asdict(settings)
    return out


def healthy_deviation_statistics(arrays, scenario, case: str = 'proposed',
                                 settings: IsolationSettings | None = None,
                                 settle: float = 1.0) -> dict:
    """Return the healthy deviation statistics the default thresholds and noise levels are set from.

    See docs/faults.md#isolation-and-identification. Per channel, over every fault-free UH and over
    every faulted UH before its earliest onset, after the learning phase.

    Parameters
    ----------
    arrays, scenario, case, settings
        As for :func:`isolate_run` (the scenario's faults say which samples are healthy).
    settle : float
        s after the learning phase from which ``rms`` is taken (the networks' switch-over
        transient at the end of the phase is left out of it).

    Returns
    -------
    dict
        ``{channel name: {"filtered_max": rad, "filtered_max_at": "uh<i> t=<s>", "rms": rad}}``:
        the largest ``|filtered d|`` after the learning phase and the largest per-UH RMS of the
        raw ``d`` after ``learning_phase + settle``.
    """
    nominal, settings, data = _setup(arrays, scenario, case, settings)
    out = {name: {'filtered_max': 0.0, 'filtered_max_at': None, 'rms': 0.0} for name in CHANNELS}
    for j, uh in enumerate(tuple(scenario.ids)):
        onset = min((float(f.onset_time) for f in scenario.faults[uh]), default=math.inf)
        iso = FaultIsolator(nominal, scenario.model_mismatch, float(scenario.dt), settings)
        sums, counts = [0.0] * _N, 0
        for step in _steps(data, j):
            t = step[0]
            if t >= onset - 1e-9:
                break
            iso.update(*step)
            if t < settings.learning_phase - 1e-9:
                continue
            y, d = iso.filtered_deviation, iso.deviation
            for c, name in enumerate(CHANNELS):
                if abs(y[c]) > out[name]['filtered_max']:
                    out[name]['filtered_max'] = abs(y[c])
                    out[name]['filtered_max_at'] = f'uh{uh} t={t:.2f}'
            if t >= settings.learning_phase + settle - 1e-9:
                counts += 1
                for c in range(_N):
                    sums[c] += d[c] * d[c]
        if counts:
            for c, name in enumerate(CHANNELS):
                out[name]['rms'] = max(out[name]['rms'], math.sqrt(sums[c] / counts))
    return out
