"""The package's logger, for every layer: what the solver decides (step rejections, Jacobian
refreshes, checkpoints, a damaged checkpoint passed over, a lock file taken over), at INFO and
WARNING. Its level and handler are the command line's (cosserat_fem/analysis/progress.py
``configure_logging``: ``--quiet``, default, ``--verbose``, rank 0 only)."""

from __future__ import annotations

import logging

LOGGER = logging.getLogger("cosserat_fem")
