"""What the secure tier's test modules share: the secure interpreter, the tier guard, a secure DDS domain.

tests/conftest.py loads this module as a plugin, so its fixtures serve every test module; a module of
the tier marks itself ``pytest.mark.usefixtures('only_in_the_secure_tier')``.
"""
import os
import sys
from pathlib import Path

import pytest

from uh_bringup.run_secure import SECURE_MAX_DOMAIN_ID
from uh_runtime.network import release_domain_id, reserve_domain_id

ROOT = Path(__file__).resolve().parents[2]
#: The interpreter of .venv-secure (Cyclone DDS 0.10.2 with DDS Security), or UH_SECURE_PYTHON.
SECURE_PYTHON = Path(os.environ.get('UH_SECURE_PYTHON', ROOT / '.venv-secure' / 'bin' / 'python'))


@pytest.fixture
def only_in_the_secure_tier(request):
    """Run in the secure tier (pytest in .venv-secure, or ``-m secure``), not in the main suite's time budget."""
    in_tier = Path(sys.prefix).resolve() == SECURE_PYTHON.parent.parent.resolve() or \
        'secure' in (request.config.option.markexpr or '')
    if not in_tier:
        pytest.skip('the secure tier: scripts/test.sh --secure (or pytest -m secure)')


@pytest.fixture
def secure_domain():
    """Reserve a private DDS domain a secure participant may use (DDS Security documents stop at 230)."""
    domain = reserve_domain_id(last=SECURE_MAX_DOMAIN_ID)
    yield domain
    release_domain_id(domain)
