"""Where the package finds its shipped assets (flags, network weights).

Assets live in the repository's top-level assets/ folder; the package is installed editable
(`pip install -e .`) so that folder sits beside it. HVS_SIM_ASSETS points elsewhere if needed.
"""

from __future__ import annotations

import os
from pathlib import Path

ASSETS_DIR = Path(os.environ.get("HVS_SIM_ASSETS", Path(__file__).resolve().parent.parent / "assets"))
FLAGS_DIR = ASSETS_DIR / "flags"
WEIGHTS_DIR = ASSETS_DIR / "weights"
