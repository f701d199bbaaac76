"""An outside planner for mjnav: head for the goal, slower where the scan sees little free space.

Evaluate, render and plot it without installing anything::

    mjnav evaluate task=stage5 policy=docs/examples/goal_seeker.py:GoalSeeker episodes=20
    mjnav render task=stage5 policy=docs/examples/goal_seeker.py:GoalSeeker planner.speed=1.2
    mjnav plot episode task=stage5 policy=docs/examples/goal_seeker.py:GoalSeeker

Each control step it picks a desired velocity towards the goal (``speed``, lower when the beams
around the goal direction are short), turns the velocity error into a desired acceleration
(time constant ``tau``) and returns the jerk that reaches it over ``tau_accel``. It reads only what
a robot measures (no ``privileged`` ground truth).
"""

from __future__ import annotations

import dataclasses

import numpy as np


@dataclasses.dataclass(frozen=True)
class GoalSeekerConfig:
    """Parameters (``planner.<field>=value`` on the command line).

    Attributes:
        speed: Cruise speed towards the goal, m/s.
        clearance: Free range along the goal direction below which it slows down, metres.
        cone: Half-width of the beam cone around the goal direction, radians.
        tau: Time constant from velocity error to desired acceleration, seconds.
        tau_accel: Time constant from acceleration error to jerk, seconds.
    """

    speed: float = 1.0
    clearance: float = 1.5
    cone: float = 0.3
    tau: float = 0.5
    tau_accel: float = 0.2

    def __post_init__(self) -> None:
        """Reject non-positive values."""
        for name, value in dataclasses.asdict(self).items():
            if not value > 0.0:
                raise ValueError(f"{name}: must be > 0, got {value}")


class GoalSeeker:
    """A :class:`mjnav.planners.base.Planner`: reset once per episode, act once per control step."""

    config_class = GoalSeekerConfig  # planner.<field>=value sets its fields
    privileged: frozenset[str] = frozenset()  # reads no ground truth

    def __init__(self, config: GoalSeekerConfig | None = None) -> None:
        """``config``: its parameters (defaults when None)."""
        self.config = config or GoalSeekerConfig()
        self.stats = {"slowed": 0}  # integer counters, recorded per episode as planner_stats
        self._period = 0.1

    def reset(self, config, rng: np.random.Generator) -> None:
        """Start an episode of task ``config`` (a mjnav.config.TaskConfig); ``rng`` is its own stream."""
        del rng  # deterministic
        self._period = config.timing.control_period

    def act(self, inp) -> np.ndarray:
        """The jerk (2,), m/s³, world frame, for the next control period."""
        to_goal = inp.goal - inp.position
        distance = float(np.hypot(*to_goal))
        if distance < 1e-6:
            return -inp.acceleration / self.config.tau_accel
        heading = np.arctan2(to_goal[1], to_goal[0])
        gap = np.abs(np.angle(np.exp(1j * (inp.angles - heading))))
        free = float(inp.scan[gap <= self.config.cone].min(initial=np.inf))
        scale = min(1.0, free / self.config.clearance, distance / (self.config.speed * self.config.tau))
        if scale < 1.0:
            self.stats["slowed"] += 1
        desired_velocity = to_goal / distance * self.config.speed * scale
        desired_accel = (desired_velocity - inp.velocity) / self.config.tau
        return (desired_accel - inp.acceleration) / self.config.tau_accel
