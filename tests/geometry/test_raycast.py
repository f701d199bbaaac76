"""Tests for the analytic 2-D ray caster."""

from __future__ import annotations

import math

import numpy as np
import pytest

from mjnav.geometry.raycast import (
    add_noise,
    beam_angles,
    cast_rays,
    cast_rays_kernel,
    cast_uniform_rays_kernel,
    polygon_segments,
    wall_segments,
)

NO_SEGMENTS = np.zeros((0, 4))
NO_CIRCLES = np.zeros((0, 3))


def _reference(origin, angles, segments, circles, max_range):
    """Slow pure-Python ray caster (same conventions) used as ground truth."""
    out = []
    for a in angles:
        d = (math.cos(a), math.sin(a))
        best = max_range
        for x0, y0, x1, y1 in segments:
            e = (x1 - x0, y1 - y0)
            w = (x0 - origin[0], y0 - origin[1])
            den = d[0] * e[1] - d[1] * e[0]
            if den == 0.0:
                continue
            t = (w[0] * e[1] - w[1] * e[0]) / den
            u = (w[0] * d[1] - w[1] * d[0]) / den
            if t >= 0 and 0 <= u <= 1:
                best = min(best, t)
        for cx, cy, r in circles:
            f = (origin[0] - cx, origin[1] - cy)
            b = f[0] * d[0] + f[1] * d[1]
            disc = b * b - (f[0] ** 2 + f[1] ** 2 - r * r)
            if disc < 0:
                continue
            roots = [t for t in (-b - math.sqrt(disc), -b + math.sqrt(disc)) if t >= 0]
            if roots:
                best = min(best, roots[0])
        out.append(best)
    return np.array(out)


def test_beam_angles_start_along_x_and_go_ccw():
    """Beam 0 points along +x, beam 90 along +y, 1° apart for 360 beams."""
    angles = beam_angles(360)
    assert angles.shape == (360,)
    assert angles[0] == 0.0
    np.testing.assert_allclose(np.diff(angles), np.deg2rad(1.0))
    ranges = cast_rays(np.zeros(2), angles, wall_segments((20.0, 30.0)), None, 40.0)
    assert ranges[0] == pytest.approx(10.0) and ranges[90] == pytest.approx(15.0)
    assert ranges[180] == pytest.approx(10.0) and ranges[270] == pytest.approx(15.0)


def test_wall_segments_are_inner_faces_ccw():
    """Wall segments trace the interior rectangle counter-clockwise from the bottom-left corner."""
    walls = wall_segments((4.0, 6.0))
    expected = [[-2, -3, 2, -3], [2, -3, 2, 3], [2, 3, -2, 3], [-2, 3, -2, -3]]
    np.testing.assert_array_equal(walls, expected)


def test_wall_distance_matches_analytic_value():
    """A 30° ray from (1, 2) to the x = 10 wall travels 9 / cos 30°."""
    origin = np.array([1.0, 2.0])
    ranges = cast_rays(origin, np.array([np.pi / 6]), wall_segments((20.0, 30.0)), None, 50.0)
    assert ranges[0] == pytest.approx(9.0 / math.cos(np.pi / 6), rel=1e-12)


def test_cylinder_distance_matches_analytic_value():
    """A ray offset by h from a circle's centre line hits at d - sqrt(r² - h²)."""
    circles = np.array([[5.0, 0.3, 0.5]])
    ranges = cast_rays(np.zeros(2), np.array([0.0]), None, circles, 10.0)
    assert ranges[0] == pytest.approx(5.0 - math.sqrt(0.25 - 0.09), rel=1e-12)


def test_polygon_edge_distance_matches_analytic_value():
    """A ray along +y hits the square's bottom edge at y = 2."""
    square = np.array([[-1.0, 2.0], [1.0, 2.0], [1.0, 4.0], [-1.0, 4.0]])
    ranges = cast_rays(np.zeros(2), np.array([np.pi / 2]), polygon_segments([square]), None, 10.0)
    assert ranges[0] == pytest.approx(2.0, rel=1e-12)


