"""Bank of static obstacle shapes: convex triangles and quadrilaterals on a circle (spec §9).

Every shape lives in a local frame whose origin is the centre of its circumscribed circle
(radius ``ObstacleConfig.circumradius``); vertices are counter-clockwise. The bank depends only
on the :class:`~mjnav.schema.ObstacleConfig` (``bank_seed`` seeds it), so all environments of a
task share it and an episode only picks bank indices and poses. The circle centre need not lie
inside the polygon (vertices may fall within a half circle).
"""

from __future__ import annotations

import dataclasses

import numpy as np

from mjnav.schema import ObstacleConfig

__all__ = ["ShapeBank", "make_shape_bank", "polygon_area"]

# Upper bound on draws per shape before a config is declared impossible.
_MAX_DRAWS_PER_SHAPE = 10_000


def polygon_area(vertices: np.ndarray) -> float:
    """Signed shoelace area, m² (positive for counter-clockwise vertices).

    Args:
        vertices: (n, 2) polygon vertices, metres.
    """
    x, y = vertices[:, 0], vertices[:, 1]
    return 0.5 * float(np.dot(x, np.roll(y, -1)) - np.dot(np.roll(x, -1), y))


@dataclasses.dataclass(frozen=True, eq=False)
class ShapeBank:
    """Obstacle shapes in their local frames (read-only arrays).

    Attributes:
        vertices: (B, 4, 2) float64 counter-clockwise vertices on the circumcircle, metres.
            Triangles are padded: row 3 repeats row 2 (a zero-length edge).
        counts: (B,) int64 vertex counts, 3 or 4.
        circumradius: Radius of the circle every vertex lies on, metres.
    """

    vertices: np.ndarray
    counts: np.ndarray
    circumradius: float

    def __post_init__(self) -> None:
        for array in (self.vertices, self.counts):
            array.flags.writeable = False

    def __len__(self) -> int:
        return int(self.counts.shape[0])

    def polygon(self, index: int) -> np.ndarray:
        """(n, 2) counter-clockwise vertices of shape ``index`` without padding, metres."""
        return self.vertices[index, : self.counts[index]]

    @property
    def areas(self) -> np.ndarray:
        """(B,) polygon areas, m²."""
        return np.array([polygon_area(self.polygon(i)) for i in range(len(self))])


def _draw_polygon(n: int, radius: float, rng: np.random.Generator) -> np.ndarray:
    """(n, 2) CCW vertices at sorted uniform angles on a circle (always convex)."""
    angles = np.sort(rng.uniform(0.0, 2.0 * np.pi, size=n))
    return radius * np.column_stack([np.cos(angles), np.sin(angles)])


def _draw_accepted(n: int, config: ObstacleConfig, rng: np.random.Generator) -> np.ndarray:
    """Redraw an n-gon until its area is in [min_area, max_area] (and > 0)."""
    for _ in range(_MAX_DRAWS_PER_SHAPE):
        polygon = _draw_polygon(n, config.circumradius, rng)
        area = polygon_area(polygon)
        if area > 0.0 and config.min_area <= area <= config.max_area:
            return polygon
    raise ValueError(
        f"make_shape_bank: no {n}-gon on a circle of radius {config.circumradius} m with area in "
        f"[{config.min_area}, {config.max_area}] m² after {_MAX_DRAWS_PER_SHAPE} draws"
    )


def make_shape_bank(config: ObstacleConfig) -> ShapeBank:
    """Draw the task's obstacle shape bank.

    Shapes alternate triangle, quadrilateral, triangle, ... (so half of each, the extra one a
    triangle for odd sizes). Each has vertices at sorted uniform random angles on the
    circumcircle and is redrawn until its area lies in ``[min_area, max_area]``. Only
    ``config.bank_seed`` seeds the draw (``np.random.default_rng``).

    Args:
        config: Obstacle config (``bank_size``, ``bank_seed``, ``circumradius``, area bounds).

    Returns:
        The bank of ``config.bank_size`` shapes.

    Raises:
        ValueError: If the area bounds admit (almost) no triangle or quadrilateral; e.g. a
            triangle on a unit circle has area at most 3√3/4 ≈ 1.30 m².
    """
    rng = np.random.default_rng(config.bank_seed)
    counts = np.array([3 + i % 2 for i in range(config.bank_size)], dtype=np.int64)
    vertices = np.empty((config.bank_size, 4, 2), dtype=np.float64)
    for i, n in enumerate(counts):
        polygon = _draw_accepted(int(n), config, rng)
        vertices[i, :n] = polygon
        vertices[i, n:] = polygon[-1]
    return ShapeBank(vertices=vertices, counts=counts, circumradius=float(config.circumradius))
