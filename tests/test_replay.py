"""Behaviour is pinned: a fixed sample of episodes (every stage, ``mpc_goal`` and the shipped
policies, the other planners, social force, the MuJoCo LiDAR, a design, a reward variant, the
paper's rule) and a short PPO run replay bit for bit against digests recorded before the house
reorganisation (``tests/replay_cases.py``)."""

from __future__ import annotations

import json

import pytest

from tests.replay_cases import CASES, DIGESTS, run_case, train_case

RECORDED = json.loads(DIGESTS.read_text())


@pytest.mark.parametrize("name,task,policy,index,overrides", CASES, ids=[c[0] for c in CASES])
def test_episode_replays_bit_for_bit(name, task, policy, index, overrides):
    assert run_case(task, policy, index, overrides) == RECORDED[name]


def test_training_replays_bit_for_bit(tmp_path):
    assert train_case(tmp_path) == RECORDED["train-stage1"]
