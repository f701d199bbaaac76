"""``mjnav export``: export one episode as a standalone MuJoCo scene (``--help`` lists the keys)."""

import sys

from mjnav.cli import main

if __name__ == "__main__":
    sys.exit(main(["export", *sys.argv[1:]]))
