"""Stage config loading, validation and overrides."""

from pathlib import Path

import pytest

from mjnav.config import ConfigError, TaskConfig, load_task, task_dir
from mjnav.schema import apply_overrides, from_dict, to_dict

SPEC_TABLE = {  # stage: (interior, static, dynamic, radius range, speed range) from spec §9
    "stage1": ((20.0, 30.0), 0, 0, None, None),
    "stage2": ((20.0, 30.0), 10, 0, None, None),
    "stage3": ((20.0, 30.0), 10, 5, (0.2, 0.3), (0.3, 0.3)),
    "stage4": ((20.0, 30.0), 10, 10, (0.2, 0.3), (0.3, 0.3)),
    "stage5": ((10.0, 10.0), 0, 10, (0.1, 0.4), (0.3, 0.6)),
    "stage6": ((10.0, 10.0), 0, 20, (0.1, 0.4), (0.3, 0.6)),
    "stage7": ((10.0, 10.0), 0, 30, (0.1, 0.4), (0.3, 0.6)),
}


@pytest.mark.parametrize("name", sorted(SPEC_TABLE))
def test_stage_matches_spec_table(name: str) -> None:
    """Every bundled stage loads and matches the paper's stage table."""
    size, static, dynamic, radius, speed = SPEC_TABLE[name]
    cfg = load_task(name)
    assert cfg.name == name
    assert cfg.arena.size == size
    assert cfg.obstacles.count == static
    assert cfg.crowd.count == dynamic
    if dynamic:
        assert cfg.crowd.radius == radius and cfg.crowd.speed == speed
    assert cfg.timing.control_period == 0.1 and cfg.timing.episode_steps == 300
    assert cfg.lidar.beams == 360 and cfg.lidar.max_range == 10.0


def test_unknown_key_in_file_names_key_and_file(tmp_path: Path) -> None:
    """An unknown key fails at load with its dotted path and the file name."""
    bad = tmp_path / "bad.yaml"
    bad.write_text("crowd:\n  cont: 3\n")
    with pytest.raises(ConfigError, match=r"bad\.yaml: crowd\.cont: unknown key"):
        load_task(bad)


def test_bad_value_names_key_and_file(tmp_path: Path) -> None:
    """A value failing validation names the key and the file."""
    bad = tmp_path / "neg.yaml"
    bad.write_text("crowd:\n  count: -1\n")
    with pytest.raises(ConfigError, match=r"neg\.yaml: crowd\.count: must be >= 0"):
        load_task(bad)


def test_wrong_type_rejected(tmp_path: Path) -> None:
    """A string where a number is expected is rejected, not coerced."""
    bad = tmp_path / "typ.yaml"
    bad.write_text("timing:\n  substeps: five\n")
    with pytest.raises(ConfigError, match=r"timing\.substeps: expected an integer"):
        load_task(bad)


def test_literal_choice_rejected() -> None:
    """An option outside its allowed set is rejected with the choices listed."""
    with pytest.raises(ConfigError, match=r"crowd\.model.*random_walk"):
        load_task("stage6", ["crowd.model=teleport"])


def test_dotted_overrides_apply() -> None:
    """Dotted overrides change exactly the named values."""
    cfg = load_task("stage6", ["crowd.count=25", "lidar.backend=mujoco", "crowd.speed=[0.2, 0.5]"])
    assert cfg.crowd.count == 25
    assert cfg.lidar.backend == "mujoco"
    assert cfg.crowd.speed == (0.2, 0.5)
    assert load_task("stage6").crowd.count == 20


def test_unknown_override_rejected() -> None:
    """An override naming an unknown key is rejected with the key."""
    with pytest.raises(ConfigError, match=r"crowd\.counts"):
        load_task("stage6", ["crowd.counts=3"])


def test_unknown_task_lists_known() -> None:
    """Asking for a missing stage lists the known ones."""
    with pytest.raises(ConfigError, match="stage1"):
        load_task("stage99")


