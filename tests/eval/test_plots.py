"""Figures: the per-episode path figure and the learning curve are written as PNG."""

from __future__ import annotations

import types

import numpy as np

from mjnav.eval.plots import load_scalars, plot_episode, plot_grid, plot_learning_curve


def _is_png(path) -> bool:
    return path.exists() and path.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def _synthetic():
    t = np.linspace(0.0, 3.0, 31)
    robot = np.column_stack([-3 + 2 * t, np.zeros_like(t)])
    peds = np.stack([np.column_stack([np.zeros_like(t), -2 + 0.5 * t, np.full_like(t, 0.3)]),
                     np.column_stack([2 - 0.4 * t, np.full_like(t, 2.0), np.full_like(t, 0.2)])], axis=1)
    layout = types.SimpleNamespace(start=np.array([-3.0, 0.0]), goal=np.array([3.0, 0.0]),
                                   obstacle_polygons=(np.array([[1.0, -3.0], [2.0, -3.0], [1.5, -2.0]]),))
    return robot, peds, layout


def test_episode_figure(tmp_path):
    """A synthetic episode (robot, two pedestrians, one obstacle) gives a PNG."""
    robot, peds, layout = _synthetic()
    out = plot_episode(robot, peds, layout, (10.0, 10.0), tmp_path / "ep.png", title="synthetic")
    assert _is_png(out)


def test_qualitative_and_comparison_figures(tmp_path):
    """Planning snapshots (region, Q_s, Q_l) and a 2 x 2 grid of episodes give PNGs."""
    robot, peds, layout = _synthetic()
    square = np.array([[-1.0, 1.0], [1.0, 1.0], [1.0, -1.0], [-1.0, -1.0]])
    plans = [{"position": robot[k], "polygon": robot[k] + square, "q_s": robot[k] + [0.3, 0.0],
              "q_l": robot[k] + [0.9, 0.1]} for k in (5, 15)]
    assert _is_png(plot_episode(robot, peds, layout, (10.0, 10.0), tmp_path / "plans.png", plans=plans))
    panel = {"positions": robot, "pedestrians": peds, "layout": layout, "arena_size": (10.0, 10.0)}
    assert _is_png(plot_grid([[panel, {**panel, "plans": plans}], [panel]], tmp_path / "grid.png"))


def test_learning_curve_from_events(tmp_path):
    """TensorBoard scalars episode/success and episode/return become a two-panel PNG."""
    from torch.utils.tensorboard import SummaryWriter

    writer = SummaryWriter(log_dir=str(tmp_path))
    for it in range(30):
        writer.add_scalar("episode/success", min(1.0, it / 20), it)
        writer.add_scalar("episode/return", 10.0 * it, it)
    writer.close()
    (tmp_path / "config.yaml").write_text("train:\n  num_envs: 4\n  steps_per_env: 8\n")
    scalars = load_scalars(tmp_path)
    assert len(scalars["episode/success"][0]) == 30
    out = plot_learning_curve(tmp_path, tmp_path / "curve.png")
    assert _is_png(out)


def test_success_by_distance_figure_and_command(tmp_path):
    """``mjnav plot distance`` writes the figure and prints the table; a missing file is an error."""
    import json

    from mjnav.verbs import plot

    rows = [{"start": [0.0, 0.0], "goal": [d, 0.0], "outcome": "success" if d < 5 else "collision"}
            for d in np.linspace(1.0, 9.0, 40)]
    (tmp_path / "a").mkdir()
    (tmp_path / "a" / "stage7.jsonl").write_text("\n".join(json.dumps(r) for r in rows))
    out = tmp_path / "d.png"
    assert plot.main(["distance", f"evals={tmp_path / 'a' / 'stage7.jsonl'}", f"out={out}"]) == 0
    assert _is_png(out)
    assert plot.main(["distance", f"evals={tmp_path / 'missing.jsonl'}"]) == 2
    assert plot.main(["distance", f"evals={tmp_path / 'a' / 'stage7.jsonl'}", "labels=A,B"]) == 2
    assert plot.main(["distance", f"evals={tmp_path / 'a' / 'stage7.jsonl'}", "edges=0,x"]) == 2
    (tmp_path / "a" / "stage6.jsonl").write_text((tmp_path / "a" / "stage7.jsonl").read_text())
    both = f"evals={tmp_path / 'a' / 'stage6.jsonl'},{tmp_path / 'a' / 'stage7.jsonl'}"
    assert plot.main(["distance", both, f"out={out}"]) == 0  # one folder: labelled a/stage6, a/stage7