def test_polygon_segments_close_each_polygon():
    """Each n-gon gives n edges, the last one back to its first vertex."""
    tri = np.array([[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]])
    segments = polygon_segments([tri, tri + 5.0])
    assert segments.shape == (6, 4)
    np.testing.assert_array_equal(segments[2], [0.0, 1.0, 0.0, 0.0])
    assert polygon_segments([]).shape == (0, 4)


def test_no_hit_reads_max_range():
    """Rays that miss everything, or hit beyond max_range, read max_range."""
    angles = beam_angles(8)
    assert np.all(cast_rays(np.zeros(2), angles, None, None, 10.0) == 10.0)
    far = cast_rays(np.zeros(2), angles, wall_segments((40.0, 40.0)), np.array([[0.0, 15.0, 1.0]]), 10.0)
    assert np.all(far == 10.0)


def test_objects_behind_the_origin_are_not_hit():
    """A circle behind the ray (t < 0) is ignored."""
    ranges = cast_rays(np.zeros(2), np.array([0.0]), None, np.array([[-3.0, 0.0, 1.0]]), 10.0)
    assert ranges[0] == 10.0


def test_origin_inside_circle_reads_exit_distance():
    """A ray starting inside a circle reads the exit point (MuJoCo mj_ray convention)."""
    circles = np.array([[0.1, 0.0, 0.5]])
    ranges = cast_rays(np.zeros(2), np.array([0.0, np.pi]), None, circles, 10.0)
    np.testing.assert_allclose(ranges, [0.6, 0.4], rtol=1e-12)


def test_matches_mujoco_mj_ray():
    """Readings equal MuJoCo's mj_ray for walls, a cylinder and a start inside a cylinder."""
    mujoco = pytest.importorskip("mujoco")
    xml = """<mujoco><worldbody>
      <geom type="box" size="0.05 5 1" pos="4.05 0 1"/>
      <geom type="cylinder" size="0.5 1" pos="0 2 1"/>
      <geom type="cylinder" size="0.4 1" pos="-2 -2 1"/>
    </worldbody></mujoco>"""
    model = mujoco.MjModel.from_xml_string(xml)
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    segments = np.array([[4.0, -5.0, 4.0, 5.0]])
    circles = np.array([[0.0, 2.0, 0.5], [-2.0, -2.0, 0.4]])
    geom = np.zeros(1, np.int32)
    for origin in (np.array([0.2, -0.3]), np.array([-2.1, -1.9])):
        angles = beam_angles(72)
        ours = cast_rays(origin, angles, segments, circles, 10.0)
        for angle, reading in zip(angles, ours):
            direction = np.array([math.cos(angle), math.sin(angle), 0.0])
            dist = mujoco.mj_ray(model, data, np.array([*origin, 0.5]), direction, None, 1, -1, geom)
            assert reading == pytest.approx(10.0 if dist < 0 or dist > 10 else dist, abs=1e-9)


def test_agrees_with_python_reference_on_random_scenes():
    """The jitted caster equals the pure-Python reference on 20 random scenes."""
    rng = np.random.default_rng(7)
    angles = beam_angles(90)
    for _ in range(20):
        segments = np.vstack([wall_segments((12.0, 8.0)), rng.uniform(-5.0, 5.0, (12, 4))])
        circles = np.column_stack([rng.uniform(-5.0, 5.0, (8, 2)), rng.uniform(0.1, 0.6, 8)])
        origin = rng.uniform(-3.0, 3.0, 2)
        ours = cast_rays(origin, angles, segments, circles, 6.0)
        np.testing.assert_allclose(ours, _reference(origin, angles, segments, circles, 6.0), atol=1e-12)


