"""``mjnav bench throughput``: environment and adapter steps/s (``--help`` lists the keys)."""

import sys

from mjnav.cli import main

if __name__ == "__main__":
    sys.exit(main(["bench", "throughput", *sys.argv[1:]]))
