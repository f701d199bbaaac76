"""``mjnav plot <figure>``: episode, compare, curve or distance figures (``--help`` lists them)."""

import sys

from mjnav.cli import main

if __name__ == "__main__":
    sys.exit(main(["plot", *sys.argv[1:]]))
