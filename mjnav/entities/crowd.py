"""``Crowd``: mocap-driven pedestrian cylinders in fixed slots (spec §9).

Each slot is a :class:`Pedestrian` entity attached to the arena through an attachment frame
with ``frame.mocap = True`` (a mocap body inside an attached model does not compile). Slots
are compiled at the largest radius of the config, so the compiled bounding volumes hold for
every episode; per episode the radius is written by binding (``geom_size``, ``geom_rbound``,
``geom_aabb``) and positions go straight to ``data.mocap_pos`` through cached mocap ids.
Unused slots are parked far below the floor (no collision, invisible to horizontal rays).
"""

from __future__ import annotations

from collections.abc import Iterable

import numpy as np
from dm_control import composer, mjcf

from mjnav.entities.arena import PARK_DEPTH
from mjnav.resources import asset
from mjnav.schema import CrowdConfig

__all__ = ["Crowd", "Pedestrian"]


class Pedestrian(composer.Entity):
    """One pedestrian: a vertical cylinder standing on the floor (geom ``body``, ``assets/pedestrian.xml``)."""

    def _build(self, radius: float, height: float, name: str = "ped") -> None:
        """Builds the MJCF.

        Args:
            radius: Compiled radius, metres (the largest the slot will take).
            height: Cylinder height, metres.
            name: MJCF model name (``ped_07``).
        """
        self._mjcf_root = mjcf.from_path(str(asset("pedestrian.xml")))
        self._mjcf_root.model = name
        self._geom = self._mjcf_root.find("geom", "body")
        self._geom.size = (radius, height / 2)
        self._geom.pos = (0, 0, height / 2)

    @property
    def mjcf_model(self) -> mjcf.RootElement:
        """The pedestrian's MJCF root."""
        return self._mjcf_root

    @property
    def geom(self) -> mjcf.Element:
        """The cylinder geom."""
        return self._geom


class Crowd:
    """``CrowdConfig.num_slots`` pedestrian slots attached to an arena as mocap bodies."""

    def __init__(self, config: CrowdConfig) -> None:
        """Builds the slot entities (attach them with :meth:`attach_to`).

        Args:
            config: Slot count, radius range (the maximum is compiled) and height, metres.
        """
        self._config = config
        self._height = float(config.height)
        self._pedestrians = [Pedestrian(config.radius[1], config.height, name=f"ped_{i:02d}")
                             for i in range(config.num_slots)]
        self._frames: list[mjcf.Element] = []
        self._cache_model = None
        self._active = 0

    def attach_to(self, arena: composer.Arena) -> None:
        """Attaches every slot to ``arena`` through a mocap attachment frame, parked."""
        if self._frames:
            raise RuntimeError("the crowd is already attached")
        for i, ped in enumerate(self._pedestrians):
            frame = arena.attach(ped)
            frame.mocap = True
            frame.pos = _park_position(i)
            self._frames.append(frame)

    # ------------------------------------------------------------------ properties
    @property
    def num_slots(self) -> int:
        """Compiled pedestrian slots."""
        return len(self._pedestrians)

    @property
    def pedestrians(self) -> list[Pedestrian]:
        """The slot entities."""
        return list(self._pedestrians)

    @property
    def frames(self) -> list[mjcf.Element]:
        """The mocap attachment frames (bodies), one per slot."""
        return list(self._frames)

    @property
    def geoms(self) -> list[mjcf.Element]:
        """The cylinder geoms, one per slot."""
        return [ped.geom for ped in self._pedestrians]

    @property
    def active(self) -> int:
        """Slots in use this episode (the first ``active`` ones)."""
        return self._active

    # ------------------------------------------------------------------ runtime
    def _bind(self, physics: mjcf.Physics) -> None:
        model = physics.model.ptr
        if self._cache_model is model:
            return
        if self._pedestrians:
            self._mocap_ids = np.asarray(physics.bind(self._frames).mocapid, dtype=np.int64)
            self._geom_ids = np.asarray(physics.bind(self.geoms).element_id, dtype=np.int64)
        else:
            self._mocap_ids = self._geom_ids = np.zeros(0, np.int64)
        self._cache_model = model

    def mocap_ids(self, physics: mjcf.Physics) -> np.ndarray:
        """(slots,) mocap indices of the slots in ``physics``."""
        self._bind(physics)
        return self._mocap_ids

    def geom_ids(self, physics: mjcf.Physics) -> np.ndarray:
        """(slots,) geom ids of the slot cylinders in ``physics``."""
        self._bind(physics)
        return self._geom_ids

    def set_radii(self, physics: mjcf.Physics, radii: np.ndarray) -> None:
        """Activates the first ``len(radii)`` slots with these radii (metres), parks the rest."""
        self._bind(physics)
        radii = np.asarray(radii, dtype=np.float64).reshape(-1)
        if len(radii) > self.num_slots:
            raise ValueError(f"{len(radii)} pedestrians do not fit {self.num_slots} slots")
        if np.any(radii <= 0) or np.any(radii > self._config.radius[1] + 1e-12):
            raise ValueError(f"radii must lie in (0, {self._config.radius[1]}] m (the compiled maximum)")
        model = physics.model.ptr
        n, half = len(radii), self._height / 2
        ids = self._geom_ids[:n]
        model.geom_size[ids, 0] = radii
        model.geom_rbound[ids] = np.sqrt(radii**2 + half**2)
        model.geom_aabb[ids, 3] = radii
        model.geom_aabb[ids, 4] = radii
        physics.data.ptr.mocap_pos[self._mocap_ids[:n], 2] = 0.0
        self._active = n
        self.park(physics, range(n, self.num_slots))

    def park(self, physics: mjcf.Physics, slots: Iterable[int]) -> None:
        """Moves the given slots far below the floor."""
        self._bind(physics)
        slots = np.asarray(list(slots), dtype=np.int64)
        if slots.size:
            physics.data.ptr.mocap_pos[self._mocap_ids[slots]] = np.stack([_park_position(i) for i in slots])

    def set_positions(self, physics: mjcf.Physics, positions: np.ndarray) -> None:
        """Writes (n, 2) centres (metres) of the first n active slots to ``mocap_pos``."""
        self._bind(physics)
        physics.data.ptr.mocap_pos[self._mocap_ids[: len(positions)], :2] = positions


def _park_position(slot: int) -> np.ndarray:
    return np.array([3.0 * slot, 10.0, -PARK_DEPTH])
