"""``python -m dolfin_rod run|check SCENE.toml`` (see dolfin_rod.cli)."""

import sys

from .cli import main

sys.exit(main())
