"""``mjnav render``: render one episode off-screen to MP4 (``--help`` lists the keys)."""

import sys

from mjnav.cli import main

if __name__ == "__main__":
    sys.exit(main(["render", *sys.argv[1:]]))
