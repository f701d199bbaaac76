"""The ``mjnav`` command: ``mjnav <verb> key=value ...`` (console script, ``python -m mjnav`` and the
thin ``scripts/*.py`` wrappers).

Every verb takes the one grammar of :mod:`mjnav.args`; ``mjnav <verb> --help`` lists its keys with
defaults (generated from its options dataclass) and ``mjnav <verb> --help task.crowd`` a config
section's. Bad input prints one ``error: ...`` line and returns exit code 2; success returns 0.

The grammar and the run function of each verb are named as ``module:attribute`` and imported
only when that verb runs, so ``mjnav --help`` does not import MuJoCo or torch. Argument parsing
uses the standard library (:mod:`mjnav.args`): tyro, Hydra and OmegaConf each bring their own
syntax (``--key value``, ``+key=``) and error texts, where mjnav's ``key=value`` grammar and its
config loader's messages (the key's dotted path, the known keys, the closest one) are the contract.
"""

from __future__ import annotations

import dataclasses
import importlib
import sys
import typing
from collections.abc import Callable, Mapping, Sequence
from typing import Any

from mjnav.args import HELP_FLAGS, PREFIXES, Grammar, Parsed, closest, describe_fields, parse
from mjnav.registry import RegistryError
from mjnav.schema import ConfigError

__all__ = ["VERBS", "Verb", "evaluate", "export", "help_text", "main", "render", "run_script", "run_verb",
           "section_help", "train"]

#: ``run(parsed, argv) -> exit code`` of a verb.
Runner = Callable[[Parsed, list[str]], int]


@dataclasses.dataclass(frozen=True)
class Verb:
    """One command of ``mjnav``.

    Attributes:
        name: The words that call it (``train``, ``plot episode``).
        summary: One line for ``mjnav --help``.
        grammar: ``module:function`` returning its :class:`mjnav.args.Grammar`, or that function.
        run: ``module:function`` (or the function) run as ``run(parsed, argv)``; returns the exit code.
        subverbs: Sub-commands by name (``mjnav bench sim``); then ``grammar`` and ``run`` are unused.
    """

    name: str
    summary: str
    grammar: str | Callable[[], Grammar] = ""
    run: str | Runner = ""
    subverbs: Mapping[str, Verb] = dataclasses.field(default_factory=dict)


def _load(ref: str | Callable[..., Any]) -> Callable[..., Any]:
    if callable(ref):
        return ref
    module, _, attr = ref.partition(":")
    return getattr(importlib.import_module(module), attr)


def _verb(name: str, summary: str, module: str) -> Verb:
    """A verb whose module holds ``grammar()`` and ``run(parsed, argv)``."""
    return Verb(name, summary, f"{module}:grammar", f"{module}:run")


VERBS: dict[str, Verb] = {
    "train": _verb("train", "Train a policy with PPO (rsl-rl); a run folder per run; data-parallel under "
                   "`torchrun --nproc_per_node=N -m mjnav train`.", "mjnav.verbs.train"),
    "evaluate": _verb("evaluate", "Evaluate a policy on held-out scenarios; JSONL, CSV and a table.",
                      "mjnav.verbs.evaluate"),
    "render": _verb("render", "Render one episode off-screen to MP4 with the action layer drawn in.",
                    "mjnav.verbs.render"),
    "export": _verb("export", "Export one episode as a standalone MuJoCo scene plus pedestrian trajectories.",
                    "mjnav.verbs.export"),
    "tables": _verb("tables", "Regenerate a table of the paper from held-out evaluations.", "mjnav.verbs.tables"),
    "plot": Verb("plot", "Figures: an episode's paths, policies side by side, learning curves, success by distance.",
                 subverbs={
                     "episode": Verb("plot episode", "One episode's paths (and planned regions).",
                                     "mjnav.verbs.plot:episode_grammar", "mjnav.verbs.plot:episode"),
                     "compare": Verb("plot compare", "One row per task, one column per policy, same scenario.",
                                     "mjnav.verbs.plot:compare_grammar", "mjnav.verbs.plot:compare"),
                     "curve": Verb("plot curve", "Learning curves of a run folder.",
                                   "mjnav.verbs.plot:curve_grammar", "mjnav.verbs.plot:curve"),
                     "distance": Verb("plot distance", "Success by start-goal distance of evaluation records.",
                                      "mjnav.verbs.plot:distance_grammar", "mjnav.verbs.plot:distance"),
                 }),
    "sweep": _verb("sweep", "A grid of training runs (overrides x seeds), each evaluated; one table over seeds.",
                   "mjnav.verbs.sweep"),
    "demo": _verb("demo", "Drive one episode with the convex-MPC planner, report it, export the world.",
                  "mjnav.verbs.demo"),
    "bench": Verb("bench", "Speed benchmarks.", subverbs={
        "throughput": _verb("bench throughput", "Environment and adapter steps/s with a per-part breakdown.",
                            "mjnav.bench.throughput"),
        "collect": _verb("bench collect", "PPO collection steps/s for 1, 2, ... workers, with where each step goes.",
                         "mjnav.bench.collect"),
        "crowd": _verb("bench crowd", "Pedestrian models' cost per control step and ORCA's contacts.",
                       "mjnav.bench.crowd"),
        "tracker": _verb("bench tracker", "LiDAR pedestrian tracker vs ground truth per stage.", "mjnav.bench.tracker"),
        "sim": _verb("bench sim", "NavSim build, reset and control-step times per LiDAR backend.", "mjnav.bench.sim"),
        "action_layer": _verb("bench action_layer", "Region, action mapping and MPC latencies vs the authors'.",
                              "mjnav.bench.action_layer"),
        "evalscale": _verb("bench evalscale", "Held-out evaluation episodes/s with 1 and N workers (Ray or local).",
                           "mjnav.bench.evalscale"),
    }),
}


