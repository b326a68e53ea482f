"""``uh-campaign``: run a campaign (:mod:`uh_team.campaign.cli`, every option and exit status there)
and, once every run is stored, write its report (``uh-report DIR``: ``DIR/report/``; docs/campaigns.md)
unless ``--no-report``.
"""
from __future__ import annotations

import sys
from pathlib import Path

__all__ = ['main']


def _write_report(out: Path) -> int:
    from .report import main as report_main

    return report_main([str(out)])


def main(argv=None) -> int:
    """Entry point of ``uh-campaign``; returns the exit status."""
    from uh_team.campaign import cli

    return cli.main(argv, on_complete=_write_report)


if __name__ == '__main__':
    sys.exit(main())
