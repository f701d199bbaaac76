"""Train a navigation policy with PPO (rsl-rl).

    python scripts/train.py task=stage6 [task.crowd.count=25] [train.num_envs=16] [train.iterations=500]
                            [seed=3] [resume=RUN_DIR] [init=CHECKPOINT] [curriculum=true] [out=runs]
                            [start=auto|shipped|curriculum|scratch]

See :mod:`mjnav.train.session` for the arguments and the run folder layout.
"""

from __future__ import annotations

import sys

from mjnav.cli import train as main

if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
