"""Test layout: ``unit/`` (one module each, ``test_<module>.py``), ``integration/`` (modules
together: simulated and real drives through the core, replay, the study), ``system/`` (the
commands, the node over DDS, the package's structure). This folder is put on ``sys.path`` so
that every test imports the shared helpers as ``helpers``."""
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
