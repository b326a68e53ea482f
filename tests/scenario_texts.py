"""Scenario YAML texts for tests: the bundled paper scenario, movable to any directory."""
from pathlib import Path

CONFIG = Path(__file__).resolve().parents[1] / 'uh_topology' / 'uh_topology' / 'config'


def paper_yaml(extra: str = '') -> str:
    """Return the paper scenario's YAML with its gains file named by absolute path, and ``extra`` appended."""
    text = (CONFIG / 'paper.yaml').read_text().replace('gains: paper_gains.yaml',
                                                      f'gains: {CONFIG / "paper_gains.yaml"}')
    return text + '\n' + extra if extra else text
