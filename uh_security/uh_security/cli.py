"""``uh-security``: the keystore of a secure team, made from its scenario (docs/security.md).

``uh-security create --scenario S --keystore DIR [--safety on|off] [--domain-id N]`` writes a CA, one
identity per node of a run of S and one per tool (``/tools/inspect``, ``/tools/operator``), the
signed governance and each identity's signed permissions, in sros2's keystore layout
(:mod:`uh_security.keystore`), and the ROS 2 access-control policy they come from as ``DIR/policy.xml``.
``uh-security policy --scenario S [--safety on|off]`` prints that policy without writing anything.
``uh-security check --scenario S --keystore DIR [--safety on|off] [--domain-id N]`` checks that DIR is a
keystore of S with that safety setting, valid on domain N, with every identity signed by its CA and valid
now, and prints its record (``uh_keystore.json``) on stdout: what ``run_formation.sh --secure`` runs first.

Exit status: 0 done, 2 bad input (an unknown scenario or a broken one, a DIR that exists and is not
empty (create) or is not a keystore of S (check), a domain outside 0..230; one line on stderr, nothing
written).
"""
from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from uh_runtime.command_line import ArgumentParser, directory_argument
from uh_topology.errors import ScenarioError
from uh_topology.safety import add_safety_argument, safety_override
from uh_topology.scenario import load_scenario

from . import keystore, policy

__all__ = ['main', 'build_parser', 'PROG']

PROG = 'uh-security'


def _scenario_arguments(parser) -> None:
    parser.add_argument('--scenario', required=True, metavar='S',
                        help='scenario YAML file or the name of a bundled scenario (paper, crowd, square, ...)')
    add_safety_argument(parser)


def build_parser() -> argparse.ArgumentParser:
    """Return the argument parser of ``uh-security``."""
    p = ArgumentParser(
        prog=PROG,
        description='Secure mode: the DDS Security keystore of a team, with access control generated from the '
                    "scenario's communication graph (a controller may read only the states of the UHs it hears "
                    'and publish only its own command and status).',
        epilog='Examples: uh-security create --scenario paper --keystore runs/keys; '
               'uh-security policy --scenario paper. Exit status: 0 done, 2 bad input. docs/security.md')
    commands = p.add_subparsers(dest='command', required=True, metavar='COMMAND', parser_class=ArgumentParser)
    create = commands.add_parser('create', help='write a keystore for the nodes of a run of the scenario',
                                 description="Write a CA, one identity per node of a run of the scenario and per "
                                             'tool, and their signed permissions, in sros2\'s keystore layout.')
    _scenario_arguments(create)
    create.add_argument('--keystore', required=True, type=directory_argument, metavar='DIR',
                        help='the keystore directory to create: new or empty')
    create.add_argument('--domain-id', type=int, metavar='N',
                        help=f'make the documents valid on DDS domain N only (default: every domain, '
                             f'0..{policy.SECURE_MAX_DOMAIN_ID}, as a run picks a free one)')
    check = commands.add_parser('check', help='check that a keystore is one of the scenario (before a secure run)',
                                description='Check that DIR is a keystore made for the scenario and safety setting, '
                                            'valid on the domain, every identity signed by its CA and valid now; '
                                            'print its record (JSON).')
    _scenario_arguments(check)
    check.add_argument('--keystore', required=True, metavar='DIR', help='the keystore directory')
    check.add_argument('--domain-id', type=int, metavar='N', help='the DDS domain of the run')
    show = commands.add_parser('policy', help='print the access-control policy of the scenario (ROS 2 format)',
                               description='Print the ROS 2 access-control policy (format 0.2.0) that '
                                           '"create" signs, without writing anything.')
    _scenario_arguments(show)
    return p


def _fail(message: str) -> int:
    print(f'{PROG}: error: {message}', file=sys.stderr)
    return 2


def main(argv=None) -> int:
    """Entry point of ``uh-security``; returns the exit status (see the module docstring)."""
    try:
        args = build_parser().parse_args(argv)
    except SystemExit as exc:
        return int(exc.code or 0)
    if not args.scenario.strip():
        return _fail("--scenario '': give a scenario YAML file or a bundled name")
    domains = policy.DomainRange()
    if getattr(args, 'domain_id', None) is not None:
        if not 0 <= args.domain_id <= policy.SECURE_MAX_DOMAIN_ID:
            return _fail(f'--domain-id {args.domain_id} is outside 0..{policy.SECURE_MAX_DOMAIN_ID}')
        domains = policy.DomainRange(args.domain_id, args.domain_id)
    try:
        scenario = load_scenario(args.scenario, safety=safety_override(args.safety))
    except ScenarioError as exc:
        return _fail(str(exc))
    grants = policy.team_grants(scenario)
    if args.command == 'policy':
        sys.stdout.write(policy.xml_text(policy.policy_xml(grants)))
        return 0
    record = {'scenario': scenario.name, 'scenario_source': scenario.source, 'safety': scenario.safety.enabled}
    if args.command == 'check':
        try:
            found = keystore.check_keystore(Path(args.keystore), grants, record, args.domain_id)
        except keystore.KeystoreError as exc:
            return _fail(str(exc))
        print(json.dumps(found))
        return 0
    try:
        enclaves = keystore.create_keystore(args.keystore, grants, record, domains)
    except keystore.KeystoreError as exc:
        return _fail(str(exc))
    where = Path(args.keystore).resolve()
    print(f'{PROG}: keystore of scenario {scenario.name} with {len(enclaves)} identities in {where} '
          f'(policy: {where / "policy.xml"})', file=sys.stderr)
    return 0


if __name__ == '__main__':
    sys.exit(main())
