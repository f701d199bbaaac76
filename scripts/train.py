"""Train a navigation policy with PPO (rsl-rl).

    python scripts/train.py task=stage6 [task.crowd.count=25] [train.num_envs=16] [train.iterations=500]
                            [seed=3] [resume=RUN_DIR] [init=CHECKPOINT] [curriculum=true] [out=runs]

See :mod:`mjnav.train.session` for the arguments and the run folder layout.
"""

from __future__ import annotations

import sys

from mjnav.schema import ConfigError
from mjnav.train.session import run


def main(argv: list[str]) -> int:
    """Run a training session; config errors print one line and return 2."""
    try:
        run(argv)
    except ConfigError as err:
        print(f"error: {err}", file=sys.stderr)
        return 2
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
