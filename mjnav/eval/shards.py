"""Merge the shards of an evaluation (``mjnav evaluate shard=i/n``) into the whole evaluation's files.

``mjnav evaluate merge=DIR_OR_FILE,... out=DIR`` reads the shard JSONL files, checks that they are
pieces of one evaluation, and writes ``<task>.jsonl`` and ``summary.csv``/``summary.md`` into
``out``: the same records (without their ``shard`` field) and the same summary an unsharded
evaluation of those episodes writes.

What is read: a JSONL file as named; a folder's ``<task>.shard-i-of-n.jsonl`` files, or, for a task
without shard files there, its ``<task>.jsonl`` (so merging into the shards' own folder twice reads
the shards again, not the merged file).

What is refused (:class:`mjnav.eval.runner.EvalError`, naming the files and the difference): a file
named twice, an episode in two files (overlapping shards), records that disagree on a field every
record of one evaluation shares (task and its version, policy and its hash, planner, overrides,
code commit, action mode, seed offset, shard count), and missing episodes, named by shard: the
indices must be 0 .. N − 1, where N is ``episodes`` when given, else the largest episode count the
shards were run with (their records' ``planned_episodes``; the largest index + 1 for records made
before that field). Records past N − 1 are left out of the merge (and counted). A merged
``<task>.jsonl`` already in ``out`` is replaced only when every record it holds is one of the merged
records; otherwise it is left as it is.
"""

from __future__ import annotations

import json
import re
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from mjnav.eval.runner import (
    _COMMON_KEYS,
    HELD_OUT_BASE,
    EvalError,
    read_jsonl,
    summarise,
    write_summaries,
)
from mjnav.jobs import write_atomic

__all__ = ["SHARD_FILE", "merge", "shard_files"]

#: Name of a shard's JSONL file: ``<task>.shard-<i>-of-<n>.jsonl``.
SHARD_FILE = re.compile(r"^(?P<task>.+)\.shard-(?P<i>\d+)-of-(?P<n>\d+)\.jsonl$")
#: Fields all records of one evaluation share, checked across shards (``shard`` itself differs).
_SHARED = (*_COMMON_KEYS, "seed_offset", "shard_count")
#: How many missing indices an error lists.
_LISTED = 10


def shard_files(sources: Sequence[str | Path]) -> list[Path]:
    """The JSONL files to merge from folders and files (see the module docstring), each once.

    Raises:
        EvalError: A source that does not exist, or a folder without JSONL files.
    """
    files: list[Path] = []
    for source in map(Path, sources):
        if source.is_file():
            files.append(source)
        elif source.is_dir():
            found = sorted(source.glob("*.jsonl"))
            sharded = {m["task"] for p in found if (m := SHARD_FILE.match(p.name))}
            picked = [p for p in found if SHARD_FILE.match(p.name) or p.name.removesuffix(".jsonl") not in sharded]
            if not picked:
                raise EvalError(f"merge: no JSONL files in {source}")
            files += picked
        else:
            raise EvalError(f"merge: no such file or folder {str(source)!r}")
    seen: dict[Path, Path] = {}
    for path in files:
        key = path.resolve()
        if key in seen:
            raise EvalError(f"merge: {path} is named twice (also as {seen[key]}): name each shard once")
        seen[key] = path
    return list(seen)


def _shared(record: dict[str, Any]) -> dict[str, Any]:
    """The fields of ``record`` that every record of its evaluation has alike (:data:`_SHARED`)."""
    seed, index = record.get("seed"), record.get("index")
    offset = seed - HELD_OUT_BASE - index if isinstance(seed, int) and isinstance(index, int) else None
    shard = record.get("shard")
    count = int(shard.partition("/")[2]) if isinstance(shard, str) else 1
    fields = {k: record.get(k) for k in _COMMON_KEYS}
    return {**fields, "seed_offset": offset, "shard_count": count}


def _by_task(files: Sequence[Path]) -> dict[str, dict[int, tuple[Path, dict[str, Any]]]]:
    """``{task: {index: (file, record)}}`` of all files, checked for overlaps and disagreements."""
    tasks: dict[str, dict[int, tuple[Path, dict[str, Any]]]] = {}
    reference: dict[str, tuple[Path, dict[str, Any]]] = {}
    for path in files:
        for record in read_jsonl(path):
            index, task = record.get("index"), record.get("task")
            if not isinstance(index, int) or index < 0 or not isinstance(task, str):
                raise EvalError(f"merge: {path} holds a line that is not an evaluation record")
            shared = _shared(record)
            first_path, first = reference.setdefault(task, (path, shared))
            differ = [f"{k}: {first[k]!r} there, {shared[k]!r} here" for k in _SHARED if shared[k] != first[k]]
            if differ:
                raise EvalError(f"merge: {path} and {first_path} are not shards of one evaluation of {task} "
                                f"({'; '.join(differ)})")
            episodes = tasks.setdefault(task, {})
            if index in episodes:
                raise EvalError(f"merge: episode {index} of {task} is in {episodes[index][0]} and in {path} "
                                f"(overlapping shards)")
            episodes[index] = (path, record)
    return tasks


