"""Outcome-verified local search with common random numbers (lab tool, not in mjnav).

    python experiments/search.py crn CKPT STAGE SEED            # a changed action, the same crowd?
    python experiments/search.py collect OUT.npz CKPT STAGE N SEED0   # search failures, label rescues
    python experiments/search.py fit OUT_DIR CKPT DATA.npz [...]      # refit -> OUT_DIR/model_0.pt

Why: on the crowd stages PPO's advantages are drowned by the pedestrians' random walks (the
critic explains ~3 % more of the return even when it sees the true crowd; docs/results.md). The
pedestrians do not react to the robot and draw from their own random stream, so an episode seed
fixes the crowd's whole future whatever the robot does. Re-playing a failed episode with a changed
action therefore compares actions on the *same* future: a paired, noise-free comparison.

``collect``: the policy (mean action, task overrides of its config) plays N training-seed episodes.
Each collision at step T is searched: from the latest branch point t in T-4, T-8, ... T-20, the
episode is re-played with the policy's mean plus one offset δ (logits; smallest first) held for
``HOLD`` steps from t, the policy's own mean elsewhere. A rescue (success) labels those ``HOLD``
observations with the policy's mean plus the offset (``SEARCH_LABEL``, see :func:`search`).
Every observation of the successful episodes (and of the steps before t) is kept with the
policy's own action as an anchor, so the refit moves the actor only where a rescue was found.
Labels and anchors are stored with a flag.

``fit``: weighted regression of the actor's mean on labels (weight ``SEARCH_LABEL_WEIGHT``, default
5) and anchors (1), Adam 3e-4, ``SEARCH_EPOCHS`` (default 10); the log-std is kept. Writes
``OUT_DIR/model_0.pt`` and the base checkpoint's ``config.yaml`` beside it.

Result (docs/results.md, stage 7, from the shipped stage-6 policy): 3,000 episodes with
``SEARCH_LABEL=first``, 43 % of the failures rescued by one 0.5 s offset, 2,025 labels; the refits
scored 68.0 / 66.0 % (label weight 5 / 20) on development scenarios against 69.0 % for the policy.
"""

from __future__ import annotations

import os
import shutil
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from imitation import load_student as _actor  # noqa: E402  (the actor's mean: obs -> logits)

HOLD = int(os.environ.get("SEARCH_HOLD", "5"))
BACK = (4, 8, 12, 16, 20)
#: Offsets in logit space of (α_s, β_s, α_l, β_l), by growing size: turn Q_l, then move it nearer / farther.
DELTAS = [np.array(d, np.float32) for d in (
    (0, 0, 0.3, 0), (0, 0, -0.3, 0), (0, 0, 0, -0.5), (0, 0, 0, 0.5),
    (0, 0, 0.6, 0), (0, 0, -0.6, 0), (0, 0, 0, -1.0), (0, 0, 0, 1.0),
    (0, 0, 1.0, 0), (0, 0, -1.0, 0), (0, 0, 0.6, -0.5), (0, 0, -0.6, -0.5),
)]


def config_path(ckpt: str | Path) -> Path:
    """The checkpoint's training config (:func:`mjnav.policy.policy_config`); an error if none."""
    from mjnav.policy import policy_config

    config = policy_config(ckpt)
    if config is None:
        raise FileNotFoundError(f"no config next to {ckpt}")
    return config


def _overrides(ckpt: str) -> list[str]:
    """The task overrides the checkpoint was trained with."""
    from mjnav.policy import training_overrides

    return list(training_overrides(ckpt))


def play(env, seed: int, actor, offset: tuple[int, np.ndarray] | None = None, peds: list | None = None):
    """One episode: (outcome, observations, actions); ``offset`` = (t, δ) adds δ at steps t..t+HOLD-1."""
    obs, _ = env.reset(options={"episode_seed": seed})
    observations, actions = [], []
    info = {"outcome": "timeout"}
    for k in range(300):
        action = actor(obs)
        if offset is not None and offset[0] <= k < offset[0] + HOLD:
            action = action + offset[1]
        observations.append(obs)
        actions.append(action)
        if peds is not None:
            peds.append(env.task.sim.pedestrian_circles()[:, :2].copy())
        obs, _, term, trunc, info = env.step(action.astype(np.float32))
        if term or trunc:
            break
    return info["outcome"], observations, actions


