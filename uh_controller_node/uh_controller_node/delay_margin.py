"""The delay margin of a team: the linearised team with a uniform link delay (docs/delay.md#delay-margin).

One axis of every UH's outer and inner loop of docs/control_law.md, linearised about hover (small
angles; the networks, the SPEMs and the fault observers left out, the nominal model cancelling the
plant exactly, no input limits), sampled as the controllers run: each UH's command computed at step
``k`` from its own state at ``k`` and its neighbours' states sent at ``k - D``, held over the step;
the filters updated exactly as the kernel updates them. The team is one linear map
``x(k+1) = A(D) x(k)`` whose state holds every UH's plant and filters and the last ``D`` positions
and velocities each sends; the team is stable at delay ``D`` when every eigenvalue of ``A(D)`` lies
inside the unit circle.

Two axes are modelled: a horizontal one (the acceleration through the tilt, behind the attitude
loop) and the vertical one (the acceleration through the collective, at once). The margin is the
smaller of the two. The reference is an input, not a state: it does not change stability, only the
degree ``d_i`` of a UH that hears it.

What it leaves out, and so what a measurement can show that it does not: saturation (an unstable
mode grows until the inputs sit at their limits, then stays bounded), the learning laws (Case II
differs from the proposed law only there, so the model gives them the same margin), jitter and loss
(a link with ``delay_steps + jitter_steps`` is at least as old as the model's ``D``).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import scipy.linalg

from uh_core.airframe import load_helicopter_params
from uh_topology.impairments import DEFAULT_COMPENSATION

from .gains import scenario_gains

__all__ = ['LoopModel', 'loop_model', 'team_matrix', 'ModeReport', 'DelayMargin', 'delay_margin',
           'MOST_STEPS', 'MODELLED', 'modelled', 'applied_compensation', 'margin_steps_for', 'scenario_margin',
           'scenario_link_age', 'WEIGHT_GRID',
           'covering_feedforward_weight', 'margin_notice', 'margin_lines', 'axis_models',
           'unstable_axis', 'MarginWatch']

#: The compensations the model tells apart. ``reference_motion`` adds to ``predict`` only terms of the
#: known trajectory, which close no loop, so the model gives it ``predict``'s margin (:func:`modelled`).
MODELLED = ('predict', 'none')
#: The delay scan stops here (steps): beyond it the margin is reported as none found (``None``).
MOST_STEPS = 50
#: A UH is named as carrying a mode when its share of the mode's position amplitude is at least this
#: fraction of the largest UH's (UHs that barely move in it are left out).
MODE_SHARE = 0.3


@dataclass(frozen=True)
class LoopModel:
    """The gains of one axis of the linearised loops (docs/control_law.md), SI units.

    ``k1``, ``kz2 = beta / (2 r_p)``, ``tau1``: outer loop; ``k3``, ``kz4 = beta / (2 r_w)``, ``tau2``,
    ``tauw``: inner loop (None on the vertical axis, which has no attitude loop); ``gravity`` m/s^2
    turns a tilt into an acceleration; ``feedforward_weight`` multiplies the neighbours' velocities
    in the feed-forward ``f``.
    """

    k1: float
    kz2: float
    tau1: float
    k3: float | None
    kz4: float | None
    tau2: float | None
    tauw: float | None
    gravity: float
    feedforward_weight: float = 1.0

    @property
    def horizontal(self) -> bool:
        """Whether the axis has the attitude loop between ``u_p`` and the acceleration."""
        return self.k3 is not None

    @property
    def size(self) -> int:
        """States per UH: position, velocity, alpha_f (and tilt, tilt rate, Theta_df, alpha_wf)."""
        return 7 if self.horizontal else 3


def loop_model(gains, gravity: float, horizontal: bool, feedforward_weight: float = 1.0) -> LoopModel:
    """Make the :class:`LoopModel` of one axis from ``ControllerGains`` (its case already applied)."""
    outer, inner = gains.outer, gains.inner
    kz2 = gains.beta / (2 * outer.r)
    if not horizontal:
        return LoopModel(outer.k, kz2, outer.tau_command, None, None, None, None, gravity, feedforward_weight)
    return LoopModel(outer.k, kz2, outer.tau_command, inner.k, gains.beta / (2 * inner.r), inner.tau_command,
                     inner.tau_rate, gravity, feedforward_weight)


def modelled(compensation: str) -> str:
    """Give the compensation of :data:`MODELLED` whose margin a scenario's ``delay_compensation`` has."""
    return 'predict' if compensation == 'reference_motion' else compensation


