"""Observation layout against spec §6 on hand-built frames."""


import numpy as np
import pytest

from mjnav.tasks import observation as O


def _boundary(r: float = 2.0) -> np.ndarray:
    theta = np.linspace(0, 2 * np.pi, 60, endpoint=False)
    return np.stack([np.full(60, r), theta], axis=1)


def test_sizes() -> None:
    """A frame is 120 + 13 = 133 values and the 3-frame stack is 399."""
    assert O.observation_size() == 399
    assert O.polygon_block(_boundary(), 0.325).shape == (120,)


def test_polygon_block_encoding() -> None:
    """r̂ = clip((r+R)/10, 0, 1) and θ̂ = θ/2π, interleaved."""
    b = _boundary(2.0)
    b[3, 0] = 20.0
    block = O.polygon_block(b, 0.325)
    assert block[0] == pytest.approx(0.2325)
    assert block[6] == 1.0
    assert block[3] == pytest.approx(b[1, 1] / (2 * np.pi))


def test_state_block_at_reset() -> None:
    """At reset the point terms are 0 with distances R/10 and the angle uses the velocity heading."""
    s = O.state_block(np.zeros(2), np.array([1.0, 0.0]), np.array([0.0, 8.0]), True, None, 0.325)
    assert s[0] == pytest.approx(0.5)
    assert s[1] == pytest.approx(8.0 / 40)
    assert list(s[2:5]) == [0.4, 0.0, 1.0]
    assert list(s[5:7]) == [0.0, 0.0] and list(s[9:11]) == [0.0, 0.0]
    assert s[7] == s[8] == s[11] == s[12] == pytest.approx(0.0325)


def test_state_block_with_plan() -> None:
    """Point terms are polar angles/π and (distance + R)/10; dθ uses the MPC direction."""
    plan = O.Plan(q_s=np.array([0.0, 1.0]), q_l=np.array([-2.0, 0.0]), q1=np.array([1.0, 0.0]),
                  qn=np.array([3.0, 0.0]), q1_world=np.array([1.0, 0.0]), qn_world=np.array([3.0, 0.0]))
    s = O.state_block(np.zeros(2), np.zeros(2), np.array([1.0, 5.0]), False, plan, 0.325)
    assert s[0] == pytest.approx(0.5)  # MPC direction +x, Q*_1→goal +y
    assert s[4] == 0.0
    assert s[5] == pytest.approx(0.5) and s[6] == pytest.approx(1.0)
    assert s[7] == pytest.approx(0.1325) and s[8] == pytest.approx(0.2325)
    assert s[9] == 0.0 and s[10] == 0.0
    assert s[11] == pytest.approx(0.1325) and s[12] == pytest.approx(0.3325)
    paper = O.state_block(np.zeros(2), np.array([0.0, -1.0]), np.array([1.0, 0.0]), True, plan, 0.325, "velocity")
    assert paper[0] == pytest.approx(0.5)


def _turn(xy: np.ndarray, angle: float) -> np.ndarray:
    c, s = np.cos(angle), np.sin(angle)
    return np.array([c * xy[0] - s * xy[1], s * xy[0] + c * xy[1]])


def test_goal_frame_sees_a_turned_scene_the_same() -> None:
    """observation.frame='goal': a scene and the same scene turned about the robot give one frame."""
    rng = np.random.default_rng(3)
    theta = np.sort(rng.uniform(0, 2 * np.pi, 60))
    radius = rng.uniform(0.5, 6.0, 60)
    pts = [rng.normal(size=2) for _ in range(4)]
    velocity, goal = np.array([0.7, -0.4]), np.array([4.0, 1.5])
    blocks = []
    for turn in (0.0, 2.1):
        order = np.argsort(np.mod(theta + turn, 2 * np.pi), kind="stable")
        boundary = np.stack([radius[order], np.mod(theta + turn, 2 * np.pi)[order]], axis=1)
        q = [_turn(p, turn) for p in pts]
        plan = O.Plan(q_s=q[0], q_l=q[1], q1=q[2], qn=q[3], q1_world=q[2], qn_world=q[3])
        g = _turn(goal, turn)
        rotation = float(np.arctan2(g[1], g[0]))
        blocks.append(np.concatenate([
            O.polygon_block(boundary, 0.325, rotation),
            O.state_block(np.zeros(2), _turn(velocity, turn), g, True, plan, 0.325, "mpc", rotation),
        ]))
    np.testing.assert_allclose(blocks[0], blocks[1], atol=1e-9)
    assert blocks[0][1] == pytest.approx(blocks[0][1::2][:60].min())  # starts from the smallest turned angle
    world = O.state_block(np.zeros(2), velocity, goal, True, None, 0.325)
    assert np.hypot(*blocks[0][122:124]) == pytest.approx(np.hypot(*world[2:4]))


def test_stack_order_oldest_first() -> None:
    """The stack is [3 polygon blocks, 3 state blocks], oldest first, reset fills every slot."""
    stack = O.FrameStack(3, 60)
    poly = [np.full(120, k, dtype=float) for k in range(3)]
    state = [np.full(13, 10 + k, dtype=float) for k in range(3)]
    obs = stack.reset(poly[0], state[0])
    assert obs.dtype == np.float32 and obs.shape == (399,)
    assert np.all(obs[:360] == 0) and np.all(obs[360:] == 10)
    stack.push(poly[1], state[1])
    obs = stack.push(poly[2], state[2])
    assert [obs[k * 120] for k in range(3)] == [0, 1, 2]
    assert [obs[360 + k * 13] for k in range(3)] == [10, 11, 12]


