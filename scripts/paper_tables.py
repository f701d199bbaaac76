"""``mjnav tables``: regenerate a table of the paper (``--help`` lists the keys)."""

import sys

from mjnav.cli import main

if __name__ == "__main__":
    sys.exit(main(["tables", *sys.argv[1:]]))
