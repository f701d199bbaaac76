"""``mjnav bench sim``: NavSim build, reset and step times (``--help`` lists the keys)."""

import sys

from mjnav.cli import main

if __name__ == "__main__":
    sys.exit(main(["bench", "sim", *sys.argv[1:]]))
