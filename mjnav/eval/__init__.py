"""Evaluation: per-episode metrics, policy loading, the held-out runner, rendering and plots.

Only :mod:`mjnav.eval.metrics` is imported here (pure numpy); the other modules pull in
MuJoCo, torch or matplotlib and are imported explicitly.
"""

from mjnav.eval.metrics import EpisodeMetrics, aggregate, episode_metrics, format_markdown, write_csv

__all__ = ["EpisodeMetrics", "aggregate", "episode_metrics", "format_markdown", "write_csv"]
