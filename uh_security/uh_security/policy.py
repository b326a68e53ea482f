"""The access-control policy of a team, generated from its scenario: who may publish and read what.

The pure part of secure mode (docs/security.md#how-the-policy-follows-the-graph): no file is written and
no DDS is touched here. One identity (an *enclave*, sros2's word) per node of a run, named by the node's
fully qualified name (``/uh3/controller``), plus two for people: ``/tools/inspect`` (read-only, for
``uh`` and ``ros2`` listings and echoes) and ``/tools/operator`` (an operator who may also publish
every ``/uhN/fault`` and set parameters, e.g. gains at run time: deliberate acts). The nodes come from the
run's node table (:func:`uh_bringup.team_nodes.node_specs`),
the topics from the registry (:mod:`uh_wire.topics`), and the edges from the scenario's graph
(``Scenario.receivable_edges``: a controller reads exactly the states its node subscribes to):

* UH i's controller reads its own state, the states of the UHs it hears (a_ij > 0, and its standby
  neighbours when the scenario answers losses), ``/reference`` only with a_i0 > 0 and its own
  ``proximity`` with the safety filter on; it publishes ``/uhi/command``, ``/uhi/status``, its
  ``received`` in an impaired run and ``/diagnostics``;
* UH i's simulator publishes ``/uhi/state``, ``/uhi/fault_truth``, ``/uhi/odom``, ``/tf`` and
  ``/diagnostics``; it reads ``/uhi/command``, ``/uhi/fault`` and ``/clock``;
* the recorder and the live view only read (the recorder publishes its progress for the clock);
* every node also has what any ROS 2 node has: ``/rosout``, ``/parameter_events``, its six parameter
  services and ``~/get_type_description`` (:data:`NODE_SERVICES`), and ``ros_discovery_info`` (rmw's
  graph topic, which sros2 grants every enclave).

:func:`team_grants` gives each identity's :class:`Grant` (ROS names; :meth:`Grant.dds_publish` and
:meth:`Grant.dds_subscribe` the DDS topic names as the runtime maps them, ``rt/``, ``rq/``, ``rr/``);
:func:`policy_xml` the ROS 2 access-control policy ("ROS 2 Access Control Policies", version 0.2.0) a
person reads, :func:`permissions_xml` and :func:`governance_xml` the DDS Security documents the keystore
signs. Topic names may hold fnmatch wildcards, as DDS Security's permissions do.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from xml.etree import ElementTree as ET

from uh_bringup.run_secure import INSPECT_ENCLAVE, OPERATOR_ENCLAVE, SECURE_MAX_DOMAIN_ID
from uh_bringup.run_setup import run_node_names
from uh_bringup.team_nodes import node_specs
from uh_runtime.names import REPLY_PREFIX, REQUEST_PREFIX, ROS_TOPIC_PREFIX
from uh_wire import topics

__all__ = ['Grant', 'DomainRange', 'SECURE_MAX_DOMAIN_ID', 'TOOL_ENCLAVES', 'INSPECT', 'OPERATOR',
           'DISCOVERY_TOPIC', 'PARAMETER_SERVICES', 'READ_ONLY_PARAMETER_SERVICES', 'NODE_SERVICES', 'NODE_TOPICS',
           'POLICY_VERSION',
           'team_grants', 'node_grant', 'grant_of', 'policy_xml', 'permissions_xml', 'governance_xml', 'xml_text']

#: The graph topic of rmw (``rmw_dds_common``): every enclave publishes and reads it, as sros2 grants it.
DISCOVERY_TOPIC = 'ros_discovery_info'
#: The services every node of the runtime serves under its own name (``rclpy``'s parameter services).
PARAMETER_SERVICES = ('describe_parameters', 'get_parameters', 'get_parameter_types', 'list_parameters',
                      'set_parameters', 'set_parameters_atomically')
#: The parameter services a read-only identity may call (listing and reading, not setting).
READ_ONLY_PARAMETER_SERVICES = ('describe_parameters', 'get_parameters', 'get_parameter_types', 'list_parameters')
#: The services every ROS 2 Jazzy node serves: its parameters and ``~/get_type_description``, which rclpy and
#: rclcpp start by default (the ``ros2`` command line's own node too: without it, rmw_cyclonedds refuses to create
#: that node, measured on a Jazzy built from source). The runtime serves the parameter services only.
NODE_SERVICES = PARAMETER_SERVICES + ('get_type_description',)
#: What the runtime publishes for any node (``uh_runtime.dds.node``; rcl does the same).
NODE_TOPICS = ('/rosout', '/parameter_events')
#: The identities of people's tools, besides the nodes of a run: read-only, and the operator.
INSPECT, OPERATOR = INSPECT_ENCLAVE, OPERATOR_ENCLAVE
TOOL_ENCLAVES = (INSPECT, OPERATOR)
#: ``version`` of the ROS 2 access-control policy format written by :func:`policy_xml`.
POLICY_VERSION = '0.2.0'
#: Name patterns of the node a ROS 2 command-line tool makes (``ros2 topic echo``, its daemon).
_ROS2CLI_NODES = '/_ros2cli_*'


@dataclass(frozen=True)
class DomainRange:
    """The DDS domains a keystore's documents are valid on, ``lo..hi`` inclusive (default: all a secure run may use)."""

    lo: int = 0
    hi: int = SECURE_MAX_DOMAIN_ID

    def __post_init__(self):
        if not 0 <= self.lo <= self.hi <= SECURE_MAX_DOMAIN_ID:
            raise ValueError(f'domain range {self.lo}..{self.hi} is not within 0..{SECURE_MAX_DOMAIN_ID}')