def _error(err: Exception) -> int:
    print(f"error: {err}", file=sys.stderr)
    return 2


def main(argv: Sequence[str] | None = None) -> int:
    """``mjnav <verb> [sub-verb] key=value ...``; returns the exit code."""
    args = list(sys.argv[1:] if argv is None else argv)
    verbs, prog = VERBS, "mjnav"
    while True:
        if not args or args[0] in HELP_FLAGS:
            print(_verbs_help(prog, verbs))
            return 0 if args else 2
        if args[0] not in verbs:
            near = closest(args[0], verbs)
            hint = f"; did you mean {near!r}?" if near else ""
            return _error(ConfigError(f"unknown command {args[0]!r} (known: {', '.join(verbs)}){hint}"))
        verb, args = verbs[args[0]], args[1:]
        if not verb.subverbs:
            return run_verb(verb, args, prog)
        verbs, prog = verb.subverbs, f"{prog} {verb.name.split()[-1]}"


def run_verb(verb: Verb, argv: Sequence[str], prog: str = "mjnav") -> int:
    """Answer ``--help [TOPIC]`` or parse ``argv`` by the verb's grammar and run it."""
    argv = list(argv)
    grammar = _load(verb.grammar)()
    for i, token in enumerate(argv):
        if token in HELP_FLAGS:
            topic = argv[i + 1] if i + 1 < len(argv) and "=" not in argv[i + 1] else None
            try:
                print(help_text(verb, grammar, prog) if topic is None else section_help(topic, grammar.prefixes))
            except ConfigError as err:
                return _error(err)
            return 0
    try:
        parsed = parse(argv, grammar)
    except ConfigError as err:
        return _error(err)
    try:
        return _load(verb.run)(parsed, argv)
    except RegistryError as err:  # an unknown stage, planner, design, ... named anywhere in the command
        return _error(err)


def run_script(argv: Sequence[str], script: str, summary: str, options: type, body: Callable[[Parsed], int],
               prefixes: tuple[str, ...] = ()) -> int:
    """A script of ``scripts/`` outside the verbs (reliability checks) in the same grammar, with ``--help``.

    Args:
        argv: Its ``key=value`` arguments.
        script: Its path as typed (``scripts/fuzz.py``), for the usage line.
        summary: One line for ``--help``.
        options: Its options dataclass (documented ``Attributes:``).
        body: Runs it with the parsed arguments; returns the exit code.
        prefixes: Config prefixes it takes (``("task",)``).
    """
    def grammar() -> Grammar:
        if "task" not in prefixes:
            return Grammar(options, prefixes)
        # deferred: mjnav.config ~0.3 s (numba, scipy, osqp), not needed by scripts without task keys
        from mjnav.config import TASK_SECTIONS

        return Grammar(options, prefixes, {}, TASK_SECTIONS)

    def run(parsed: Parsed, _: list[str]) -> int:
        try:
            return body(parsed)
        except ConfigError as err:  # a bad task or override found while running
            return _error(err)

    return run_verb(Verb(script, summary, grammar, run), argv, "python")


def _verbs_help(prog: str, verbs: Mapping[str, Verb]) -> str:
    width = max(len(name) for name in verbs)
    lines = [f"usage: {prog} <command> [key=value ...]", "", "commands:"]
    lines += [f"  {name:{width}}  {verb.summary}" for name, verb in verbs.items()]
    lines += ["", f"{prog} <command> --help lists a command's keys."]
    return "\n".join(lines)


