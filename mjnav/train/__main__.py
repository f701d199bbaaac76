"""``python -m mjnav.train task=stage6 ...``: the same as ``mjnav-train`` and ``scripts/train.py``."""

import sys

from mjnav.cli import train

sys.exit(train())
