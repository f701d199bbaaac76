"""The one command line (``mjnav <verb>``, :mod:`mjnav.args`): help, key forms, unknown keys, the resume hint."""

from __future__ import annotations

import dataclasses
import os
import re
import runpy
import shlex
import signal
import subprocess
import sys
import time
from pathlib import Path

import gymnasium as gym
import pytest

import mjnav  # noqa: F401 - registers the Gymnasium ids
from mjnav import cli
from mjnav.args import Grammar, attribute_docs, parse
from mjnav.config import TASK_SECTIONS
from mjnav.schema import ConfigError
from tests._scripts import ROOT

ENV = {**os.environ, "PYTHONPATH": os.pathsep.join(filter(None, [str(ROOT), os.environ.get("PYTHONPATH")]))}


def _leaves(verbs: dict[str, cli.Verb] = cli.VERBS) -> list[tuple[list[str], cli.Verb]]:
    """Every runnable verb with the words that call it."""
    out = []
    for name, verb in verbs.items():
        out += [([name, *w], v) for w, v in _leaves(verb.subverbs)] if verb.subverbs else [([name], verb)]
    return out


def test_mjnav_help_lists_the_verbs(capsys: pytest.CaptureFixture[str]) -> None:
    """``mjnav --help`` exits 0 and names every verb; an unknown verb is exit 2 with the closest."""
    assert cli.main(["--help"]) == 0
    text = capsys.readouterr().out
    assert all(verb in text for verb in ("train", "evaluate", "render", "export", "tables", "plot", "demo", "bench"))
    assert cli.main(["trian"]) == 2
    assert "did you mean 'train'" in capsys.readouterr().err


@pytest.mark.parametrize("words,verb", [pytest.param(w, v, id="-".join(w)) for w, v in _leaves()])
def test_every_verb_help_names_every_key(words: list[str], verb: cli.Verb, capsys) -> None:
    """``mjnav <verb> --help`` and ``-h`` exit 0 and name every key the verb accepts, with its doc line."""
    grammar = cli._load(verb.grammar)()
    for flag in ("--help", "-h"):
        assert cli.main([*words, flag]) == 0
        text = capsys.readouterr().out
        docs = attribute_docs(grammar.options)
        for field in dataclasses.fields(grammar.options):
            assert re.search(rf"^  {field.name}=", text, re.MULTILINE), field.name
            assert docs.get(field.name), f"{grammar.options.__name__}.{field.name} is undocumented"
        assert all(f"  {alias}=" in text for alias in grammar.aliases)
        assert all(f"{prefix}." in text for prefix in grammar.prefixes)


@pytest.mark.parametrize("script", sorted((ROOT / "scripts").glob("*.py")), ids=lambda p: p.name)
def test_every_script_answers_help(script: Path, monkeypatch: pytest.MonkeyPatch, capsys) -> None:
    """``python scripts/<name>.py --help`` exits 0 with a usage line (run in-process as ``__main__``)."""
    monkeypatch.setattr(sys, "argv", [str(script), "--help"])
    with pytest.raises(SystemExit) as done:
        runpy.run_path(str(script), run_name="__main__")
    assert done.value.code == 0
    assert capsys.readouterr().out.startswith("usage: ")


def test_scripts_and_python_m_answer_help_from_a_shell() -> None:
    """``python -m mjnav --help``, ``python -m mjnav export -h`` and ``python scripts/bench_sim.py --help``
    exit 0 with a usage line in a fresh interpreter."""
    commands = [["-m", "mjnav", "--help"], ["-m", "mjnav", "export", "-h"], ["scripts/bench_sim.py", "--help"]]
    procs = [subprocess.Popen([sys.executable, *c], cwd=ROOT, env=ENV, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                              text=True) for c in commands]
    for proc in procs:
        out, err = proc.communicate(timeout=300)
        assert proc.returncode == 0 and out.startswith("usage: "), (proc.args, err[-2000:])
    assert len(list((ROOT / "scripts").glob("*.py"))) >= 15


def test_script_keys_are_checked() -> None:
    """A reliability script answers an unknown key with its own keys and the closest one (exit 2)."""
    done = subprocess.run([sys.executable, "scripts/fuzz.py", "sed=1"], cwd=ROOT, env=ENV, capture_output=True,
                          text=True, timeout=300)
    assert done.returncode == 2 and "unknown key 'sed'" in done.stderr and "did you mean 'seed'" in done.stderr


