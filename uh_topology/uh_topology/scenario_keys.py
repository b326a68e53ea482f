"""The keys of a scenario file, declared once: name, required or default, unit, allowed values, meaning.

Each :class:`ScenarioKey` says what a key of a scenario mapping is. The tables are read where the
keys are used, at the time they are used:

* the scenario loader (:mod:`uh_topology.scenario`, :mod:`uh_topology.impairments`) takes from
  them which keys a mapping may hold and which it must, the default of an absent key and, for a
  scalar key, the type and range it checks (:func:`read_key`);
* the campaign spec (:mod:`uh_campaign.spec`) takes the impairment keys a campaign may copy into
  its scenarios, and those it draws itself (``seed``);
* docs/scenario.md's tables of the top-level and the impairment keys are
  :func:`markdown_table` of :data:`SCENARIO_KEYS` and :data:`IMPAIRMENT_KEYS` (a test compares
  them).

A new key is one more entry here (and, for what it does, its reader and its effect).
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Any

__all__ = ['ScenarioKey', 'SCENARIO_KEYS', 'IMPAIRMENT_KEYS', 'NOISE_KEYS', 'SAFETY_KEYS', 'SEPARATION_MARGIN',
           'EVENT_KINDS', 'EVENT_KEYS', 'ON_LOSS', 'ON_UNABLE', 'RESILIENCE_KEYS', 'STALE_TIMEOUT',
           'key_named', 'key_names',
           'read_key', 'default_cell', 'markdown_table']

#: The kinds of scalar key :func:`read_key` reads.
KINDS = ('integer', 'number', 'string', 'boolean')


@dataclass(frozen=True)
class ScenarioKey:
    """One key of a scenario mapping.

    Attributes
    ----------
    name : str
        The key.
    meaning : str
        What it means and what is allowed, as docs/scenario.md's table says it (Markdown).
    required : bool
        The mapping must hold it.
    default : object
        The value of an absent key (None: no value, the part it describes is absent).
    default_text : str or None
        The default as the table writes it, when not the default itself (e.g. ``all 0``).
    unit : str
        The unit (the table's; a number's errors name it too).
    kind : str or None
        ``integer``, ``number``, ``string`` or ``boolean`` for a scalar that :func:`read_key` reads; None for
        a mapping or list, which has its own reader.
    lo, hi, lo_open, hi_open
        The allowed range of an integer (``lo``) or a number.
    choices : tuple
        The allowed values of a string (empty: any string).
    what : str
        How an integer's type error names what was expected (default ``an integer``).
    null_is_default : bool
        ``null`` is read as the default (otherwise it is a wrong type).
    per_link : bool
        Impairments: also a per-link override under ``links``.
    drawn_by_campaign : bool
        Impairments: a campaign draws it for every draw; its spec must not give it.
    """

    name: str
    meaning: str
    required: bool = False
    default: Any = None
    default_text: str | None = None
    unit: str = ''
    kind: str | None = None
    lo: Any = None
    hi: Any = None
    lo_open: bool = False
    hi_open: bool = False
    choices: tuple = ()
    what: str = ''
    null_is_default: bool = False
    per_link: bool = False
    drawn_by_campaign: bool = False

    def __post_init__(self):
        """Refuse a kind :func:`read_key` does not know."""
        if self.kind is not None and self.kind not in KINDS:
            raise ValueError(f'{self.name}: kind {self.kind!r}; allowed: {", ".join(KINDS)} or None')


#: The top-level keys of a scenario, in the order of docs/scenario.md (docs/scenario.md#top-level-keys).
SCENARIO_KEYS = (
    ScenarioKey('name', 'string', required=True, kind='string'),
    ScenarioKey('description', 'string', default='', kind='string'),
    ScenarioKey('dt', 'control period, > 0', required=True, unit='s', kind='number', lo=0.0, lo_open=True),
    ScenarioKey('substeps', 'RK4 substeps per control period, integer >= 1 ([model.md](model.md#integration))',
                default=5, kind='integer', lo=1),
    ScenarioKey('duration', "run length, >= `dt` and a whole number of `dt` (K = duration / dt steps); the run "
                "scripts' `--duration` overrides it", required=True, unit='s', kind='number'),
    ScenarioKey('settle_time', 'start of the after-settle metrics, in [0, duration) '
                '([metrics.md](metrics.md#after-settle-window))', default=20.0, unit='s', kind='number', lo=0.0,
                hi_open=True),
    ScenarioKey('model_mismatch', "factor on the controller's nominal `D_v` and `c_Q`, > 0; 1 = exact "
                '([model.md](model.md#what-the-controller-knows))', default=0.9, kind='number', lo=0.0,
                lo_open=True),
    ScenarioKey('helicopter', 'airframe parameter file: a bare name selects a bundled file of '
                '`uh_core/uh_core/config` (`helicopter` = `helicopter.yaml`), anything with a suffix or a '
                'directory is a path ([model.md](model.md#parameters))', default='helicopter', kind='string'),
    ScenarioKey('gains', 'controller gains: a YAML file (path) or an inline mapping ([below](#gains-file)); a '
                'scenario without gains loads, but no controller can be built from it'),
    ScenarioKey('uhs', 'non-empty list of UHs ([below](#uhs))', required=True),
    ScenarioKey('edges', 'list of edges, may be empty or `null` ([below](#edges-and-reference_links))',
                required=True),
    ScenarioKey('reference_links', 'list of virtual-leader links ([below](#edges-and-reference_links))',
                required=True),
    ScenarioKey('reference', 'virtual-leader trajectory ([below](#reference))', required=True),
    ScenarioKey('disturbance', 'force disturbance on every UH ([below](#disturbance))'),
    ScenarioKey('faults', 'actuator faults ([below](#faults))'),
    ScenarioKey('safety', 'the collision-avoidance layer outside the law: keeps every pair of UHs at least '
                '`min_separation` apart ([below](#safety); [safety.md](safety.md))'),
    ScenarioKey('impairments', 'what the controllers receive: per-link delay and jitter in steps, loss, measurement '
                'noise, dropouts, and whether a controller predicts delayed states; in process, lockstep and '
                'realtime ([below](#impairments); in real time: [runtime.md](runtime.md#impairments-in-real-time))'),
    ScenarioKey('events', 'what happens to the team during the run: `{time, uh, kind: lost}`, a helicopter lost; '
                '`{time, uh, kind: stuck, channel}`, an actuator stuck ([below](#events); '
                '[resilience.md](resilience.md))'),
    ScenarioKey('resilience', 'how the team answers a loss: re-form or hold, standby edges, the timeout that declares '
                'a UH lost ([below](#resilience); [resilience.md](resilience.md))'),
)

#: The kinds of event (docs/resilience.md): ``lost``, the helicopter stops publishing and hovers where it is;
#: ``stuck``, one actuator freezes where it is.
EVENT_KINDS = ('lost', 'stuck')

#: The keys of one entry of ``events`` (docs/scenario.md#events).
EVENT_KEYS = (
    ScenarioKey('time', 'when it happens, in (0, `duration`)', required=True, unit='s', kind='number'),
    ScenarioKey('uh', 'the UH it happens to; one event per UH', required=True, kind='integer'),
    ScenarioKey('kind', '`lost`: from `time` on the UH publishes nothing (as if its processes died or its radio '
                'failed) and hovers where it is, an obstacle to the others; `stuck`: from `time` on the actuator '
                'of `channel` stays where it is, whatever is commanded (its own controller may find it and leave: '
                '`resilience.on_unable`)', required=True, kind='string', choices=EVENT_KINDS),
    ScenarioKey('channel', 'the stuck actuator (`stuck` only, and required there): `collective`, `tail_rotor`, '
                '`lateral`, `longitudinal` (or 0-3, or `theta_col`, `theta_tr`, `delta_lat`, `delta_lon`)'),
)

#: A neighbour's state this old (s) is stale: the controller leaves it out of the law (docs/reliability.md); the
#: default of the nodes' ``stale_timeout`` and the floor of ``resilience.lost_timeout``.
STALE_TIMEOUT = 0.25

#: The answers of a team to a loss (docs/resilience.md).
ON_LOSS = ('reform', 'hold')

#: What a UH does when its fault isolator finds a fault it cannot compensate (docs/resilience.md#leaving-the-team).
ON_UNABLE = ('leave', 'stay')

#: The keys of ``resilience`` (docs/scenario.md#resilience, docs/resilience.md).
RESILIENCE_KEYS = (
    ScenarioKey('on_loss', '`reform`: every UH computes the same new team from the scenario and the agreed lost set '
                '(promotion, repaired graph) and flies it; `hold`: a UH drops the lost neighbour and holds its '
                'position when it has no path from the virtual leader left, as without this layer',
                default='reform', kind='string', choices=ON_LOSS),
    ScenarioKey('standby_edges', '`bypass`: the edges the repair of any single loss needs, derived from the graph; '
                '`none`; or a list `{uh, hears}` (`hears: 0` is the virtual leader). A UH subscribes to its standby '
                'neighbours from the start and uses them only in a re-formed team', default='bypass'),
    ScenarioKey('lost_timeout', 'a neighbour whose newest state is this old is declared lost: > the stale timeout '
                f'({STALE_TIMEOUT:g} s) and > the largest age a link gives (`(delay_steps + jitter_steps) dt`)',
                default=0.5, unit='s', kind='number', lo=STALE_TIMEOUT, lo_open=True),
    ScenarioKey('on_unable', '`leave`: a UH whose fault isolator finds an actuator with effectiveness below '
                '`unable_rho` declares itself lost, the others re-form without it (as `on_loss` says) and it climbs '
                '`leave_climb` and holds there; `stay`: it flies on with the fault, as without this layer',
                default='leave', kind='string', choices=ON_UNABLE),
    ScenarioKey('unable_rho', 'the effectiveness floor: a channel isolated with `rho` fit plus its worst-case error '
                'bound below this is one the law cannot compensate', default=0.5, kind='number', lo=0.0, hi=1.0,
                lo_open=True, hi_open=True),
    ScenarioKey('unable_spread', 'and the command has moved: its standard deviation over the fit is above this (a '
                'law that cancels a sinusoidal bias holds the actual input nearly constant too, but moves its '
                'command only as far as the bias: at most 0.010 rad for the campaigns\' faults)', default=0.015,
                unit='rad', kind='number', lo=0.0),
    ScenarioKey('leave_climb', 'how far a leaving UH climbs above the point where it declared itself, to hold there '
                'clear of the team', default=5.0, unit='m', kind='number', lo=0.0),
)

#: The keys of ``impairments.noise``: the standard deviation of the noise on each part of a received state.
NOISE_KEYS = tuple(
    ScenarioKey(name, f'standard deviation of the noise on the {name} of every received state, >= 0', default=0.0,
                unit=unit, kind='number', lo=0.0)
    for name, unit in (('position', 'm'), ('velocity', 'm/s'), ('attitude', 'rad'), ('rate', 'rad/s')))

_STEPS = dict(default=0, unit='control steps', kind='integer', lo=0, what='a whole number of steps >= 0',
              null_is_default=True, per_link=True)
_LINK_KEYS = (
    ScenarioKey('delay_steps', 'integer >= 0: every link delivers a state this many steps after it was sent',
                **_STEPS),
    ScenarioKey('jitter_steps', 'integer >= 0: each state of each link is delayed by a further seeded draw in '
                '`0..jitter_steps`, so states may arrive out of order; the controller uses the newest *sent* step '
                'that has arrived, never an older one', **_STEPS),
    ScenarioKey('loss', 'probability in [0, 1) that a link loses a state', default=0.0, kind='number', lo=0.0,
                hi=1.0, hi_open=True, null_is_default=True, per_link=True),
)

#: The keys of ``impairments`` (docs/scenario.md#impairments, docs/campaigns.md#impairments).
IMPAIRMENT_KEYS = (
    ScenarioKey('seed', 'integer >= 0: seeds the loss and jitter draws and the noise', default=0, kind='integer',
                lo=0, what='an integer seed >= 0', drawn_by_campaign=True),
    *_LINK_KEYS,
    ScenarioKey('links', 'per-link overrides `{uh, hears, ' + ', '.join(k.name for k in _LINK_KEYS) + '}`; '
                '`uh` must hear `hears` (an edge of `edges`)'),
    ScenarioKey('noise', 'standard deviations ' + ', '.join(f'`{k.name}`' for k in NOISE_KEYS) + ' >= 0 of the '
                'noise on every received state', default_text='all 0', unit=', '.join(k.unit for k in NOISE_KEYS)),
    ScenarioKey('dropouts', "`{uh, time}`: from `time` on no other UH receives the UH's state; one per UH, `time` "
                'in [0, duration]', unit='s'),
    ScenarioKey('delay_compensation', "`none`: a controller uses each neighbour's state as received; `predict`: it "
                'predicts it from the step it was sent at to the current step ([delay.md](delay.md)); '
                "`reference_motion`: predicts it and adds the virtual leader's own motion over the age, a "
                'departure ([delay.md](delay.md#remedies))',
                default='predict', kind='string', choices=('none', 'predict', 'reference_motion')),
)


#: The margin the default ``min_separation`` adds to two rotor radii (docs/safety.md#the-separation), m.
SEPARATION_MARGIN = 0.15

#: The keys of ``safety`` (docs/scenario.md#safety, docs/safety.md).
SAFETY_KEYS = (
    ScenarioKey('enabled', 'the filter runs: `true` (the default: rotors never touch) or `false` (the paper\'s law '
                "alone, bit for bit); the run scripts' `--safety on` and `--safety off` override it", default=True,
                kind='boolean'),
    ScenarioKey('min_separation', 'smallest hub-to-hub distance the filter keeps between two UHs (3-D), '
                '>= 2 `rotor_radius` of the airframe', default=None,
                default_text=f'2 `rotor_radius` + {SEPARATION_MARGIN:g}', unit='m', kind='number', lo=0.0,
                lo_open=True, null_is_default=True),
    ScenarioKey('sensing_radius', "a UH's proximity input reports the UHs within this distance, > `min_separation`",
                default=12.0, unit='m', kind='number', lo=0.0, lo_open=True),
    ScenarioKey('barrier_gain', 'gamma of the barrier condition `dh/dt >= -gamma h`, > 0', default=2.0, unit='1/s',
                kind='number', lo=0.0, lo_open=True),
    ScenarioKey('brake_accel', 'deceleration each UH of a pair is assumed to give, > 0 (at most what the tilt '
                'limit allows)', default=2.0, unit='m/s^2', kind='number', lo=0.0, lo_open=True),
    ScenarioKey('slack_weight', "weight of the squared slack against the squared change of `u_p`, > 0",
                default=1.0e4, unit='-', kind='number', lo=0.0, lo_open=True),
    ScenarioKey('sidestep_accel', 'the head-on rule: a UH pushed straight at another steps right by this, >= 0',
                default=0.5, unit='m/s^2', kind='number', lo=0.0),
    # what degrades the proximity input, as the links' impairments degrade the states (docs/safety.md)
    ScenarioKey('proximity_delay_steps', 'integer >= 0: the proximity input arrives this many steps late (the '
                'filter predicts the positions it reports to the current step from their velocities)', default=0,
                unit='control steps', kind='integer', lo=0, what='a whole number of steps >= 0'),
    ScenarioKey('proximity_loss', "probability in [0, 1) that a step's proximity input is lost (the filter keeps "
                'the newest it has, predicted)', default=0.0, kind='number', lo=0.0, hi=1.0, hi_open=True),
    ScenarioKey('proximity_noise_position', 'standard deviation of the noise on each reported position, >= 0',
                default=0.0, unit='m', kind='number', lo=0.0),
    ScenarioKey('proximity_noise_velocity', 'standard deviation of the noise on each reported velocity, >= 0',
                default=0.0, unit='m/s', kind='number', lo=0.0),
    ScenarioKey('proximity_seed', 'integer >= 0: seeds the losses and the noise of the proximity input', default=0,
                kind='integer', lo=0, what='an integer seed >= 0'),
)


def key_named(keys, name: str) -> ScenarioKey:
    """Return the key ``name`` of the table ``keys`` (KeyError if it has none)."""
    for key in keys:
        if key.name == name:
            return key
    raise KeyError(name)


def key_names(keys, required: bool | None = None) -> tuple:
    """Return the names of ``keys`` in their order: all, or only the required (True) or optional (False) ones."""
    return tuple(k.name for k in keys if required is None or k.required == required)


def read_key(ctx, key: ScenarioKey, raw: dict, path: tuple = (), **bounds):
    """Read the scalar ``key`` of the mapping ``raw`` at key path ``path`` as declared.

    ``ctx`` is the file's :class:`~uh_topology.schema.ConfigContext`; an absent key gives its default.
    ``bounds`` (``lo``, ``hi``, ``lo_open``, ``hi_open``) replace the declared range where it
    depends on other keys (a duration of at least ``dt``).
    """
    value = raw.get(key.name, key.default)
    if value is None and key.null_is_default:
        value = key.default
    where = path + (key.name,)
    lo = bounds.get('lo', key.lo)
    if key.kind == 'integer':
        return ctx.integer(value, where, lo=lo, what=key.what or 'an integer')
    if key.kind == 'number':
        return ctx.number(value, where, lo=lo, hi=bounds.get('hi', key.hi),
                          lo_open=bounds.get('lo_open', key.lo_open), hi_open=bounds.get('hi_open', key.hi_open),
                          unit=key.unit)
    if key.kind == 'string':
        return ctx.string(value, where, choices=key.choices or None)
    if key.kind == 'boolean':
        return ctx.boolean(value, where)
    raise ValueError(f'{key.name} is not a scalar key; it has its own reader')


def default_cell(key: ScenarioKey) -> str:
    """Write the default of ``key`` as docs/scenario.md's tables do (empty for a required key)."""
    if key.required:
        return ''
    if key.default_text is not None:
        return key.default_text
    if key.default is None:
        return 'none'
    if isinstance(key.default, bool):
        return f'`{str(key.default).lower()}`'
    if isinstance(key.default, str):
        return f'`{key.default}`' if key.default else "`''`"
    if isinstance(key.default, float):
        return f'{key.default:g}'
    return str(key.default)


def markdown_table(keys, required_column: bool = False) -> str:
    """Write the table of ``keys`` as docs/scenario.md has it: key, (required,) default, unit, meaning and allowed."""
    head = ['key', *(['required'] if required_column else []), 'default', 'unit', 'meaning, allowed values']
    rows = ['| ' + ' | '.join(head) + ' |', '|' + '---|' * len(head)]
    for key in keys:
        cells = [f'`{key.name}`', *([('yes' if key.required else 'no')] if required_column else []),
                 default_cell(key), key.unit, key.meaning]
        rows.append('|' + '|'.join(f' {cell} ' if cell else ' ' for cell in cells) + '|')
    return '\n'.join(rows) + '\n'
