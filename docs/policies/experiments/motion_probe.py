"""Lab probe: can a student imitate mpc_crowd when its observation also carries the K nearest
pedestrians' true relative positions and velocities (goal frame)? Not part of mjnav.
    python docs/policies/experiments/motion_probe.py collect OUT.npz stage5,stage6,stage7 400
    python docs/policies/experiments/motion_probe.py fit NET.pt - OUT.npz
    python docs/policies/experiments/motion_probe.py eval NET.pt    # 200 development scenarios per crowd stage

Results in docs/results.md (section "A privileged crowd teacher").
"""
import math
import os
import sys
import numpy as np
import torch
sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
os.environ.setdefault("IMIT_OVERRIDES", "action.heading=goal,observation.frame=goal")
os.environ.setdefault("IMIT_TEACHER", "vo")
import imitation as im

K = 6

def features(env, prev):
    t = env.task
    p = t.sim.robot_state(env._env.physics)[0][:2]
    c = t.sim.pedestrian_circles()
    g = np.asarray(t.core.goal) - p
    ang = math.atan2(g[1], g[0])
    R = np.array([[math.cos(ang), math.sin(ang)], [-math.sin(ang), math.cos(ang)]])
    rel = c[:, :2] - p
    vel = (c[:, :2] - prev) / 0.1 if prev is not None and prev.shape == c[:, :2].shape else np.zeros_like(rel)
    d = np.hypot(*rel.T) - c[:, 2]
    order = np.argsort(d)[:K]
    f = np.zeros((K, 5))
    f[:len(order), :2] = (rel[order] @ R.T) / 10.0
    f[:len(order), 2:4] = (vel[order] @ R.T) / 0.6
    f[:len(order), 4] = c[order, 2]
    return f.ravel().astype(np.float32), c[:, :2].copy()

def net_fn(n_in):
    return torch.nn.Sequential(torch.nn.Linear(n_in, 256), torch.nn.ReLU(), torch.nn.Linear(256, 256), torch.nn.ReLU(),
                               torch.nn.Linear(256, 256), torch.nn.Hardswish(), torch.nn.Linear(256, 4))

def run(stage, n, seed0, student=None, record=None):
    env = im.make_env(stage)
    out = {}
    for ep in range(n):
        obs, _ = env.reset(options={"episode_seed": seed0 + ep})
        prev = None
        for _ in range(300):
            f, prev = features(env, prev)
            x = np.concatenate([obs, f])
            label = im.teacher_action(env) if (record is not None or student is None) else None
            if record is not None:
                record[0].append(x); record[1].append(label)
            if student is None:
                a = label
            else:
                with torch.no_grad():
                    a = student(torch.as_tensor(x)[None]).numpy()[0]
            obs, _, term, trunc, info = env.step(a.astype(np.float32))
            if term or trunc:
                break
        out[info["outcome"]] = out.get(info["outcome"], 0) + 1
    env.close()
    return out

def fit(files, init=None, epochs=30):
    data = [np.load(f) for f in files]
    X = torch.as_tensor(np.concatenate([d["x"] for d in data])); Y = torch.as_tensor(np.concatenate([d["y"] for d in data]))
    net = net_fn(X.shape[1])
    if init: net.load_state_dict(torch.load(init))
    opt = torch.optim.Adam(net.parameters(), lr=1e-3); sched = torch.optim.lr_scheduler.CosineAnnealingLR(opt, epochs)
    torch.manual_seed(0); perm = torch.randperm(len(X)); val, tr = perm[: len(X) // 10], perm[len(X) // 10:]
    for e in range(epochs):
        for idx in tr[torch.randperm(len(tr))].split(1024):
            loss = ((net(X[idx]) - Y[idx]) ** 2).mean(); opt.zero_grad(); loss.backward(); opt.step()
        sched.step()
    with torch.no_grad():
        print("val mse", ((net(X[val]) - Y[val]) ** 2).mean(0).numpy().round(4), "var", Y.var(0).numpy().round(3), flush=True)
    return net.eval()

if __name__ == "__main__":
    mode = sys.argv[1]
    if mode == "collect":  # out stages n seed [student.pt]
        student = None
        if len(sys.argv) > 5:
            student = net_fn(399 + 5 * K); student.load_state_dict(torch.load(sys.argv[5])); student.eval()
        rec = ([], [])
        for st in sys.argv[3].split(","):
            print(st, run(st, int(sys.argv[4]), 7000000 if student is None else 7500000, student, rec), len(rec[0]), flush=True)
        np.savez_compressed(sys.argv[2], x=np.array(rec[0], np.float32), y=np.array(rec[1], np.float32))
    elif mode == "fit":  # out.pt init|- files...
        net = fit(sys.argv[4:], None if sys.argv[3] == "-" else sys.argv[3])
        torch.save(net.state_dict(), sys.argv[2])
    elif mode == "eval":  # net.pt
        net = net_fn(399 + 5 * K); net.load_state_dict(torch.load(sys.argv[2])); net.eval()
        for st in ("stage5", "stage6", "stage7"):
            print(st, run(st, 200, 2**32 + 5000000, net), flush=True)
