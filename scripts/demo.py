"""``mjnav demo``: one convex-MPC episode, reported and exported (``--help`` lists the keys)."""

import sys

from mjnav.cli import main

if __name__ == "__main__":
    sys.exit(main(["demo", *sys.argv[1:]]))