def help_text(verb: Verb, grammar: Grammar, prog: str = "mjnav") -> str:
    """The verb's ``--help``: its own keys (default and one line each, from the options dataclass's
    ``Attributes:``), its aliases, the config key forms it takes and how to list a section's keys."""
    words = verb.name.split()[-1]
    usage = f"usage: {prog} {words} [key=value ...]"
    lines = [usage, "", verb.summary, "", "keys:", *(describe_fields(grammar.options) or ["  (none)"])]
    lines += [f"  {alias}=  same as {target}=" for alias, target in grammar.aliases.items()]
    if grammar.prefixes:
        lines += ["", "config keys (values read as YAML):"]
    for prefix in grammar.prefixes:
        if prefix == "task":
            lines.append("  task.<section>.<field>=V  task config override; the short form <section>.<field>=V "
                         "is the same (crowd.count=25)")
        else:
            lines.append(f"  {prefix}.<field>=V  {PREFIXES[prefix]}")
    if grammar.prefixes:
        topics = {"task": "task.crowd", "train": "train", "planner": "planner.dwa"}
        examples = " | ".join(topics[p] for p in grammar.prefixes)
        lines += ["", f"list a section's keys: {prog} {words} --help <section>   ({examples}; task lists the sections)"]
    return "\n".join(lines)


# ---------------------------------------------------------------------------- config sections

def _roots(prefixes: Sequence[str]) -> dict[str, type]:
    """The documented config class at the top of each prefix the verb takes."""
    roots: dict[str, type] = {}
    if "task" in prefixes:
        # deferred: mjnav.config ~0.3 s (numba, scipy, osqp), not needed by `mjnav --help`
        from mjnav.config import TaskConfig

        roots["task"] = TaskConfig
    if "train" in prefixes:
        # deferred: mjnav.train.config brings mjnav.config (~0.3 s, numba, scipy, osqp), not needed by `mjnav --help`
        from mjnav.train.config import TrainConfig

        roots["train"] = TrainConfig
    return roots


def _planner_help(name: str | None) -> str:
    # deferred: mjnav.planners ~0.6 s after mjnav.cli (MPC, numba kernels), only for `--help planner`
    from mjnav.planners import PLANNERS

    configs = {n: PLANNERS.get(n).config_class for n in PLANNERS.names() if PLANNERS.get(n).config_class}
    if name is None or name not in configs:
        known = ", ".join(sorted(configs))
        if name is None:
            return f"planners with parameters: {known} (list one: --help planner.<name>)"
        near = closest(name, configs)
        raise ConfigError(f"planner {name!r} has no parameters (known: {known})"
                          + (f"; did you mean {near!r}?" if near else ""))
    return "\n".join([f"planner.<field>= keys of {name} ({configs[name].__name__}):",
                      *describe_fields(configs[name], "planner.", full=True)])


def section_help(topic: str, prefixes: Sequence[str] = ("task", "train", "planner")) -> str:
    """The keys of one config section with defaults and descriptions (``task.crowd``, ``crowd``,
    ``train.policy``, ``planner.dwa``).

    Raises:
        ConfigError: An unknown section (with the known ones and the closest).
    """
    parts = topic.split(".")
    if parts[0] == "planner" and "planner" in prefixes:
        return _planner_help(parts[1] if len(parts) > 1 else None)
    roots = _roots(prefixes)
    if parts[0] not in roots and "task" in roots:
        parts = ["task", *parts]  # the short form: crowd.count
    if parts[0] not in roots:
        raise ConfigError(f"unknown section {topic!r} (this command takes: {', '.join(prefixes) or 'none'})")
    cls, path = roots[parts[0]], parts[0]
    for part in parts[1:]:
        sections = {f.name: tp for f, tp in _nested(cls)}
        if part not in sections:
            near = closest(part, sections)
            raise ConfigError(f"unknown section {path}.{part} (known: {', '.join(sections)})"
                              + (f"; did you mean {path}.{near}?" if near else ""))
        cls, path = sections[part], f"{path}.{part}"
    head = f"{path} ({cls.__name__}): {(cls.__doc__ or '').strip().splitlines()[0]}"
    return "\n".join([head, "", *describe_fields(cls, path + ".", full=True)])


def _nested(cls: type) -> list[tuple[dataclasses.Field, type]]:
    hints = typing.get_type_hints(cls)
    return [(f, hints[f.name]) for f in dataclasses.fields(cls) if dataclasses.is_dataclass(hints[f.name])]


# ---------------------------------------------------------------------------- console scripts of 0.1

def train(argv: Sequence[str] | None = None) -> int:
    """``mjnav-train``: the same as ``mjnav train``."""
    return main(["train", *(sys.argv[1:] if argv is None else argv)])


def evaluate(argv: Sequence[str] | None = None) -> int:
    """``mjnav-evaluate``: the same as ``mjnav evaluate``."""
    return main(["evaluate", *(sys.argv[1:] if argv is None else argv)])


def render(argv: Sequence[str] | None = None) -> int:
    """``mjnav-render``: the same as ``mjnav render``."""
    return main(["render", *(sys.argv[1:] if argv is None else argv)])


def export(argv: Sequence[str] | None = None) -> int:
    """``mjnav-export``: the same as ``mjnav export``."""
    return main(["export", *(sys.argv[1:] if argv is None else argv)])
