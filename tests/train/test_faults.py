"""Training survives SIGKILL: checkpoints are written atomically and ``resume=`` loses at most one
save interval (the full 5-kill run is ``scripts/kill_resume.py``, reported in docs/reliability.md)."""

from __future__ import annotations

import random
import sys
from pathlib import Path

import pytest
import torch

from mjnav.train.runner import checkpoints
from tests._scripts import ROOT, load_script

kill_resume = load_script("kill_resume")


def test_atomic_checkpoint_leaves_no_partial_file(tmp_path: Path) -> None:
    """A finished save leaves only ``model_<it>.pt``; a stray ``.partial`` is never listed as a checkpoint."""
    (tmp_path / "model_3.pt.partial").write_bytes(b"truncated")
    torch.save({"x": 1}, tmp_path / "model_2.pt")
    assert [p.name for p in checkpoints(tmp_path)] == ["model_2.pt"]


@pytest.mark.skipif(sys.platform == "win32", reason="SIGKILL")
def test_sigkill_at_random_moments_then_resume(tmp_path: Path) -> None:
    """Two kills of a tiny stage-1 run at random moments: each resume starts from the last
    checkpoint, which loads, and is at most one save interval behind the last logged iteration."""
    report = kill_resume.run(kills=2, out=tmp_path, rng=random.Random(7), iterations=12, save_interval=2,
                             python=sys.executable, cwd=ROOT)
    assert report["finished"], report
    for kill in report["kills"]:
        assert kill["lost_iterations"] <= 2, kill
    assert report["final_checkpoint"] == "model_11.pt"
