"""``mjnav bench action_layer``: action-layer latencies (``--help`` lists the keys)."""

import sys

from mjnav.cli import main

if __name__ == "__main__":
    sys.exit(main(["bench", "action_layer", *sys.argv[1:]]))