def _planned(episodes: dict[int, tuple[Path, dict[str, Any]]]) -> int:
    """The episode count of the evaluation the records come from: their largest ``planned_episodes``
    (the largest index + 1 for records made before that field)."""
    counts = [r.get("planned_episodes") for _, r in episodes.values()]
    return max([c for c in counts if isinstance(c, int)] + [max(episodes) + 1])


def _merged(task: str, episodes: dict[int, tuple[Path, dict[str, Any]]], wanted: int) -> list[dict[str, Any]]:
    """Episodes 0 .. ``wanted`` − 1 of one task by index, without their ``shard`` field.

    Raises:
        EvalError: Some are missing; the message counts them per shard.
    """
    missing = sorted(set(range(wanted)) - set(episodes))
    if missing:
        count = _shared(next(iter(episodes.values()))[1])["shard_count"]
        shards = [f"shard {k}/{count} has {sum(i in episodes for i in range(k, wanted, count))} of "
                  f"{len(range(k, wanted, count))}" for k in range(count)] if count > 1 else []
        listed = ", ".join(map(str, missing[:_LISTED])) + (", ..." if len(missing) > _LISTED else "")
        raise EvalError(f"merge: {task} lacks {len(missing)} of its {wanted} episodes ({listed})"
                        f"{': ' if shards else ''}{', '.join(shards)}; a shard is missing or unfinished "
                        f"(episodes=N merges the first N)")
    return [{k: v for k, v in episodes[i][1].items() if k != "shard"} for i in range(wanted)]


def _write_jsonl(path: Path, records: list[dict[str, Any]]) -> None:
    """Write the merged records to ``path``, unless it holds a record that is not among them."""
    text = "".join(json.dumps(r) + "\n" for r in records)
    merged = {json.dumps(r, sort_keys=True) for r in records}
    foreign = [r for r in read_jsonl(path) if json.dumps(r, sort_keys=True) not in merged]
    if foreign:
        raise EvalError(f"merge: {path} holds {len(foreign)} records that are not among the merged ones "
                        f"(episode {foreign[0].get('index')!r} first); it is left as it is: choose another out=")
    path.parent.mkdir(parents=True, exist_ok=True)
    write_atomic(path, text)


def merge(sources: Sequence[str | Path], out_dir: str | Path, episodes: int | None = None) -> list[dict[str, Any]]:
    """Merge shard files into ``<out_dir>/<task>.jsonl`` and ``summary.csv``/``summary.md``.

    Args:
        sources: Shard folders and JSONL files (:func:`shard_files`).
        out_dir: Folder of the merged files (may be a shards' folder).
        episodes: Episodes per task of the merged evaluation (the first ones); None: the count the
            shards were run with (:func:`_planned`).

    Returns:
        One summary row per task (:func:`mjnav.eval.runner.summarise`), as an unsharded
        evaluation of the same episodes returns; each row's ``left_out`` counts the records past
        the merged episodes.

    Raises:
        EvalError: A file named twice, overlapping or disagreeing shards, missing episodes, a missing
            source, ``episodes`` < 1, or a merged file in ``out_dir`` that holds other records
            (nothing is written then).
    """
    if episodes is not None and episodes < 1:
        raise EvalError(f"merge: episodes must be >= 1, got {episodes}")
    tasks = _by_task(shard_files(sources))
    if not tasks:
        raise EvalError("merge: the files hold no episodes")
    wanted = {task: episodes or _planned(found) for task, found in tasks.items()}
    merged = {task: _merged(task, found, wanted[task]) for task, found in tasks.items()}
    out, rows = Path(out_dir), []
    for task, records in merged.items():
        _write_jsonl(out / f"{task}.jsonl", records)
        offset = _shared(records[0])["seed_offset"]
        rows.append(summarise(records, records[0], offset))
    write_summaries(rows, out)
    return [{**row, "left_out": len(tasks[task]) - len(merged[task])} for row, task in zip(rows, merged, strict=True)]
