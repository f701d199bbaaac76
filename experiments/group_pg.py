"""Policy gradient with scenario groups: a critic-free baseline from common random numbers (lab tool).

    python experiments/group_pg.py OUT_DIR CKPT STAGE ITERATIONS [SEED0]

Why: on the crowd stages PPO's advantages are drowned by the pedestrians' random walks: the critic
cannot predict the return, even when it sees the true crowd (docs/results.md). The pedestrians do
not react to the robot and draw from their own random stream, so one episode seed fixes the crowd's
whole future whatever the robot does (``search.py crn`` checks it). Here every scenario is played
``GPG_GROUP`` times (default 8) with independently sampled actions, and an episode's advantage is
its return (reward r_t1, the task's own; ``GPG_ADV=success``: 1 for a success, else 0) minus the
mean of its group: the scenario's difficulty cancels, what is left is due to the actions (the
group baseline of GRPO, on paired scenarios). Groups whose values are all equal carry no signal
and are skipped.

Per iteration: ``GPG_SCENARIOS`` (default 24) fresh training-seed scenarios × the group; then
``GPG_EPOCHS`` (4) passes of the PPO clipped objective (clip 0.2) on the actor's mean, minibatches of
2,048, Adam ``GPG_LR`` (1e-4); the standard deviation is the checkpoint's and stays fixed. Each
step of an episode gets the episode's advantage, normalised over the iteration. Every 10 iterations
``OUT_DIR/model_<it>.pt`` (rsl-rl layout, the base checkpoint's critic untouched) and
``OUT_DIR/config.yaml`` (the base checkpoint's) are written, so ``scripts/evaluate.py`` reads them.

Result (docs/results.md, stage 7, from the shipped stage-6 policy): training success flat with
either advantage (1.39M steps on the return, 3.74M on success); development success 66.7 % and
66.5 % against 69.0 % for the policy it started from.
"""

from __future__ import annotations

import os
import shutil
import sys
import time
from pathlib import Path

import numpy as np
import torch

sys.path.insert(0, str(Path(__file__).resolve().parent))
from search import _env, config_path  # noqa: E402  (the checkpoint's task overrides and config)

GROUP = int(os.environ.get("GPG_GROUP", "8"))
SCENARIOS = int(os.environ.get("GPG_SCENARIOS", "24"))
EPOCHS = int(os.environ.get("GPG_EPOCHS", "4"))
LR = float(os.environ.get("GPG_LR", "1e-4"))
CLIP = 0.2
ADVANTAGE = os.environ.get("GPG_ADV", "return")  # return: r_t1's return; success: 1 for a success, else 0


def play(env, seed: int, net, std: torch.Tensor, gen: torch.Generator):
    """One episode with sampled actions: (observations, actions, return, success)."""
    obs, _ = env.reset(options={"episode_seed": seed})
    observations, actions, total, info = [], [], 0.0, {"outcome": "timeout"}
    for _ in range(300):
        x = torch.as_tensor(obs, dtype=torch.float32)[None]
        with torch.no_grad():
            action = (net(x)[0] + std * torch.randn(4, generator=gen)).numpy()
        observations.append(obs)
        actions.append(action)
        obs, reward, term, trunc, info = env.step(action.astype(np.float32))
        total += float(reward)
        if term or trunc:
            break
    return observations, actions, total, info["outcome"] == "success"


def main(argv: list[str]) -> None:
    from mjnav.policy import build_actor

    out, ckpt, stage, iterations = Path(argv[0]), Path(argv[1]), argv[2], int(argv[3])
    seed0 = int(argv[4]) if len(argv) > 4 else 30_000_000
    out.mkdir(parents=True, exist_ok=True)
    shutil.copy(config_path(ckpt), out / "config.yaml")
    base = torch.load(ckpt, map_location="cpu", weights_only=False)
    net = build_actor(base["actor_state_dict"], ("relu", "relu", "hardswish"))
    std = base["actor_state_dict"]["distribution.log_std_param"].exp()
    opt = torch.optim.Adam(net.parameters(), lr=LR)
    env = _env(stage, str(ckpt))
    gen = torch.Generator().manual_seed(seed0)
    torch.manual_seed(seed0)
    seed = seed0
    for it in range(1, iterations + 1):
        start = time.time()
        obs_l, act_l, adv_l, successes, mixed, steps = [], [], [], [], 0, 0
        for _ in range(SCENARIOS):
            group = [play(env, seed, net, std, gen) for _ in range(GROUP)]
            seed += 1
            returns = np.array([g[3] if ADVANTAGE == "success" else g[2] for g in group], float)
            successes += [g[3] for g in group]
            steps += sum(len(g[0]) for g in group)
            if np.ptp(returns) < 1e-6:
                continue
            mixed += len({g[3] for g in group}) > 1
            for (o, a, _, _), adv in zip(group, returns - returns.mean()):
                obs_l += o
                act_l += a
                adv_l += [adv] * len(o)
        collect = time.time() - start
        if adv_l:
            _update(net, opt, std, np.array(obs_l, np.float32), np.array(act_l, np.float32), np.array(adv_l))
        print(f"it {it} | {steps} steps, collect {collect:.1f}s, update {time.time() - start - collect:.1f}s | "
              f"success {np.mean(successes):.3f} | groups with mixed outcomes {mixed}/{SCENARIOS}", flush=True)
        if it % 10 == 0 or it == iterations:
            base["actor_state_dict"].update({f"mlp.{k}": v for k, v in net.state_dict().items()})
            base["iter"] = it
            base.pop("optimizer_state_dict", None)
            torch.save(base, out / f"model_{it}.pt")


def _update(net, opt, std, obs, act, adv) -> None:
    obs_t, act_t = torch.as_tensor(obs), torch.as_tensor(act)
    adv_t = torch.as_tensor((adv - adv.mean()) / (adv.std() + 1e-8), dtype=torch.float32)
    dist = torch.distributions.Normal
    with torch.no_grad():
        old = dist(net(obs_t), std).log_prob(act_t).sum(-1)
    for _ in range(EPOCHS):
        for idx in torch.randperm(len(obs_t)).split(2048):
            logp = dist(net(obs_t[idx]), std).log_prob(act_t[idx]).sum(-1)
            ratio = (logp - old[idx]).exp()
            loss = -torch.min(ratio * adv_t[idx], ratio.clamp(1 - CLIP, 1 + CLIP) * adv_t[idx]).mean()
            opt.zero_grad()
            loss.backward()
            torch.nn.utils.clip_grad_norm_(net.parameters(), 1.0)
            opt.step()


if __name__ == "__main__":
    main(sys.argv[1:])
