"""A worker process killed mid-training, for the tests of what a training keeps when one dies."""

from __future__ import annotations

import os
import signal
from typing import Any

from mjnav.envs.vec_env import NavVecEnv


def kill_a_worker_at(env: NavVecEnv, step: int) -> NavVecEnv:
    """Make ``env`` SIGKILL its first worker process just before its ``step``-th step (from 1)."""
    real, calls = env.step, []

    def step_then_kill(actions: Any) -> Any:
        calls.append(1)
        if len(calls) == step:
            os.kill(env._handles[0].process.pid, signal.SIGKILL)
        return real(actions)

    env.step = step_then_kill
    return env
