"""The robot's limits are written once (:class:`mjnav.control.dynamics.Limits`) and the MPC, its QP,
the action layer and the task read them from there."""

from __future__ import annotations

import dataclasses

import numpy as np

from mjnav.config import TaskConfig
from mjnav.control.action import ActionConfig
from mjnav.control.dynamics import Limits
from mjnav.control.mpc import Mpc, MpcConfig
from mjnav.geometry.region import RegionConfig
from mjnav.schema import LidarConfig, RobotConfig, TimingConfig


def test_limits_defaults_are_the_task_schema_defaults() -> None:
    """Limits() equals the limits of a default task, and the MPC and action defaults follow it."""
    assert Limits() == Limits.from_task(TaskConfig())
    robot, timing = RobotConfig(), TimingConfig()
    assert (Limits().v_max, Limits().a_max, Limits().j_max) == (robot.v_max, robot.a_max, robot.j_max)
    assert Limits().control_period == timing.control_period
    assert Limits().inflation == RegionConfig().inflation and Limits().max_range == LidarConfig().max_range
    assert MpcConfig().limits == Limits()
    assert (ActionConfig().jerk_max, ActionConfig().t_c) == (Limits().j_max, Limits().control_period)


def test_bounds_are_in_the_qp_order() -> None:
    """Limits.bounds() is [j_max, v_max, a_max], the order the QP kernels read."""
    np.testing.assert_array_equal(Limits(v_max=1.0, a_max=2.0, j_max=3.0).bounds(), [3.0, 1.0, 2.0])


def test_mpc_plans_within_the_task_robot_limits() -> None:
    """A robot override reaches the MPC through MpcConfig.limits, bit for bit."""
    config = TaskConfig(robot=dataclasses.replace(RobotConfig(), v_max=1.7, a_max=3.1, j_max=6.3))
    mpc = Mpc(config.mpc)
    assert mpc.limits == dataclasses.replace(Limits(), v_max=1.7, a_max=3.1, j_max=6.3)
    assert dataclasses.replace(Limits.from_task(config), radius=Limits.radius, inflation=Limits.inflation,
                               max_range=Limits.max_range) == mpc.limits
    np.testing.assert_array_equal(mpc._limits, [6.3, 1.7, 3.1])