def applied_compensation(scenario, realtime: bool) -> str:
    """Give the compensation a scenario's controllers apply to the states they receive.

    Its ``delay_compensation`` with impairments; without them a realtime controller uses states as
    they arrive (``none``), and lockstep or in-process ones have no delay to compensate (the default).
    """
    if scenario.impairments is not None:
        return scenario.impairments.compensation
    return 'none' if realtime else DEFAULT_COMPENSATION


# position of each state in a UH's block
_P, _V, _AF, _TH, _OM, _TDF, _AWF = range(7)


def team_matrix(model: LoopModel, adjacency: np.ndarray, dt: float, delay: int, predict: bool) -> np.ndarray:
    """Return ``A(D)`` of the team on one axis: ``x(k+1) = A x(k)`` (see the module doc).

    ``adjacency`` is the scenario's (n+1, n+1) ``a_ij`` (row i: what UH i hears; column 0: the
    virtual leader); ``delay`` D steps on every link between UHs; ``predict``: the received position
    is ``p_j + v_j D dt`` (docs/delay.md#the-prediction). The state is, per UH, its ``size`` loop
    states, then ``D`` (position, velocity) pairs per UH: what it sent 1..D steps ago.
    """
    n, s = adjacency.shape[0] - 1, model.size
    loops = n * s
    size = loops + 2 * n * delay
    A = np.zeros((size, size))

    def own(i, state):
        return i * s + state

    def sent(j, age):
        """Columns of (p_j, v_j) as sent ``age`` steps ago (age 0: the current state)."""
        if age == 0:
            return own(j, _P), own(j, _V)
        base = loops + 2 * ((age - 1) * n + j)
        return base, base + 1

    plant_a, plant_b = _plant(model, dt)
    for i in range(n):
        row = adjacency[i + 1]
        degree = float(row.sum())
        # z1 = d p_i - sum a_ij p^_j, f = w sum a_ij v^_j (the offsets and the reference are inputs)
        z1, f = np.zeros(size), np.zeros(size)
        z1[own(i, _P)] = degree
        for j in np.nonzero(row[1:])[0]:
            cp, cv = sent(j, delay)
            z1[cp] -= row[j + 1]
            f[cv] += model.feedforward_weight * row[j + 1]
            if predict and delay:
                z1[cv] -= row[j + 1] * delay * dt
        alpha_v = (f - model.k1 * z1) / degree
        af = _unit(size, own(i, _AF))
        alpha_f_rate = (alpha_v - af) / model.tau1
        z2 = _unit(size, own(i, _V)) - af
        u_p = alpha_f_rate - degree * z1 - model.kz2 * z2
        A[own(i, _AF)] = af + (1 - math.exp(-dt / model.tau1)) * (alpha_v - af)
        if model.horizontal:
            # tilt command u_p / g; the inner loop of docs/control_law.md#inner-loop with G u_m cancelling
            theta_d = u_p / model.gravity
            tdf, awf = _unit(size, own(i, _TDF)), _unit(size, own(i, _AWF))
            tdf_rate = (theta_d - tdf) / model.tau2
            z3 = _unit(size, own(i, _TH)) - tdf
            alpha_w = -model.k3 * z3 + tdf_rate
            z4 = _unit(size, own(i, _OM)) - awf
            command = (alpha_w - awf) / model.tauw - z3 - model.kz4 * z4   # angular acceleration
            A[own(i, _TDF)] = tdf + (1 - math.exp(-dt / model.tau2)) * (theta_d - tdf)
            A[own(i, _AWF)] = awf + (1 - math.exp(-dt / model.tauw)) * (alpha_w - awf)
            plant = [own(i, x) for x in (_P, _V, _TH, _OM)]
        else:
            command = u_p                                                  # vertical acceleration
            plant = [own(i, _P), own(i, _V)]
        current = np.zeros((len(plant), size))
        current[np.arange(len(plant)), plant] = 1.0
        A[plant] = plant_a @ current + np.outer(plant_b, command)
    for j in range(n):                 # the shift register of what each UH sent
        for age in range(1, delay + 1):
            for new, old in zip(sent(j, age), sent(j, age - 1), strict=True):
                A[new, old] = 1.0
    return A


