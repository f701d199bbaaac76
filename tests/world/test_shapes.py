"""Tests for the obstacle shape bank."""

from __future__ import annotations

import numpy as np
import pytest

from mjnav.schema import ObstacleConfig
from mjnav.world.shapes import ShapeBank, make_shape_bank, polygon_area

CONFIG = ObstacleConfig(count=10, bank_size=64, bank_seed=5, circumradius=1.0, min_area=0.3, max_area=2.0)


@pytest.fixture(scope="module")
def bank() -> ShapeBank:
    return make_shape_bank(CONFIG)


def test_bank_has_half_triangles_half_quadrilaterals(bank):
    """The bank alternates triangles and quadrilaterals: 32 of each for 64 shapes."""
    assert len(bank) == 64 and bank.vertices.shape == (64, 4, 2)
    np.testing.assert_array_equal(bank.counts, [3, 4] * 32)


def test_vertices_lie_on_the_circumcircle(bank):
    """Every vertex (padding included) is at the circumradius from the local origin."""
    np.testing.assert_allclose(np.linalg.norm(bank.vertices, axis=-1), 1.0, rtol=1e-12)


def test_polygons_are_convex_and_ccw(bank):
    """Every turn of every polygon is strictly to the left (convex, counter-clockwise)."""
    for i in range(len(bank)):
        poly = bank.polygon(i)
        edges = np.roll(poly, -1, axis=0) - poly
        nxt = np.roll(edges, -1, axis=0)
        turns = edges[:, 0] * nxt[:, 1] - edges[:, 1] * nxt[:, 0]
        assert np.all(turns > 0.0), i


def test_triangle_padding_repeats_the_last_vertex(bank):
    """A triangle's fourth row repeats its third vertex; polygon() drops it."""
    assert bank.polygon(0).shape == (3, 2)
    np.testing.assert_array_equal(bank.vertices[0, 3], bank.vertices[0, 2])


def test_areas_are_in_range(bank):
    """Every shape's area lies in [min_area, max_area] and matches a shapely polygon."""
    shapely = pytest.importorskip("shapely.geometry")
    areas = bank.areas
    assert np.all(areas >= CONFIG.min_area) and np.all(areas <= CONFIG.max_area)
    for i in range(len(bank)):
        assert shapely.Polygon(bank.polygon(i)).area == pytest.approx(areas[i], rel=1e-12)


def test_tight_area_bounds_are_respected():
    """A narrow area window is met by every shape."""
    config = ObstacleConfig(bank_size=20, bank_seed=1, min_area=0.8, max_area=1.0)
    areas = make_shape_bank(config).areas
    assert np.all((areas >= 0.8) & (areas <= 1.0))


def test_bank_is_deterministic_in_bank_seed(bank):
    """The same bank_seed gives the same bank; another seed gives a different one."""
    again = make_shape_bank(CONFIG)
    np.testing.assert_array_equal(again.vertices, bank.vertices)
    other = make_shape_bank(ObstacleConfig(bank_seed=6))
    assert not np.array_equal(other.vertices, bank.vertices)


def test_bank_ignores_global_random_state():
    """Seeding numpy's global state does not change the bank."""
    np.random.seed(0)
    a = make_shape_bank(CONFIG)
    np.random.seed(1)
    b = make_shape_bank(CONFIG)
    np.testing.assert_array_equal(a.vertices, b.vertices)


def test_bank_arrays_are_read_only(bank):
    """The shared bank cannot be mutated in place."""
    with pytest.raises(ValueError):
        bank.vertices[0, 0, 0] = 1.0


def test_impossible_area_bounds_raise():
    """Triangles cannot reach 1.5 m² on a unit circle: ValueError names the bounds."""
    with pytest.raises(ValueError, match="area"):
        make_shape_bank(ObstacleConfig(bank_size=2, min_area=1.5, max_area=2.0))


def test_polygon_area_sign():
    """Counter-clockwise vertices give a positive area, clockwise a negative one."""
    square = np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]])
    assert polygon_area(square) == pytest.approx(1.0)
    assert polygon_area(square[::-1]) == pytest.approx(-1.0)
