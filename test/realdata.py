"""Where the team's real Pathfinder logs live (../shared/data/pathfinder beside the repo; never
copied into it), and the skip every test that needs them takes when they are absent."""
from pathlib import Path

import pytest

DATA_DIR = Path(__file__).resolve().parents[1].parent / 'shared' / 'data' / 'pathfinder'


def mat_or_skip(name: str) -> Path:
    """Path of ``<name>.mat``; skips the calling test with a clear message when absent."""
    path = DATA_DIR / f'{name}.mat'
    if not path.exists():
        pytest.skip(f'Pathfinder log {path} not found (real data lives in '
                    '<repo>/../shared/data/pathfinder; not part of the repo)')
    return path