def _unit(size: int, index: int) -> np.ndarray:
    row = np.zeros(size)
    row[index] = 1.0
    return row


def _plant(model: LoopModel, dt: float):
    """Sample the plant with the command held over a step: ``(A_d, B_d)`` by the matrix exponential.

    Horizontal: ``p' = v, v' = g theta, theta' = omega, omega' = command``; vertical:
    ``p' = v, v' = command``.
    """
    if model.horizontal:
        a = np.zeros((4, 4))
        a[0, 1], a[1, 2], a[2, 3] = 1.0, model.gravity, 1.0
    else:
        a = np.zeros((2, 2))
        a[0, 1] = 1.0
    m = a.shape[0]
    block = np.zeros((m + 1, m + 1))
    block[:m, :m], block[m - 1, m] = a, 1.0      # the command drives the last state's derivative
    e = scipy.linalg.expm(block * dt)
    return e[:m, :m], e[:m, m]


@dataclass(frozen=True)
class ModeReport:
    """One mode of ``A(D)``: the eigenvalue of largest modulus.

    ``modulus`` (> 1: growing), ``frequency_hz`` (0 for a real mode), ``time_constant_s`` (the
    e-folding time of its growth or decay, ``dt / |ln |lambda||``), ``uhs`` the UHs carrying at least
    :data:`MODE_SHARE` of its largest position amplitude, ``axis`` (``'horizontal'``, ``'vertical'``).
    """

    modulus: float
    frequency_hz: float
    time_constant_s: float
    uhs: tuple
    axis: str


def dominant_mode(A: np.ndarray, dt: float, ids, size: int, axis: str) -> ModeReport:
    """Return the eigenvalue of ``A`` of largest modulus as a :class:`ModeReport`."""
    values, vectors = scipy.linalg.eig(A)
    k = int(np.argmax(np.abs(values)))
    value = values[k]
    positions = np.abs(vectors[[i * size + _P for i in range(len(ids))], k])
    share = positions / positions.max() if positions.max() > 0 else positions
    modulus = float(abs(value))
    tc = dt / abs(math.log(modulus)) if modulus not in (0.0, 1.0) else math.inf
    return ModeReport(modulus, float(abs(np.angle(value)) / dt / (2 * math.pi)), tc,
                      tuple(int(ids[i]) for i in np.nonzero(share >= MODE_SHARE)[0]), axis)


@dataclass(frozen=True)
class DelayMargin:
    """The delay margin of one team and case (docs/delay.md#delay-margin).

    ``margin_steps[c]``: the largest uniform delay D (steps) such that every delay 0..D is stable with
    compensation ``c`` (``'predict'``, ``'none'``); None when no delay up to ``most`` destabilises it.
    ``first_unstable[c]``: the first unstable delay (``margin + 1``; a margin of -1: unstable without
    delay), or None; ``onset_mode[c]``: the mode that goes unstable there (:class:`ModeReport`), or
    None. ``slowest_mode``: the slowest mode at zero delay (what limits settling).
    """

    dt: float
    most: int
    margin_steps: dict
    first_unstable: dict
    onset_mode: dict
    slowest_mode: ModeReport

    def margin_ms(self, compensation: str) -> float | None:
        """Give the margin in milliseconds (None when none was found)."""
        steps = self.margin_steps[compensation]
        return None if steps is None else steps * self.dt * 1000.0

    def as_json(self) -> dict:
        """Give the margin as one JSON object (what ``uh-analyze --json`` prints)."""
        def mode(m):
            return None if m is None else {'frequency_hz': m.frequency_hz, 'modulus': m.modulus,
                                           'time_constant_s': m.time_constant_s, 'uhs': list(m.uhs),
                                           'axis': m.axis}
        return {'dt_s': self.dt, 'most_steps': self.most, 'margin_steps': dict(self.margin_steps),
                'margin_ms': {c: self.margin_ms(c) for c in self.margin_steps},
                'first_unstable_steps': dict(self.first_unstable),
                'onset_mode': {c: mode(m) for c, m in self.onset_mode.items()},
                'slowest_mode_s': self.slowest_mode.time_constant_s, 'slowest_mode': mode(self.slowest_mode)}


