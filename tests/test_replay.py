"""Behaviour is pinned: a fixed sample of episodes (every stage, ``mpc_goal`` and the shipped
policies, the other planners, social force, the MuJoCo LiDAR, a design, a reward variant, the
paper's rule) and a short PPO run replay bit for bit against digests recorded before the house
reorganisation (``tests/replay_cases.py``)."""

from __future__ import annotations

import pytest

from tests.replay_cases import CASES, expected, numerics_fingerprint, run_case, train_case


@pytest.mark.parametrize("name,task,policy,index,overrides", CASES, ids=[c[0] for c in CASES])
def test_episode_replays_bit_for_bit(name, task, policy, index, overrides):
    result = run_case(task, policy, index, overrides)
    assert result == expected(name), f"numerics class {numerics_fingerprint()} (tests/replay_cases.py)"


def test_training_replays_bit_for_bit(tmp_path):
    result = train_case(tmp_path)
    assert result == expected("train-stage1"), f"numerics class {numerics_fingerprint()} (tests/replay_cases.py)"