def test_short_and_long_task_keys_mean_the_same_in_every_verb(tmp_path: Path) -> None:
    """``crowd.count=25`` and ``task.crowd.count=25`` give the same overrides in train, evaluate, render,
    export and gym.make."""
    from mjnav.eval.runner import parse_args as evaluate_args
    from mjnav.train.session import parse_args as train_args

    for form in ("crowd.count=25", "task.crowd.count=25"):
        assert train_args(["task=stage1", form]).task_overrides == ("crowd.count=25",)
        assert evaluate_args(["policy=mpc_goal", form])[0][0].overrides == ("crowd.count=25",)
        leaves = {" ".join(words): verb for words, verb in _leaves()}
        for verb in ("render", "export", "demo", "plot episode", "plot compare", "bench throughput"):
            assert parse([form], cli._load(leaves[verb].grammar)()).task == ("crowd.count=25",)
        env = gym.make("mjnav/Stage1-v1", overrides=[form])
        assert env.unwrapped.config.crowd.count == 25
        env.close()
    scenes = []
    for i, form in enumerate(("crowd.count=3", "task.crowd.count=3")):
        out = tmp_path / str(i)
        assert cli.main(["export", "task=stage1", "seed=2", "steps=3", f"out={out}", form]) == 0
        scenes.append((out / "scene.xml").read_bytes())
    assert scenes[0] == scenes[1] and b"ped_02" in scenes[0]


def test_unknown_keys_are_named_with_the_known_ones_and_the_closest(capsys: pytest.CaptureFixture[str]) -> None:
    """A verb key typo lists the verb's keys (not config sections); a section typo lists the sections."""
    assert cli.main(["export", "sed=7"]) == 2
    err = capsys.readouterr().err
    assert "unknown key 'sed'" in err and "seed=" in err and "steps=" in err and "did you mean 'seed'" in err
    assert "crowd" not in err
    assert cli.main(["export", "crwd.count=7"]) == 2
    err = capsys.readouterr().err
    assert "'crwd'" in err and "did you mean 'crowd.count'" in err and "steps" not in err
    assert cli.main(["export", "task=stage1", "task.crowd.cont=7"]) == 2  # found when the task loads
    assert "did you mean 'count'" in capsys.readouterr().err
    assert cli.main(["export", "collision=scan"]) == 2
    assert "task.collision=scan" in capsys.readouterr().err
    assert cli.main(["tables", "crowd.count=3"]) == 2
    assert "takes no config overrides" in capsys.readouterr().err
    assert cli.main(["render", "width=wide"]) == 2
    assert "width: expected an integer, got 'wide'" in capsys.readouterr().err
    assert cli.main(["export", "seed"]) == 2
    assert "argument 'seed': expected key=value" in capsys.readouterr().err
    with pytest.raises(ConfigError, match="did you mean 'crowd'"):
        gym.make("mjnav/Stage1-v1", overrides=["task.crwd.count=3"])


def test_seed_alias_and_text_values() -> None:
    """``seed=`` in train stands for ``train.seed=``; a str key keeps its text (``out=2024``)."""
    args = parse(["seed=3", "out=2024"], Grammar(cli._load(cli.VERBS["train"].grammar)().options, ("task", "train"),
                                                 {"seed": "train.seed"}, TASK_SECTIONS))
    assert args.train == ("seed=3",) and args.options.out == "2024"


def test_help_lists_a_config_section(capsys: pytest.CaptureFixture[str]) -> None:
    """``--help task.crowd`` (or ``crowd``) lists the section's keys with defaults; ``train.policy`` the
    PPO networks; ``planner.dwa`` a planner's parameters; an unknown section is exit 2 with the closest."""
    for topic in ("task.crowd", "crowd"):
        assert cli.main(["evaluate", "--help", topic]) == 0
        text = capsys.readouterr().out
        assert "task.crowd.count=0" in text and "task.crowd.model=random_walk" in text and "Pedestrians" in text
    assert cli.main(["train", "--help", "train.policy"]) == 0
    assert "train.policy." in capsys.readouterr().out
    assert cli.main(["evaluate", "--help", "planner.dwa"]) == 0
    assert "planner.w_clearance=" in capsys.readouterr().out
    assert cli.main(["export", "--help", "task.crwd"]) == 2
    assert "did you mean task.crowd" in capsys.readouterr().err


def test_ctrl_c_hint_resumes_as_printed(tmp_path: Path) -> None:
    """After Ctrl-C the printed ``<python> -m mjnav train resume=RUN`` runs as printed and finishes the run."""
    argv = [sys.executable, "-m", "mjnav", "train", "task=stage1", "start=scratch", "train.iterations=6",
            "train.num_envs=2", "train.steps_per_env=8", "train.minibatches=1", "train.epochs=1", "train.workers=0",
            "train.save_interval=50", f"out={tmp_path}"]
    log = tmp_path / "log.txt"
    with open(log, "w") as stream:
        proc = subprocess.Popen(argv, cwd=tmp_path, env=ENV, stdout=stream, stderr=subprocess.STDOUT)
    end = time.monotonic() + 300
    while not re.search(r"\] it 1/", log.read_text()) and proc.poll() is None and time.monotonic() < end:
        time.sleep(0.05)
    proc.send_signal(signal.SIGINT)
    assert proc.wait(timeout=300) == 0, log.read_text()[-2000:]
    hint = re.search(r"^continue with: (.+)$", log.read_text(), re.MULTILINE)
    assert hint, log.read_text()[-2000:]
    command = shlex.split(hint.group(1))
    assert command[:4] == [sys.executable, "-m", "mjnav", "train"]
    done = subprocess.run(command, cwd=tmp_path, env=ENV, capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr[-2000:]
    assert (Path(command[4].removeprefix("resume=")) / "policy.pt").is_file()
