"""``python -m mjnav <verb> key=value ...``: the same as the ``mjnav`` console script."""

import sys

from mjnav.cli import main

sys.exit(main())