def axis_models(gains, gravity: float, feedforward_weight: float = 1.0) -> dict:
    """Give the :class:`LoopModel` of each axis, ``{'horizontal': ..., 'vertical': ...}``."""
    return {axis: loop_model(gains, gravity, axis == 'horizontal', feedforward_weight)
            for axis in ('horizontal', 'vertical')}


def unstable_axis(models: dict, adjacency: np.ndarray, dt: float, delay: int, predict: bool):
    """Give ``(spectral radius, axis, A, states per UH)`` of the most unstable axis at ``delay``, or None if stable."""
    worst = None
    for axis, model in models.items():
        A = team_matrix(model, adjacency, dt, delay, predict)
        rho = float(np.max(np.abs(scipy.linalg.eigvals(A))))
        if rho >= 1.0 and (worst is None or rho > worst[0]):
            worst = (rho, axis, A, model.size)
    return worst


def delay_margin(adjacency: np.ndarray, ids, gains, gravity: float, dt: float, feedforward_weight: float = 1.0,
                 most: int = MOST_STEPS, compensations=MODELLED) -> DelayMargin:
    """Scan the uniform delay 0..``most`` steps on both axes; return the :class:`DelayMargin`.

    ``gains``: ``ControllerGains`` of the case; ``adjacency`` (n+1, n+1) with the reference column.
    """
    models = axis_models(gains, gravity, feedforward_weight)
    margins, first, onset = {}, {}, {}
    for compensation in compensations:
        margins[compensation], first[compensation], onset[compensation] = None, None, None
        for delay in range(most + 1):
            worst = unstable_axis(models, adjacency, dt, delay, compensation == 'predict')
            if worst is not None:
                first[compensation] = delay
                margins[compensation] = delay - 1 if delay > 0 else -1
                onset[compensation] = dominant_mode(worst[2], dt, ids, worst[3], worst[1])
                break
    slow = [dominant_mode(team_matrix(model, adjacency, dt, 0, False), dt, ids, model.size, axis)
            for axis, model in models.items()]
    slowest = max(slow, key=lambda m: m.time_constant_s if m.modulus < 1 else -1.0)
    return DelayMargin(dt, most, margins, first, onset, slowest)


# -- a scenario's margin ---------------------------------------

def scenario_margin(scenario, case: str = 'proposed', most: int = MOST_STEPS, feedforward_weight=None,
                    compensations=MODELLED) -> DelayMargin:
    """Give the :class:`DelayMargin` of a loaded scenario and case (its gains, graph, airframe and ``dt``).

    ``feedforward_weight`` replaces the gains file's (None: the file's); ``compensations``: those scanned.
    """
    gains = scenario_gains(scenario, case)
    weight = gains.feedforward_weight if feedforward_weight is None else feedforward_weight
    return delay_margin(np.asarray(scenario.adjacency), scenario.ids, gains,
                        load_helicopter_params(scenario.helicopter).gravity, scenario.dt, weight, most, compensations)


def margin_steps_for(scenario, case: str, compensation: str, most: int, feedforward_weight=None) -> int | None:
    """Give the margin (steps) of ``compensation`` (a ``delay_compensation``) scanned to ``most``; None: none found."""
    c = modelled(compensation)
    return scenario_margin(scenario, case, most, feedforward_weight, compensations=(c,)).margin_steps[c]


