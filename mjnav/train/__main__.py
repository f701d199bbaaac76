"""``python -m mjnav.train task=stage6 ...``: the same as ``mjnav train``."""

import sys

from mjnav.cli import train

sys.exit(train())