@pytest.mark.parametrize("beams", [8, 90, 360, 361, 1000])
def test_uniform_kernel_reads_exactly_what_the_general_one_reads(beams: int) -> None:
    """Culling circles by angle changes no reading, bit for bit: circles near, far, tangent to
    beams, overlapping each other, and containing or touching the origin."""
    rng = np.random.default_rng(beams)
    angles = beam_angles(beams)
    cos_a, sin_a = np.cos(angles), np.sin(angles)
    segments = wall_segments((20.0, 20.0))
    for _ in range(40):
        origin = rng.uniform(-2.0, 2.0, 2)
        centres = origin + rng.uniform(-9.0, 9.0, (30, 2))
        radii = rng.uniform(0.05, 1.5, 30)
        near = origin + np.array([[0.3, 0.0], [0.0, -0.2], [1.0, 1.0]])  # contains / touches / tangent
        circles = np.vstack([np.column_stack([centres, radii]),
                             np.column_stack([near, [0.5, 0.2, math.sqrt(0.5)]])])
        general = cast_rays_kernel(origin[0], origin[1], cos_a, sin_a, segments, circles, 10.0)
        uniform = cast_uniform_rays_kernel(origin[0], origin[1], cos_a, sin_a, segments, circles, 10.0)
        np.testing.assert_array_equal(uniform, general)
        assert (uniform < 10.0).any()


def test_rejects_badly_shaped_inputs():
    """Segments that are not (S, 4) raise ValueError."""
    with pytest.raises(ValueError, match="segments"):
        cast_rays(np.zeros(2), beam_angles(8), np.zeros((3, 3)), NO_CIRCLES, 10.0)


def test_noise_is_clipped_to_sensor_range():
    """Noisy readings stay in [0, max_range] and are noisy in between."""
    ranges = np.array([0.0, 0.01, 5.0, 9.99, 10.0] * 200)
    noisy = add_noise(ranges, 0.05, 10.0, np.random.default_rng(0))
    assert noisy.min() >= 0.0 and noisy.max() <= 10.0
    assert np.std(noisy[2::5] - 5.0) == pytest.approx(0.05, rel=0.2)
    assert np.any(noisy[0::5] == 0.0) and np.any(noisy[4::5] == 10.0)


def test_noise_is_deterministic_and_consumes_one_draw_per_beam():
    """Same seed gives the same noise; std 0 leaves ranges unchanged but still draws."""
    ranges = np.linspace(0.0, 10.0, 360)
    a = add_noise(ranges, 0.05, 10.0, np.random.default_rng(3))
    b = add_noise(ranges, 0.05, 10.0, np.random.default_rng(3))
    np.testing.assert_array_equal(a, b)
    rng = np.random.default_rng(3)
    np.testing.assert_array_equal(add_noise(ranges, 0.0, 10.0, rng), ranges)
    reference = np.random.default_rng(3)
    reference.normal(size=360)
    assert rng.random() == reference.random()


def test_empty_scene_uses_no_segments_constant():
    """Explicit empty arrays behave like None."""
    angles = beam_angles(16)
    explicit = cast_rays(np.zeros(2), angles, NO_SEGMENTS, NO_CIRCLES, 3.0)
    np.testing.assert_array_equal(explicit, cast_rays(np.zeros(2), angles, None, None, 3.0))


def test_noise_equals_clipped_sum_in_one_and_two_dimensions():
    """add_noise is exactly min(max(ranges + N(0, std²), 0), max_range), for a scan and for a batch."""
    rng_ranges = np.random.default_rng(5)
    for shape in ((360,), (4, 90)):
        ranges = rng_ranges.uniform(-0.5, 10.5, shape)
        noisy = add_noise(ranges, 0.3, 10.0, np.random.default_rng(7))
        draw = np.random.default_rng(7).normal(0.0, 0.3, size=shape)
        np.testing.assert_array_equal(noisy, np.minimum(np.maximum(draw + ranges, 0.0), 10.0))
        assert noisy.shape == shape
