"""assets/robot.xml and assets/pedestrian.xml: standalone MJCF that the builders load unchanged."""

from __future__ import annotations

import json

import mujoco
import pytest

from mjnav.resources import asset
from tests.entities.model_fingerprint import RECORD, cases, fingerprint


@pytest.mark.parametrize("name", ["robot.xml", "pedestrian.xml"])
def test_asset_loads_in_plain_mujoco(name: str) -> None:
    """Each asset compiles with mujoco.MjModel.from_xml_path alone."""
    model = mujoco.MjModel.from_xml_path(str(asset(name)))
    assert model.ngeom == 1


def test_robot_asset_has_360_rangefinders() -> None:
    """The robot file carries the 360 beams (sites and rangefinder sensors) and two force motors."""
    model = mujoco.MjModel.from_xml_path(str(asset("robot.xml")))
    assert (model.nsite, model.nsensor, model.nu, model.njnt) == (360, 360, 2, 2)
    assert all(t == mujoco.mjtSensor.mjSENS_RANGEFINDER for t in model.sensor_type)


def test_builders_compile_the_recorded_models() -> None:
    """The robot and pedestrian built from the assets compile to the models the Python builders made."""
    recorded = json.loads(RECORD.read_text())
    assert {name: fingerprint(model) for name, model in cases().items()} == recorded


def test_unknown_asset_is_named() -> None:
    """Asking for a missing asset names it and the known ones."""
    with pytest.raises(FileNotFoundError, match="robot.xml"):
        asset("robots.xml")
