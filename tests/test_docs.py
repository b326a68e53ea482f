"""The README and docs/: a short README, links that resolve, commands and options that exist (docs/testing.md)."""
import re
import shlex
from pathlib import Path

import pytest

from uh_bringup.run_formation import build_parser

ROOT = Path(__file__).resolve().parents[1]
README = ROOT / 'README.md'
PAGES = [README, *sorted((ROOT / 'docs').rglob('*.md'))]
README_MAX_LINES = 120

FENCE = re.compile(r'^```.*?^```', re.M | re.S)
#: [text](target) and ![alt](target); a target has no spaces (an optional "title" after it is not used here)
LINK = re.compile(r'!?\[[^\]]*\]\(([^)\s]+)\)')
HEADING = re.compile(r'^#{1,6}\s+(.+?)\s*#*\s*$', re.M)


def _prose(text: str) -> str:
    """Return ``text`` without its fenced code blocks (a link or heading inside one is code, not Markdown)."""
    return FENCE.sub('', text)


def _slug(heading: str) -> str:
    """Return GitHub's anchor of a heading: lower case, punctuation dropped, spaces as hyphens."""
    return re.sub(r'[^\w\- ]', '', heading.strip().lower()).replace(' ', '-')


def _anchors(page: Path) -> set:
    """Return the anchors of ``page``'s headings, a repeated one numbered as GitHub numbers it (-1, -2, ...)."""
    seen, anchors = {}, set()
    for m in HEADING.finditer(_prose(page.read_text())):
        slug = _slug(m.group(1))
        n = seen.get(slug, 0)
        seen[slug] = n + 1
        anchors.add(slug if n == 0 else f'{slug}-{n}')
    return anchors


def _relative_links(page: Path):
    """Yield the relative link targets of ``page`` (URLs with a scheme and mail addresses left out)."""
    for m in LINK.finditer(_prose(page.read_text())):
        target = m.group(1)
        if not re.match(r'[a-zA-Z][a-zA-Z0-9+.-]*:', target):
            yield target


def test_the_readme_reads_in_five_minutes():
    lines = README.read_text().splitlines()
    assert len(lines) < README_MAX_LINES, f'README.md has {len(lines)} lines; move depth to docs/'


def test_the_slug_of_a_heading_is_githubs():
    assert _slug('scripts/compare.sh and its results') == 'scriptscomparesh-and-its-results'
    assert _slug('3. Lossy links: one network namespace per helicopter') == \
        '3-lossy-links-one-network-namespace-per-helicopter'
    assert _slug('A node by itself: `ros2 run` and `--ros-args`') == 'a-node-by-itself-ros2-run-and---ros-args'


@pytest.mark.parametrize('page', PAGES, ids=lambda p: str(p.relative_to(ROOT)))
def test_every_relative_link_resolves(page):
    broken = []
    for target in _relative_links(page):
        path, _, fragment = target.partition('#')
        dest = (page.parent / path).resolve() if path else page
        if not dest.exists():
            broken.append(f'{target}: no file {dest.relative_to(ROOT) if dest.is_relative_to(ROOT) else dest}')
        elif fragment and dest.suffix == '.md' and fragment not in _anchors(dest):
            broken.append(f'{target}: no heading with anchor #{fragment} in {dest.relative_to(ROOT)}')
    assert not broken, f'{page.relative_to(ROOT)}: ' + '; '.join(broken)


def test_the_readme_links_every_docs_page():
    linked = {(README.parent / t.partition('#')[0]).resolve() for t in _relative_links(README)}
    missing = [p.name for p in sorted((ROOT / 'docs').glob('*.md')) if p.resolve() not in linked]
    assert not missing, f'README.md does not link {missing}'


def _run_formation_commands():
    """Yield (page, line) for every ``scripts/run_formation.sh`` command of a fenced code block."""
    for page in PAGES:
        for block in FENCE.findall(page.read_text()):
            for line in block.splitlines():
                line = line.split(' #')[0].strip()
                if line.startswith('scripts/run_formation.sh') and not re.search(r'[$\[|]|\.\.\.', line):
                    yield page, line


def test_documented_run_formation_commands_parse():
    """Every documented run command is one the script accepts: no per-node ROS arguments on it, no stale option."""
    parser = build_parser()
    commands = list(_run_formation_commands())
    assert len(commands) >= 5
    for page, line in commands:
        args = shlex.split(line)[1:]
        assert not {'--ros-args', '--params-file', '-p', '-r'} & set(args), f'{page.name}: {line}'
        try:
            parser.parse_args(args)
        except SystemExit:
            pytest.fail(f'{page.relative_to(ROOT)}: run_formation.sh refuses `{line}`')


def test_every_run_formation_option_is_documented_in_usage():
    usage = (ROOT / 'docs' / 'usage.md').read_text()
    table = usage[usage.index('## Running a team'):usage.index('## ROS arguments of one node')]
    options = {s for action in build_parser()._actions for s in action.option_strings if s not in ('-h', '--help')}
    missing = sorted(o for o in options if not re.search(rf'`{re.escape(o)}[ `]', table))
    assert not missing, f'docs/usage.md does not document {missing}'
