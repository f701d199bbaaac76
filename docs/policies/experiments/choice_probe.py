"""Lab probe: mpc_crowd's choice learned as a classification over its 145 candidates from the
paper's 399-value observation (cross-entropy), acting through the same encoding. Not in mjnav.
    python docs/policies/experiments/choice_probe.py teacher stage6         # the quantised teacher, 200 tuning scenarios
    python docs/policies/experiments/choice_probe.py collect OUT.npz stage5,stage6,stage7 400
    python docs/policies/experiments/choice_probe.py fit NET.pt OUT.npz
    python docs/policies/experiments/choice_probe.py eval NET.pt

Results in docs/results.md (section "A privileged crowd teacher").
"""
import os
import sys
import numpy as np
import torch
sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
os.environ.setdefault("IMIT_OVERRIDES", "action.heading=goal,observation.frame=goal")
os.environ["IMIT_TEACHER"] = "vo"
import imitation as im
from mjnav.planners import mpc_crowd as mc
from mjnav.control.action import goal_inside

CFG = mc.MpcCrowdConfig()
CAND = mc._candidates(CFG)
SPEEDS = np.hypot(CAND[:, 0], CAND[:, 1])

def state(env):
    t = env.task
    p, v, _ = t.sim.robot_state(env._env.physics)
    return t, p[:2], v[:2], np.asarray(t.core.goal) - p[:2]

def teacher_index(env):
    t, p, v, goal = state(env)
    im.crowd_q_l(env, p, goal)  # updates the velocity estimate
    c = t.sim.pedestrian_circles()
    rel = np.column_stack([c[:, :2] - p, c[:, 2]])
    dist = float(np.hypot(*goal))
    reach = np.minimum(SPEEDS * 1.0, CFG.safety * mc._free_distances(t.core.region, CAND, SPEEDS))
    clear = mc._clearance(CAND, v, rel, im._PREV["tracker"].velocities, im.R_INF, CFG)
    danger = np.maximum(0.0, CFG.margin - clear) / CFG.margin
    score = CAND @ (goal / max(dist, 1e-9)) / max(CFG.speeds) - CFG.weight * danger - 0.5 * (reach < 0.5 * SPEEDS)
    best = int(np.argmax(score))
    if best == 0:
        return 0
    ring, k = divmod(best - 1, CFG.directions)  # to the goal frame: direction bins measured from the goal
    g = np.arctan2(goal[1], goal[0])
    k = int(round((k * 2 * np.pi / CFG.directions - g) / (2 * np.pi / CFG.directions))) % CFG.directions
    return 1 + ring * CFG.directions + k

def action_for(env, idx):
    t, p, v, goal = state(env)
    dist = float(np.hypot(*goal))
    g = np.arctan2(goal[1], goal[0])
    c, s_ = np.cos(g), np.sin(g)
    u = CAND[idx] @ np.array([[c, s_], [-s_, c]])  # goal frame -> world
    reach = min(SPEEDS[idx], CFG.safety * mc._free_distances(t.core.region, u[None], SPEEDS[idx:idx + 1])[0])
    q = np.zeros(2) if idx == 0 else u / SPEEDS[idx] * min(reach, dist)
    saved = im.crowd_q_l
    im.crowd_q_l = lambda env, p, goal: q
    try:
        return im.teacher_action(env)
    finally:
        im.crowd_q_l = saved

def net_fn():
    return torch.nn.Sequential(torch.nn.Linear(399, 256), torch.nn.ReLU(), torch.nn.Linear(256, 256), torch.nn.ReLU(),
                               torch.nn.Linear(256, 256), torch.nn.Hardswish(), torch.nn.Linear(256, len(CAND)))

def run(stage, n, seed0, net=None, record=None):
    env = im.make_env(stage); out = {}
    for ep in range(n):
        obs, _ = env.reset(options={"episode_seed": seed0 + ep})
        for _ in range(300):
            label = teacher_index(env) if (net is None or record is not None) else None
            if record is not None:
                record[0].append(obs.copy()); record[1].append(label)
            if net is None:
                idx = label
            else:
                with torch.no_grad():
                    idx = int(net(torch.as_tensor(obs)[None]).argmax())
            obs, _, term, trunc, info = env.step(action_for(env, idx).astype(np.float32))
            if term or trunc:
                break
        out[info["outcome"]] = out.get(info["outcome"], 0) + 1
    env.close(); return out

if __name__ == "__main__":
    mode = sys.argv[1]
    if mode == "teacher":
        print(run(sys.argv[2], 200, 2**32 + 1000000000))
    elif mode == "collect":  # out stages n seed [net]
        net = None
        if len(sys.argv) > 5:
            net = net_fn(); net.load_state_dict(torch.load(sys.argv[5])); net.eval()
        rec = ([], [])
        for st in sys.argv[3].split(","):
            print(st, run(st, int(sys.argv[4]), int(sys.argv[6]) if len(sys.argv) > 6 else 7000000, net, rec), len(rec[0]), flush=True)
        np.savez_compressed(sys.argv[2], x=np.array(rec[0], np.float32), y=np.array(rec[1], np.int64))
    elif mode == "fit":  # out files...
        data = [np.load(f) for f in sys.argv[3:]]
        X = torch.as_tensor(np.concatenate([d["x"] for d in data])); Y = torch.as_tensor(np.concatenate([d["y"] for d in data]))
        net = net_fn(); opt = torch.optim.Adam(net.parameters(), lr=1e-3); E = 30
        sched = torch.optim.lr_scheduler.CosineAnnealingLR(opt, E)
        torch.manual_seed(0); perm = torch.randperm(len(X)); val, tr = perm[: len(X) // 10], perm[len(X) // 10:]
        for e in range(E):
            for idx in tr[torch.randperm(len(tr))].split(1024):
                loss = torch.nn.functional.cross_entropy(net(X[idx]), Y[idx]); opt.zero_grad(); loss.backward(); opt.step()
            sched.step()
        with torch.no_grad():
            print("val accuracy", float((net(X[val]).argmax(1) == Y[val]).float().mean()), flush=True)
        torch.save(net.state_dict(), sys.argv[2])
    elif mode == "eval":
        net = net_fn(); net.load_state_dict(torch.load(sys.argv[2])); net.eval()
        for st in ("stage5", "stage6", "stage7"):
            print(st, run(st, 200, 2**32 + 5000000, net), flush=True)