@dataclass(frozen=True)
class Grant:
    """What one identity may do, in ROS names (sorted tuples; a name may be an fnmatch pattern).

    Attributes
    ----------
    enclave : str
        The identity's enclave path, also its certificate's common name (``/uh3/controller``).
    kind : str
        The node kind of :data:`uh_bringup.team_nodes.NODES`, or ``'tool'``.
    publish, subscribe : tuple of str
        ROS topics it may write and read.
    reply, request : tuple of str
        ROS services it may serve and call.
    """

    enclave: str
    kind: str
    publish: tuple = ()
    subscribe: tuple = ()
    reply: tuple = ()
    request: tuple = ()

    def dds_publish(self) -> tuple:
        """Return the DDS topics it may write: ``rt<topic>``, replies of what it serves, requests of what it calls."""
        return tuple(sorted({DISCOVERY_TOPIC, *(ROS_TOPIC_PREFIX + t for t in self.publish),
                             *(f'{REPLY_PREFIX}{s}Reply' for s in self.reply),
                             *(f'{REQUEST_PREFIX}{s}Request' for s in self.request)}))

    def dds_subscribe(self) -> tuple:
        """Return the DDS topics it may read: ``rt<topic>``, requests of what it serves, replies of what it calls."""
        return tuple(sorted({DISCOVERY_TOPIC, *(ROS_TOPIC_PREFIX + t for t in self.subscribe),
                             *(f'{REQUEST_PREFIX}{s}Request' for s in self.reply),
                             *(f'{REPLY_PREFIX}{s}Reply' for s in self.request)}))


@dataclass
class _Rights:
    """The growing allow lists of one identity (see :class:`Grant`)."""

    publish: set = field(default_factory=set)
    subscribe: set = field(default_factory=set)
    reply: set = field(default_factory=set)
    request: set = field(default_factory=set)

    def grant(self, enclave: str, kind: str) -> Grant:
        """Return the frozen :class:`Grant` of these rights."""
        return Grant(enclave, kind, *(tuple(sorted(getattr(self, n))) for n in ('publish', 'subscribe', 'reply',
                                                                               'request')))


def _node_basics(fqn: str) -> _Rights:
    """Return what any node ``fqn`` has: ``/rosout``, ``/parameter_events``, its services (:data:`NODE_SERVICES`)."""
    return _Rights(publish=set(NODE_TOPICS), reply={f'{fqn}/{s}' for s in NODE_SERVICES})


def _team_topic_names(scenario) -> dict:
    """``{TopicSpec: [full names]}`` of every topic a run of ``scenario`` can have (views and markers included)."""
    names = {}
    for name, spec in topics.run_topics(scenario.ids, **topics.scenario_flags(scenario)):
        names.setdefault(spec, []).append(name)
    return names


