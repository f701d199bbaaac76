"""The world the robot moves in: layouts, obstacle shapes and the pedestrians' motion models.

Pedestrian motion models are looked up by name in :data:`PEDESTRIAN_MODELS` (``crowd.model``).
A model is a :class:`~mjnav.world.crowd.PedestrianModel`; its factory is called with the task's
:class:`~mjnav.schema.CrowdConfig`. Outside packages add models through the entry-point group
``mjnav.pedestrian_models``; in one module::

    from mjnav.world import PEDESTRIAN_MODELS
    from mjnav.world.crowd import PedestrianModel

    @PEDESTRIAN_MODELS.register("still")
    class StandStill(PedestrianModel):
        ...

and ``crowd.model=still`` selects it.
"""

from __future__ import annotations

from mjnav.registry import Registry
from mjnav.schema import ConfigError, CrowdConfig
from mjnav.world.crowd import PedestrianModel, RandomWalkModel
from mjnav.world.orca import OrcaModel
from mjnav.world.social_force import SocialForceModel

__all__ = ["PEDESTRIAN_MODELS", "make_pedestrian_model"]

#: Pedestrian motion models by ``crowd.model`` name; a factory takes the CrowdConfig.
PEDESTRIAN_MODELS: Registry[PedestrianModel] = Registry("pedestrian model", "mjnav.pedestrian_models")


def _random_walk(config: CrowdConfig) -> RandomWalkModel:
    """The paper's random walk, with the crowd's yaw rate (rad/s) and yaw interval (s); it cannot
    react to the robot, so ``crowd.reactive=true`` is refused."""
    if config.reactive:
        raise ConfigError("crowd.reactive: the random walk cannot react to the robot "
                          "(crowd.model=social_force or crowd.model=orca can)")
    return RandomWalkModel(yaw_rate=config.yaw_rate, yaw_interval=config.yaw_interval)


def _social_force(config: CrowdConfig) -> SocialForceModel:
    """Social force, repelled by the robot unless ``crowd.reactive=false``."""
    model = SocialForceModel.from_config(config)
    if config.reactive is False:
        model.reacts_to_robot = False  # the simulation then advances it without the robot
    return model


def _orca(config: CrowdConfig) -> OrcaModel:
    """ORCA with ``crowd.orca``'s parameters; it avoids the robot only with ``crowd.reactive=true``."""
    return OrcaModel.from_config(config)


PEDESTRIAN_MODELS.register("random_walk", _random_walk, config=CrowdConfig, source="builtin")
PEDESTRIAN_MODELS.register("social_force", _social_force, config=CrowdConfig, source="builtin")
PEDESTRIAN_MODELS.register("orca", _orca, config=CrowdConfig, source="builtin")


def make_pedestrian_model(config: CrowdConfig) -> PedestrianModel:
    """The motion model named by ``config.model``, waiting for :meth:`PedestrianModel.reset`.

    Raises:
        ConfigError: An unknown name (the message lists the known ones and the closest).
    """
    if config.model not in PEDESTRIAN_MODELS:
        raise ConfigError(f"crowd.model: {PEDESTRIAN_MODELS.unknown_message(config.model)}")
    return PEDESTRIAN_MODELS.get(config.model).factory(config)
