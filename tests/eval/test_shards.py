"""Shards of an evaluation (``shard=i/n``) merge into exactly the unsharded evaluation (``merge=``),
and the merge refuses overlapping or disagreeing shards."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import pytest

from mjnav.cli import main
from mjnav.eval.runner import EvalError, EvalSpec, evaluate_tasks, parse_args, parse_shard, read_jsonl
from mjnav.eval.shards import merge

from tests.eval._same import records, summary

OVERRIDES = ("timing.episode_steps=20",)
EPISODES = 5


def _spec(**kw) -> EvalSpec:
    return EvalSpec("stage5", "mpc_goal", EPISODES, 0, OVERRIDES, 1, **kw)


@pytest.fixture(scope="module")
def runs(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    """The unsharded evaluation and its 2 shards (one folder, as a job array writes them)."""
    whole, shards = tmp_path_factory.mktemp("whole"), tmp_path_factory.mktemp("shards")
    evaluate_tasks([_spec()], whole, progress=False)
    for first in range(2):
        evaluate_tasks([_spec(shard=(first, 2))], shards, progress=False)
    return {"whole": whole, "shards": shards}


def test_shards_play_their_indices_with_the_whole_runs_seeds(runs) -> None:
    names = sorted(p.name for p in runs["shards"].iterdir())
    assert names == ["stage5.shard-0-of-2.jsonl", "stage5.shard-1-of-2.jsonl", "summary.shard-0-of-2.csv",
                     "summary.shard-0-of-2.md", "summary.shard-1-of-2.csv", "summary.shard-1-of-2.md"]
    whole = {r["index"]: r for r in records(runs["whole"] / "stage5.jsonl")}
    for first in range(2):
        path = runs["shards"] / f"stage5.shard-{first}-of-2.jsonl"
        assert [r["shard"] for r in read_jsonl(path)] == [f"{first}/2"] * len(range(first, EPISODES, 2))
        mine = records(path, drop=("shard",))
        assert [r["index"] for r in mine] == list(range(first, EPISODES, 2))
        assert mine == [whole[r["index"]] for r in mine]


def test_merged_shards_equal_the_unsharded_evaluation(runs, tmp_path, capsys) -> None:
    out = tmp_path / "merged"
    assert main(["evaluate", f"merge={runs['shards']}", f"out={out}"]) == 0
    assert "| stage5 |" in capsys.readouterr().out
    # the shards' records, byte for byte, less their shard field, in index order
    pieces = [r for k in range(2) for r in read_jsonl(runs["shards"] / f"stage5.shard-{k}-of-2.jsonl")]
    expected = sorted(({k: v for k, v in r.items() if k != "shard"} for r in pieces), key=lambda r: r["index"])
    assert read_jsonl(out / "stage5.jsonl") == expected
    # the unsharded evaluation's records and summary (solve times are measured on the clock)
    assert records(out / "stage5.jsonl") == records(runs["whole"] / "stage5.jsonl")
    assert summary(out / "summary.csv") == summary(runs["whole"] / "summary.csv")
    # merging into the shards' own folder, twice, reads the shards again (not the merged file)
    for _ in range(2):
        merge([runs["shards"]], runs["shards"])
    assert read_jsonl(runs["shards"] / "stage5.jsonl") == expected


def _shard_copy(runs, tmp_path: Path, first: int, edit=None) -> Path:
    """A copy of shard ``first`` in its own folder, each record passed through ``edit``."""
    folder = tmp_path / f"s{first}"
    folder.mkdir(exist_ok=True)
    name = f"stage5.shard-{first}-of-2.jsonl"
    records = read_jsonl(runs["shards"] / name)
    (folder / name).write_text("".join(json.dumps(edit(r) if edit else r) + "\n" for r in records))
    return folder


@pytest.mark.parametrize(("field", "value", "named"), [
    ("commit", "0" * 40, "commit"),
    ("policy_sha256", "feedface", "policy_sha256"),
    ("overrides", ["timing.episode_steps=30"], "overrides"),
    ("task_version", 99, "task_version"),
    ("planner_sha256", "beef", "planner_sha256"),
])
def test_disagreeing_shards_are_refused(runs, tmp_path, capsys, field, value, named) -> None:
    good = _shard_copy(runs, tmp_path, 0)
    bad = _shard_copy(runs, tmp_path, 1, lambda r: {**r, field: value})
    assert main(["evaluate", f"merge={good},{bad}", f"out={tmp_path / 'm'}"]) == 2
    err = capsys.readouterr().err
    assert err.startswith("error: merge:") and named in err and str(bad) in err
    assert not (tmp_path / "m" / "stage5.jsonl").exists()


def test_overlapping_missing_and_foreign_are_refused(runs, tmp_path) -> None:
    zero = _shard_copy(runs, tmp_path, 0)
    with pytest.raises(EvalError, match="episode 0 of stage5 is in .*s0.* and in .*shards.*overlapping"):
        merge([zero, runs["shards"]], tmp_path / "m")
    not_shards = "whole.* and .*s0.* are not shards of one evaluation .*shard_count: 2 there, 1 here"
    with pytest.raises(EvalError, match=not_shards):
        merge([zero, runs["whole"]], tmp_path / "m")
    with pytest.raises(EvalError, match=r"lacks 2 of its 5 episodes \(1, 3\): shard 0/2 has 3 of 3, "
                                        r"shard 1/2 has 0 of 2"):
        merge([zero], tmp_path / "m")
    with pytest.raises(EvalError, match="named twice"):
        merge([zero, zero / "stage5.shard-0-of-2.jsonl"], tmp_path / "m")
    with pytest.raises(EvalError, match="seed_offset"):
        merge([zero, _shard_copy(runs, tmp_path, 1, lambda r: {**r, "seed": r["seed"] + 7})], tmp_path / "m")
    other = tmp_path / "other"
    shutil.copytree(runs["whole"], other)
    (other / "stage5.jsonl").write_text(json.dumps({**read_jsonl(other / "stage5.jsonl")[0], "outcome": "x"}) + "\n")
    before = (other / "stage5.jsonl").read_text()
    with pytest.raises(EvalError, match="not among the merged ones"):
        merge([runs["shards"]], other)
    assert (other / "stage5.jsonl").read_text() == before


def test_unfinished_shards_are_refused_and_episodes_merges_the_first(runs, tmp_path, capsys) -> None:
    """Shards cut short (a killed job) cannot pass for a smaller evaluation: the records carry the
    evaluation's episode count; ``episodes=N`` merges the first N, saying what it leaves out."""
    cut = [_shard_copy(runs, tmp_path, k) for k in range(2)]
    for k, folder in enumerate(cut):
        path = folder / f"stage5.shard-{k}-of-2.jsonl"
        path.write_text("".join(line + "\n" for line in path.read_text().splitlines()[:1]))  # episodes 0 and 1
    assert {r["planned_episodes"] for r in read_jsonl(runs["whole"] / "stage5.jsonl")} == {EPISODES}
    with pytest.raises(EvalError, match=r"lacks 3 of its 5 episodes \(2, 3, 4\): shard 0/2 has 1 of 3, "
                                        r"shard 1/2 has 1 of 2"):
        merge(cut, tmp_path / "m")
    assert main(["evaluate", f"merge={runs['shards']}", "episodes=2", f"out={tmp_path / 'first'}"]) == 0
    assert "stage5: 3 records past episode 1 are left out" in capsys.readouterr().out
    assert records(tmp_path / "first" / "stage5.jsonl") == records(runs["whole"] / "stage5.jsonl")[:2]
    assert main(["evaluate", f"merge={cut[0]},{cut[1]}", "episodes=2", f"out={tmp_path / 'cut'}"]) == 0
    assert summary(tmp_path / "cut" / "summary.csv") == summary(tmp_path / "first" / "summary.csv")
    # records made before planned_episodes existed: the count is the largest index + 1, as then
    (tmp_path / "old").mkdir()
    unplanned = lambda r: {key: v for key, v in r.items() if key != "planned_episodes"}  # noqa: E731
    old = [_shard_copy(runs, tmp_path / "old", k, unplanned) for k in range(2)]
    merge(old, tmp_path / "old" / "m")
    merged = read_jsonl(tmp_path / "old" / "m" / "stage5.jsonl")
    assert [r["index"] for r in merged] == list(range(EPISODES)) and "planned_episodes" not in merged[0]


