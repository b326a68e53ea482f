"""The argument parser of the project's commands: a usage error is one line, exit status 2.

:class:`ArgumentParser` is :class:`argparse.ArgumentParser` whose error is the single line
``<prog>: error: <what was wrong>; see <prog> --help`` on stderr (the standard parser prints the
whole usage first, a dozen lines for ``run_formation.sh``, before the line that matters).
"""
from __future__ import annotations

import argparse
from pathlib import Path

__all__ = ['ArgumentParser', 'unwritable_reason', 'directory_argument']


class ArgumentParser(argparse.ArgumentParser):
    """``argparse.ArgumentParser`` with one-line errors (module docstring); subcommand parsers are of this class too."""

    def error(self, message: str):
        """Print ``<prog>: error: <message>; see <prog> --help`` on stderr and exit with status 2."""
        self.exit(2, f'{self.prog}: error: {message}; see {self.prog} --help\n')


def unwritable_reason(out: Path) -> str | None:
    """Create the directory ``out`` if needed and write a probe file in it; return why not (``strerror``), or None."""
    try:
        out.mkdir(parents=True, exist_ok=True)
        probe = out / '.write_test'
        probe.write_text('')
        probe.unlink()
    except OSError as exc:
        return exc.strerror
    return None


def directory_argument(text: str) -> Path:
    """``type=`` of an ``--out DIR`` option: any non-empty path (an empty one would mean the current directory)."""
    if not text.strip():
        raise argparse.ArgumentTypeError("'': give a directory")
    return Path(text)
