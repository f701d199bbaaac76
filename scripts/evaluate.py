"""Evaluate a policy on held-out scenarios (spec §10).

    python scripts/evaluate.py task=stage6 policy=PATH_OR_NAME [episodes=1000] [tasks=stage5,stage6,stage7]
                               [workers=N] [out=DIR] [seed_offset=0] [action=mean|sample]
                               [from_contact=DIR] [task.crowd.count=25]

PATH_OR_NAME: a run folder, ``policy.pt``, ``model_<it>.pt`` or a baseline (mpc_goal, mpc_gap, teb, dwa,
random, random_jerk). A learned policy is evaluated with the task overrides it was trained with
(design, reward variant, collision rule, ...: ``run.task_overrides`` of its ``config.yaml``), then
the command's ``task.*`` overrides. ``action=sample`` samples the policy's Gaussian (checkpoints
only) instead of acting on its mean. Scenario i uses the episode seed 2**32 + seed_offset + i
(never a training seed), so every policy sees the same scenarios. Writes ``<task>.jsonl`` (one line per episode),
``summary.csv`` and ``summary.md`` into ``out`` (default ``evals/<policy>``) and prints the table.
``from_contact=DIR`` (with ``task.collision=scan``): take every episode that a contact-rule run of
the same policy, seeds and code commit in ``DIR`` settles under the paper's rule, and play only the
rest (usually none), so both rules cost one evaluation.
See :mod:`mjnav.eval.runner`.
"""

from __future__ import annotations

import sys

from mjnav.cli import evaluate as main

if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