def test_a_shard_file_resumes_and_refuses_another_shard(runs, tmp_path) -> None:
    folder = _shard_copy(runs, tmp_path, 1)
    (folder / "stage5.shard-1-of-2.jsonl").rename(folder / "stage5.shard-0-of-2.jsonl")
    with pytest.raises(EvalError, match="shard"):
        evaluate_tasks([_spec(shard=(0, 2))], folder, progress=False)


def test_shard_and_backend_arguments() -> None:
    assert parse_shard("3/4") == (3, 4)
    for bad in ("4/4", "-1/2", "1", "a/b", "1/0"):
        with pytest.raises(ValueError, match="shard: expected i/n"):
            parse_shard(bad)
    specs, _, _ = parse_args(["policy=mpc_goal", "shard=1/3", "episodes=7", "workers=1"])
    assert specs[0].shard == (1, 3) and specs[0].indices == [1, 4]
    with pytest.raises(ValueError, match="backend"):
        parse_args(["policy=mpc_goal", "backend=slurm"])
    with pytest.raises(ValueError, match="address.*backend=ray"):
        parse_args(["policy=mpc_goal", "address=auto"])


def test_merge_takes_only_merge_out_and_episodes(runs, capsys) -> None:
    assert main(["evaluate", f"merge={runs['shards']}", "workers=3"]) == 2
    assert "takes only merge=, out= and episodes=, got workers" in capsys.readouterr().err
    assert main(["evaluate", f"merge={runs['shards']}", "episodes=0"]) == 2
    assert "episodes must be >= 1" in capsys.readouterr().err
