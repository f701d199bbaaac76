"""Fingerprints of the compiled robot and pedestrian models (``python -m tests.entities.model_fingerprint record``).

A fingerprint is the sha256 over every array of a compiled ``mujoco.MjModel`` (sizes, names,
poses, masses, sensors, ...) in attribute order, so two builders that compile the same model give
the same digest. The recorded digests (``tests/data/model_fingerprints.json``) were made with the
Python builders before ``assets/robot.xml`` and ``assets/pedestrian.xml`` existed.
"""

from __future__ import annotations

import hashlib
import json
import sys
from pathlib import Path

import mujoco
import numpy as np
from dm_control import mjcf

from mjnav.entities.crowd import Pedestrian
from mjnav.entities.robot import OmniRobot
from mjnav.schema import LidarConfig, RobotConfig

RECORD = Path(__file__).parents[1] / "data" / "model_fingerprints.json"


def fingerprint(model: mujoco.MjModel) -> str:
    """sha256 over every numpy array attribute of ``model`` (name-sorted) and its size fields."""
    digest = hashlib.sha256()
    for name in sorted(dir(model)):
        if name.startswith("_"):
            continue
        value = getattr(model, name, None)
        if isinstance(value, np.ndarray):
            digest.update(name.encode())
            digest.update(np.ascontiguousarray(value).tobytes())
        elif isinstance(value, (int, np.integer)) and name.startswith("n"):
            digest.update(f"{name}={int(value)}".encode())
    return digest.hexdigest()


def _compiled(entity: object) -> mujoco.MjModel:
    return mjcf.Physics.from_mjcf_model(entity.mjcf_model).model.ptr  # type: ignore[attr-defined]


def cases() -> dict[str, mujoco.MjModel]:
    """The models whose fingerprints are recorded: default and varied robots, two pedestrians."""
    return {
        "robot-default": _compiled(OmniRobot(RobotConfig(), LidarConfig())),
        "robot-no-rangefinders": _compiled(OmniRobot(RobotConfig(), LidarConfig(), rangefinders=False)),
        "robot-varied": _compiled(OmniRobot(RobotConfig(radius=0.3, mass=12.0, height=0.4, force_max=150.0),
                                            LidarConfig(beams=90, height=0.25), name="bot")),
        "pedestrian-default": _compiled(Pedestrian(0.4, 1.7, name="ped_07")),
        "pedestrian-small": _compiled(Pedestrian(0.15, 1.2)),
    }


if __name__ == "__main__" and sys.argv[1:] == ["record"]:
    RECORD.write_text(json.dumps({k: fingerprint(m) for k, m in cases().items()}, indent=1, sort_keys=True) + "\n")
    print(RECORD.read_text())
