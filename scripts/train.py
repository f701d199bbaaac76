"""``mjnav train``: train a navigation policy with PPO (``python scripts/train.py --help`` lists the keys)."""

import sys

from mjnav.cli import main

if __name__ == "__main__":
    sys.exit(main(["train", *sys.argv[1:]]))