def scenario_link_age(scenario) -> int:
    """Give the oldest a neighbour state gets on the scenario's links, in steps: the largest ``delay + jitter``."""
    imp = scenario.impairments
    if imp is None:
        return 0
    return max((imp.delays[link] + imp.jitters[link] for link in imp.delays), default=0)


#: The feed-forward weights :func:`covering_feedforward_weight` tries, largest first.
WEIGHT_GRID = tuple(round(1.0 - 0.05 * k, 2) for k in range(20))


def covering_feedforward_weight(scenario, case: str, steps: int, compensation: str = 'predict') -> float | None:
    """Give the largest weight of :data:`WEIGHT_GRID` whose margin (``compensation``) is at least ``steps``, or None.

    What the remedy ``feedforward_weight`` should be for a team whose links are ``steps`` old.
    """
    for weight in WEIGHT_GRID:
        if margin_steps_for(scenario, case, compensation, steps, weight) is None:
            return weight
    return None


def margin_notice(scenario, case: str = 'proposed') -> tuple:
    """Give ``(info, warning)``: what a run says at start about its links and the delay margin.

    Both None for a scenario whose links are not delayed (no ``delay_steps`` or ``jitter_steps``).
    Otherwise ``info`` gives the margin of the scenario's compensation and the oldest state its links
    deliver; ``warning`` (or None) says the links are beyond it. Scans only as far as it must.
    """
    age = scenario_link_age(scenario)
    if age == 0:
        return None, None
    compensation = applied_compensation(scenario, realtime=False)
    steps = margin_steps_for(scenario, case, compensation, age + 1)
    dt_ms = scenario.dt * 1000.0
    said = f'at least {age + 1} steps' if steps is None else f'{steps} steps ({steps * dt_ms:g} ms)'
    info = (f'delay margin ({compensation}): {said}; the links deliver states up to {age} steps '
            f'({age * dt_ms:g} ms) old (uh-analyze; docs/delay.md#delay-margin)')
    if steps is None or age <= steps:
        return info, None
    return info, (f'the links deliver states up to {age} steps old, beyond the delay margin of {steps} steps '
                  f'({compensation}): expect the team to oscillate (docs/delay.md#remedies)')


def margin_lines(scenario, case: str = 'proposed') -> list:
    """Give the lines :func:`margin_notice` makes, the warning prefixed ``warning:`` (none without delay)."""
    info, warning = margin_notice(scenario, case)
    return [line for line in (info, warning and f'warning: {warning}') if line]


class MarginWatch:
    """The delay margin a realtime controller checks its neighbours' measured ages against, found lazily.

    The margin of the compensation the controller applies: the scenario's ``delay_compensation`` with
    impairments; ``none`` without them (a realtime controller then uses states as they arrive). The
    delays are scanned only as far as the ages reported so far reach (a few steps on a healthy
    network), so a node pays nothing at start and little at a report.
    """

    def __init__(self, scenario, case: str):
        gains = scenario_gains(scenario, case)
        self.models = axis_models(gains, load_helicopter_params(scenario.helicopter).gravity, gains.feedforward_weight)
        self.adjacency, self.dt = np.asarray(scenario.adjacency), scenario.dt
        self.predict = modelled(applied_compensation(scenario, realtime=True)) == 'predict'
        self.stable_to = -1            # every delay 0..stable_to is stable
        self.first_unstable = None

    def margin_s(self, age_s: float) -> float:
        """Give the margin (s) when ``age_s`` is beyond it, else NaN (the team is stable up to that age)."""
        steps = int(math.ceil(age_s / self.dt - 1e-9)) if math.isfinite(age_s) else -1
        while self.first_unstable is None and self.stable_to < steps:
            if unstable_axis(self.models, self.adjacency, self.dt, self.stable_to + 1, self.predict) is None:
                self.stable_to += 1
            else:
                self.first_unstable = self.stable_to + 1
        if self.first_unstable is not None and steps >= self.first_unstable:
            return max(self.first_unstable - 1, 0) * self.dt
        return math.nan