def search(env, seed: int, actor):
    """(base outcome, rescued?, [(obs, action, is_label)], rescuing offsets) for one episode.

    ``SEARCH_LABEL=first`` labels with the first rescuing offset; ``mean`` (default) tries every
    offset at the latest branch point with a rescue and labels with the mean of the rescuing ones,
    so that rescues in opposite directions (luck, not a choice) cancel."""
    outcome, observations, actions = play(env, seed, actor)
    if outcome == "success":
        return outcome, False, [(o, a, False) for o, a in zip(observations, actions)], 0
    collided = len(observations) - 1
    first = os.environ.get("SEARCH_LABEL", "mean") == "first"
    for back in BACK:
        t = collided - back
        if t < 0:
            break
        rescues = []
        for delta in DELTAS:
            result, obs2, _ = play(env, seed, actor, (t, delta))
            if result == "success":
                rescues.append((delta, obs2))
                if first:
                    break
        if rescues:
            delta = np.mean([d for d, _ in rescues], axis=0)
            obs2 = rescues[0][1]
            rows = [(o, a, False) for o, a in zip(observations[:t], actions[:t])]
            rows += [(o, actor(o) + delta, True) for o in obs2[t:t + HOLD]]
            return outcome, True, rows, len(rescues)
    keep = max(0, collided - BACK[-1])
    return outcome, False, [(o, a, False) for o, a in zip(observations[:keep], actions[:keep])], 0


def _env(stage: str, ckpt: str):
    from mjnav.envs.gym_env import NavGymEnv

    return NavGymEnv(stage, overrides=_overrides(ckpt), seed=0)


def check_crn(ckpt: str, stage: str, seed: int) -> None:
    env, actor = _env(stage, ckpt), _actor(ckpt)
    a, b = [], []
    play(env, seed, actor, peds=a)
    play(env, seed, actor, (2, np.array([0, 0, 1.0, 1.0], np.float32)), peds=b)
    n = min(len(a), len(b))
    print(f"{n} common steps, max pedestrian difference {max(np.abs(x - y).max() for x, y in zip(a[:n], b[:n])):.3g} m")


def collect(out: str, ckpt: str, stage: str, n: int, seed0: int) -> None:
    env, actor = _env(stage, ckpt), _actor(ckpt)
    rows, counts, many = [], {"success": 0, "rescued": 0, "failed": 0}, []
    for ep in range(n):
        outcome, rescued, found, k = search(env, seed0 + ep, actor)
        rows += found
        many += [k] if rescued else []
        counts["success" if outcome == "success" else "rescued" if rescued else "failed"] += 1
        if ep % 50 == 49:
            print(ep + 1, counts, len(rows), "rescuing offsets per rescue", np.bincount(many, minlength=13)[1:],
                  flush=True)
    np.savez_compressed(out, obs=np.array([r[0] for r in rows], np.float32),
                        act=np.array([r[1] for r in rows], np.float32), label=np.array([r[2] for r in rows]))
    print(out, counts, len(rows), "labels", sum(r[2] for r in rows), flush=True)


def fit(out_dir: str, ckpt: str, files: list[str]) -> None:
    import torch

    from mjnav.policy import build_actor

    data = [np.load(f) for f in files]
    obs = torch.as_tensor(np.concatenate([d["obs"] for d in data]))
    act = torch.as_tensor(np.concatenate([d["act"] for d in data]))
    label = torch.as_tensor(np.concatenate([d["label"] for d in data]))
    weight = torch.where(label, float(os.environ.get("SEARCH_LABEL_WEIGHT", "5")), 1.0)
    base = torch.load(ckpt, map_location="cpu", weights_only=False)
    net = build_actor(base["actor_state_dict"], ("relu", "relu", "hardswish"))
    epochs = int(os.environ.get("SEARCH_EPOCHS", "10"))
    opt = torch.optim.Adam(net.parameters(), lr=3e-4)
    torch.manual_seed(0)
    perm = torch.randperm(len(obs))
    val, train = perm[: len(obs) // 10], perm[len(obs) // 10:]
    for epoch in range(epochs):
        net.train()
        for idx in train[torch.randperm(len(train))].split(512):
            loss = (weight[idx, None] * (net(obs[idx]) - act[idx]) ** 2).mean()
            opt.zero_grad()
            loss.backward()
            opt.step()
        with torch.no_grad():
            err = (net(obs[val]) - act[val]) ** 2
            lab = label[val]
        print(f"epoch {epoch + 1}: val mse anchors {err[~lab].mean(0).numpy().round(4)} "
              f"labels {err[lab].mean(0).numpy().round(4)}", flush=True)
    base["actor_state_dict"].update({f"mlp.{k}": v for k, v in net.state_dict().items()})
    base["iter"] = 0
    base.pop("optimizer_state_dict", None)
    Path(out_dir).mkdir(parents=True, exist_ok=True)
    torch.save(base, Path(out_dir) / "model_0.pt")
    shutil.copy(config_path(ckpt), Path(out_dir) / "config.yaml")  # so scripts/evaluate.py reads model_0.pt
    print("wrote", Path(out_dir) / "model_0.pt")


def main(argv: list[str]) -> None:
    if argv[0] == "crn":
        check_crn(argv[1], argv[2], int(argv[3]))
    elif argv[0] == "collect":
        collect(argv[1], argv[2], argv[3], int(argv[4]), int(argv[5]))
    elif argv[0] == "fit":
        fit(argv[1], argv[2], argv[3:])


if __name__ == "__main__":
    main(sys.argv[1:])