def node_grant(kind: str, fqn: str, scenario, uh_id: int | None = None) -> Grant:
    """Return the :class:`Grant` of the node ``fqn`` of ``kind`` (UH ``uh_id`` for a per-UH kind) in ``scenario``.

    The rules of the module docstring; ``ValueError`` for a kind this module has no rule for.
    """
    rights, t = _node_basics(fqn), topics
    flags = topics.scenario_flags(scenario)
    own = (lambda spec: t.uh_topic(uh_id, spec)) if uh_id is not None else None
    every = _team_topic_names(scenario)
    if kind == 'controller':
        edges = scenario.receivable_edges()
        heard = sorted(j for (i, j) in edges if i == uh_id and j != 0)
        rights.subscribe |= {own(t.STATE), *(t.uh_topic(j, t.STATE) for j in heard)}
        rights.subscribe |= {t.REFERENCE.name} if (uh_id, 0) in edges else set()
        rights.subscribe |= {own(t.PROXIMITY)} if flags['safety'] else set()
        rights.publish |= {own(t.COMMAND), own(t.STATUS), t.DIAGNOSTICS.name}
        rights.publish |= {own(t.RECEIVED)} if flags['impaired'] else set()
    elif kind == 'sim':
        rights.publish |= {own(t.STATE), own(t.FAULT_TRUTH), own(t.ODOM), t.TF.name, t.DIAGNOSTICS.name}
        rights.subscribe |= {own(t.COMMAND), own(t.FAULT), t.CLOCK.name}
    elif kind == 'virtual_leader':
        rights.publish |= {t.REFERENCE.name, t.TF.name}
        rights.subscribe |= {t.CLOCK.name}
    elif kind == 'sensing':
        rights.publish |= set(every.get(t.PROXIMITY, ()))
        rights.subscribe |= set(every[t.STATE])
    elif kind == 'clock':
        rights.publish |= {t.CLOCK.name}
        rights.subscribe |= {*every[t.COMMAND], t.RECORDER_PROGRESS.name}
    elif kind == 'visualization':
        rights.publish |= {t.MARKERS.name}
        rights.subscribe |= {*every[t.STATE], t.REFERENCE.name}
    elif kind in ('recorder', 'live_view'):
        rights.subscribe |= {name for names in every.values() for name in names} | set(NODE_TOPICS)
        rights.publish |= {t.RECORDER_PROGRESS.name} if kind == 'recorder' else set()
    else:
        raise ValueError(f'no access rule for a node of kind {kind!r}')
    return rights.grant(fqn, kind)


def _tool_grant(enclave: str, scenario) -> Grant:
    """Return the grant of a person's tool: read everything, read parameters; the operator also injects and sets them.

    Both may start a ROS 2 command-line node of their own (``/_ros2cli_*``: its ``/rosout``,
    ``/parameter_events`` and :data:`NODE_SERVICES`); ``uh-inject-fault``'s node serves no parameters.
    """
    rights = _Rights(publish=set(NODE_TOPICS), subscribe={'/*'},
                     reply={f'{_ROS2CLI_NODES}/{s}' for s in NODE_SERVICES},
                     request={f'/*/{s}' for s in READ_ONLY_PARAMETER_SERVICES})
    if enclave == OPERATOR:
        rights.publish |= set(_team_topic_names(scenario)[topics.FAULT])
        rights.request |= {f'/*/{s}' for s in PARAMETER_SERVICES}
    return rights.grant(enclave, 'tool')


def _node_kinds(scenario) -> list:
    """``[(fully qualified name, kind, UH id or None)]`` of every node a run of ``scenario`` can start.

    From the run's node table with the optional nodes on (visualisation, live view); the sensing node
    is in it only when the scenario's safety filter is on.
    """
    specs = node_specs(scenario, scenario.name, 'proposed', 'lockstep', 1.0, None, '.', 60.0,
                       visualization=True, live_view=('127.0.0.1', 0))
    nodes = []
    for (_name, kind, ros_args), fqn in zip(specs, (run_node_names([s])[0] for s in specs), strict=True):
        uh_id = next((int(a.split(':=', 1)[1]) for a in ros_args if a.startswith('uh_id:=')), None)
        nodes.append((fqn, kind, uh_id))
    return nodes


def team_grants(scenario) -> list:
    """Return the :class:`Grant` of every identity of a run of ``scenario`` (its nodes, then the tools), by enclave."""
    grants = [node_grant(kind, fqn, scenario, uh_id) for fqn, kind, uh_id in _node_kinds(scenario)]
    grants += [_tool_grant(enclave, scenario) for enclave in TOOL_ENCLAVES]
    return sorted(grants, key=lambda g: g.enclave)


def grant_of(grants, enclave: str) -> Grant:
    """Return the grant of ``enclave`` among ``grants`` (``KeyError`` naming the enclaves there are)."""
    for grant in grants:
        if grant.enclave == enclave:
            return grant
    raise KeyError(f'no identity {enclave!r}; there are {", ".join(g.enclave for g in grants)}')


def _split(path: str) -> tuple:
    """``(namespace, node)`` of a node's fully qualified name (``'/uh1/controller'`` -> ``('/uh1', 'controller')``)."""
    namespace, _, node = path.rpartition('/')
    return namespace or '/', node