def test_extends_one_level_only(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """A file extending a file that itself extends is rejected."""
    (tmp_path / "a.yaml").write_text("extends: stage6\n")
    (tmp_path / "b.yaml").write_text("extends: a\n")
    monkeypatch.setattr("mjnav.config.task_dir", lambda: tmp_path)
    with pytest.raises(ConfigError, match="one level"):
        load_task("b")


def test_config_is_frozen_and_roundtrips() -> None:
    """Configs are immutable and survive a dict round trip through overrides."""
    cfg = load_task("stage3")
    with pytest.raises(AttributeError):
        cfg.crowd.count = 3  # type: ignore[misc]
    flat = to_dict(cfg)
    assert flat["crowd"]["radius"] == [0.2, 0.3]
    assert apply_overrides(TaskConfig(), {"name": "stage3", **flat}) == cfg


def test_bundled_stage_dir_has_seven_stages() -> None:
    """The stage folder ships stage1..stage7."""
    assert sorted(p.stem for p in task_dir().glob("stage*.yaml")) == [f"stage{i}" for i in range(1, 8)]


def test_action_layer_limits_follow_robot_and_timing() -> None:
    """Robot limits, control period and LiDAR range flow into the MPC, action and region configs."""
    cfg = load_task("stage6", ["robot.v_max=2.0", "robot.j_max=6.0", "timing.control_period=0.05"])
    assert cfg.mpc.v_max == 2.0 and cfg.mpc.j_max == 6.0 and cfg.action.jerk_max == 6.0
    assert cfg.mpc.t_c == 0.05 and cfg.action.t_c == 0.05
    assert load_task("stage6", ["lidar.max_range=8.0"]).region.max_range == 8.0


def test_conflicting_copy_of_a_limit_is_rejected() -> None:
    """Setting the MPC's copy of a robot limit to another value names both keys."""
    with pytest.raises(ConfigError, match=r"mpc\.v_max.*robot\.v_max"):
        load_task("stage6", ["mpc.v_max=3.0"])


def test_source_can_change_again_after_derivation() -> None:
    """A derived copy follows its source through repeated overrides and a saved-config round trip."""
    cfg = apply_overrides(load_task("stage6", ["robot.v_max=2.0"]), ["robot.v_max=3.0"])
    assert cfg.mpc.v_max == 3.0
    assert apply_overrides(cfg, ["robot.v_max=2.5", "timing.control_period=0.05"]).mpc.t_c == 0.05
    assert from_dict(TaskConfig, to_dict(cfg)) == cfg


def test_long_term_reach_time_is_the_mpc_horizon() -> None:
    """action.long_time follows mpc.horizon × control period (1 s by default, 3 s at N = 30)."""
    assert load_task("stage6").action.long_time == pytest.approx(1.0)
    assert load_task("stage6", ["mpc.horizon=30"]).action.long_time == pytest.approx(3.0)


@pytest.mark.parametrize(("override", "message"), [
    ("region.inflation=0.1", r"region\.inflation.*robot\.radius"),
    ("lidar.beams=30", r"lidar\.beams"),
    ("reward.feasibility_clip=-1", r"feasibility_clip"),
    ("reward.collision=30", r"collision"),
    ("layout.free_clearance=-0.5", r"free_clearance"),
    ("layout.start_goal_max_distance=0.5", r"start_goal_max_distance"),
])
def test_inconsistent_values_rejected(override: str, message: str) -> None:
    """Values that would make the task silently wrong are rejected at load with the key."""
    with pytest.raises(ConfigError, match=message):
        load_task("stage6", [override])


def test_bad_task_files_are_config_errors(tmp_path: Path) -> None:
    """An empty, unparsable or missing task file is a ConfigError naming the file, not defaults or a YAML traceback."""
    empty, broken = tmp_path / "empty.yaml", tmp_path / "broken.yaml"
    empty.write_text("")
    broken.write_text("arena: {size: [10, ")
    with pytest.raises(ConfigError, match="empty task file"):
        load_task(empty)
    with pytest.raises(ConfigError, match="broken.yaml: not valid YAML"):
        load_task(broken)
    with pytest.raises(ConfigError, match="does not exist"):
        load_task(tmp_path / "missing.yaml")


def test_exponent_floats_are_numbers() -> None:
    """``1e-4`` (a string to YAML 1.1) is accepted for float fields; other strings and nan are not."""
    assert load_task("stage1", ["timing.control_period=1e-1"]).timing.control_period == pytest.approx(0.1)
    for bad in ("1e-1x", "nan", "inf"):
        with pytest.raises(ConfigError, match="finite number"):
            load_task("stage1", [f"timing.control_period={bad}"])