def test_stack_with_a_stride_takes_frames_that_far_apart() -> None:
    """``stride`` 2: after reset (frame 0) and pushes 1..5 the stack holds frames 1, 3, 5; early on
    the reset frame fills the older slots."""
    stack = O.FrameStack(3, 60, stride=2)
    obs = stack.reset(np.zeros(120), np.full(13, 10.0))
    for k in range(1, 6):
        obs = stack.push(np.full(120, float(k)), np.full(13, 10.0 + k))
        if k == 1:
            assert [obs[j * 120] for j in range(3)] == [0, 0, 1]
    assert [obs[j * 120] for j in range(3)] == [1, 3, 5]
    assert [obs[360 + j * 13] for j in range(3)] == [11, 13, 15]
    assert obs.shape == (399,) and obs.dtype == np.float32


def test_frame_stride_is_a_task_option() -> None:
    """``task.observation.frame_stride`` reaches the environment's stack; 0 is a named error."""
    from mjnav.config import load_task
    from mjnav.schema import ConfigError

    assert load_task("stage5", ["observation.frame_stride=3"]).observation.frame_stride == 3
    with pytest.raises((ConfigError, ValueError), match="frame_stride"):
        load_task("stage5", ["observation.frame_stride=0"])


def _square_seen_from(position: np.ndarray, half: float = 2.0) -> tuple[np.ndarray, np.ndarray]:
    """A square region (world corners ±half) as a current boundary seen from ``position``:
    (60 (r, θ) points at uneven bearings, the square's world corners)."""
    corners = np.array([[half, half], [-half, half], [-half, -half], [half, -half]])
    theta = np.sort(np.random.default_rng(0).uniform(0, 2 * np.pi, 60))
    d = np.stack([np.cos(theta), np.sin(theta)], axis=1)
    with np.errstate(divide="ignore"):
        to_wall = (np.sign(d) * half - position) / d  # along each axis to the wall ahead
    r = np.nanmin(np.where(np.isfinite(to_wall), to_wall, np.nan), axis=1)
    return np.stack([r, theta], axis=1), corners


def test_aligned_block_reads_a_region_that_stayed_put_as_the_current_one() -> None:
    """A region that did not move in the world reads the same in an older slot as in the newest,
    wherever the robot stands inside it: only motion of the region itself changes r̂."""
    for position in (np.array([0.5, -0.3]), np.array([-1.2, 1.5])):
        boundary, corners = _square_seen_from(position)
        block = O.aligned_block(boundary, corners, position, 0.325, rotation=0.7)
        np.testing.assert_allclose(block, O.polygon_block(boundary, 0.325, rotation=0.7), atol=1e-9)
    boundary, corners = _square_seen_from(np.zeros(2))
    shifted = O.aligned_block(boundary, corners + [0.3, 0.0], np.zeros(2), 0.325)  # the region moved +x
    now = O.polygon_block(boundary, 0.325)
    east = np.cos(boundary[:, 1]) > 0.9  # bearings through the +x side (θ ascending: same order)
    assert east.any() and np.all(shifted[0::2][east] > now[0::2][east])
    np.testing.assert_array_equal(shifted[1::2], now[1::2])  # same bearings


def test_aligned_block_outside_the_older_region_reads_zero_extent() -> None:
    """A robot that has left the older region (or a degenerate one) sees r = 0 there (r̂ = R_inf/10)."""
    boundary, corners = _square_seen_from(np.array([0.0, 0.0]))
    far = O.aligned_block(boundary, corners + 10.0, np.zeros(2), 0.325)
    np.testing.assert_allclose(far[0::2], 0.0325)
    assert np.all(O.aligned_block(boundary, corners[:2], np.zeros(2), 0.325)[0::2] == 0.0325)


def test_aligned_history_in_the_environment() -> None:
    """``observation.history=aligned``: reset fills three equal blocks; later, every older block
    shares the newest block's bearings; a misspelt value is a named error."""
    import gymnasium as gym

    import mjnav  # noqa: F401  (registers the ids)
    from mjnav.config import load_task
    from mjnav.schema import ConfigError

    env = gym.make("mjnav/Stage5-v1", overrides=["observation.history=aligned", "observation.frame=goal"])
    obs, _ = env.reset(seed=1)
    blocks = obs[:360].reshape(3, 120)
    np.testing.assert_array_equal(blocks[0], blocks[2])
    for _ in range(5):
        obs, *_ = env.step(np.zeros(4))
    blocks = obs[:360].reshape(3, 120)
    np.testing.assert_array_equal(blocks[0, 1::2], blocks[2, 1::2])
    np.testing.assert_array_equal(blocks[1, 1::2], blocks[2, 1::2])
    assert not np.array_equal(blocks[0, 0::2], blocks[2, 0::2])
    env.close()
    with pytest.raises((ConfigError, ValueError), match="history"):
        load_task("stage5", ["observation.history=current"])