def policy_xml(grants) -> ET.Element:
    """Return the ROS 2 access-control policy of ``grants`` (format 0.2.0: ``policy/enclaves/enclave/profiles``).

    One enclave per grant with one profile, whose ``ns`` and ``node`` are the enclave path's (the
    tools' profiles say which tool); topic and service names are fully qualified.
    """
    root = ET.Element('policy', version=POLICY_VERSION)
    enclaves = ET.SubElement(root, 'enclaves')
    for grant in grants:
        profiles = ET.SubElement(ET.SubElement(enclaves, 'enclave', path=grant.enclave), 'profiles')
        namespace, node = _split(grant.enclave)
        profile = ET.SubElement(profiles, 'profile', ns=namespace, node=node)
        for tag, item, attribute, names in (('topics', 'topic', 'publish', grant.publish),
                                            ('topics', 'topic', 'subscribe', grant.subscribe),
                                            ('services', 'service', 'reply', grant.reply),
                                            ('services', 'service', 'request', grant.request)):
            if names:
                element = ET.SubElement(profile, tag, {attribute: 'ALLOW'})
                for name in names:
                    ET.SubElement(element, item).text = name
    return root


def _domains(parent: ET.Element, domains: DomainRange) -> None:
    element = ET.SubElement(parent, 'domains')
    if domains.lo == domains.hi:
        ET.SubElement(element, 'id').text = str(domains.lo)
    else:
        id_range = ET.SubElement(element, 'id_range')
        ET.SubElement(id_range, 'min').text = str(domains.lo)
        ET.SubElement(id_range, 'max').text = str(domains.hi)


def _dds_root() -> ET.Element:
    return ET.Element('dds', {'xmlns:xsi': 'http://www.w3.org/2001/XMLSchema-instance'})


def permissions_xml(grant: Grant, not_before: str, not_after: str, domains: DomainRange = DomainRange()) -> ET.Element:
    """Return the DDS Security permissions document of ``grant`` (OMG DDS Security 1.1, as sros2's template makes it).

    One grant for subject ``CN=<enclave>``, valid from ``not_before`` to ``not_after`` (ISO 8601, the
    identity certificate's validity), one allow rule on ``domains`` and ``DENY`` by default.
    """
    root = _dds_root()
    root.set('xsi:noNamespaceSchemaLocation', 'http://www.omg.org/spec/DDS-SECURITY/20170901/omg_shared_ca_permissions.xsd')
    element = ET.SubElement(ET.SubElement(root, 'permissions'), 'grant', name=grant.enclave)
    ET.SubElement(element, 'subject_name').text = f'CN={grant.enclave}'
    validity = ET.SubElement(element, 'validity')
    ET.SubElement(validity, 'not_before').text = not_before
    ET.SubElement(validity, 'not_after').text = not_after
    rule = ET.SubElement(element, 'allow_rule')
    _domains(rule, domains)
    for tag, names in (('publish', grant.dds_publish()), ('subscribe', grant.dds_subscribe())):
        listed = ET.SubElement(ET.SubElement(rule, tag), 'topics')
        for name in names:
            ET.SubElement(listed, 'topic').text = name
    ET.SubElement(element, 'default').text = 'DENY'
    return root


def governance_xml(domains: DomainRange = DomainRange()) -> ET.Element:
    """Return the governance document: sros2's default (authenticated participants only, everything encrypted).

    No unauthenticated participant is let in, joining is access-controlled, discovery, liveliness and
    every message are encrypted, and reading and writing every topic is access-controlled.
    """
    root = _dds_root()
    root.set('xsi:noNamespaceSchemaLocation', 'http://www.omg.org/spec/DDS-SECURITY/20170901/omg_shared_ca_governance.xsd')
    rule = ET.SubElement(ET.SubElement(root, 'domain_access_rules'), 'domain_rule')
    _domains(rule, domains)
    for tag, text in (('allow_unauthenticated_participants', 'false'), ('enable_join_access_control', 'true'),
                      ('discovery_protection_kind', 'ENCRYPT'), ('liveliness_protection_kind', 'ENCRYPT'),
                      ('rtps_protection_kind', 'ENCRYPT')):
        ET.SubElement(rule, tag).text = text
    topic_rule = ET.SubElement(ET.SubElement(rule, 'topic_access_rules'), 'topic_rule')
    for tag, text in (('topic_expression', '*'), ('enable_discovery_protection', 'true'),
                      ('enable_liveliness_protection', 'true'), ('enable_read_access_control', 'true'),
                      ('enable_write_access_control', 'true'), ('metadata_protection_kind', 'ENCRYPT'),
                      ('data_protection_kind', 'ENCRYPT')):
        ET.SubElement(topic_rule, tag).text = text
    return root


def xml_text(root: ET.Element) -> str:
    """Return ``root`` as an indented XML document with its declaration."""
    ET.indent(root, space='  ')
    return '<?xml version="1.0" encoding="UTF-8"?>\n' + ET.tostring(root, encoding='unicode') + '\n'
