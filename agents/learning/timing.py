"""A run's training time, kept with the run across resumed segments (agents.check)."""

from __future__ import annotations

import json
from pathlib import Path

from ..common import write_atomic

TIME_FILE = "training_time.json"  # in the run directory: {"segments": [{from, to, seconds}]}


def record_segment(run_dir: Path, start: int, end: int, seconds: float) -> tuple[float, int]:
    """Add a training segment (steps start..end in `seconds`) to the run's TIME_FILE,
    dropping segments past `start` (a fresh run, or steps a resumed checkpoint lost); return
    the run's training seconds and the steps they cover."""
    segments = [s for s in _segments(run_dir) if s["to"] <= start] if start > 0 else []
    if end > start:
        segments.append({"from": start, "to": end, "seconds": round(seconds, 3)})
    write_atomic(run_dir / TIME_FILE, json.dumps({"segments": segments}, indent=1) + "\n")
    return _total(segments)


def recorded(run_dir: Path) -> tuple[float, int]:
    """The run's training seconds and the steps they cover, as its TIME_FILE records them."""
    return _total(_segments(run_dir))


def _segments(run_dir: Path) -> list[dict]:
    path = run_dir / TIME_FILE
    return json.loads(path.read_text()).get("segments", []) if path.exists() else []


def _total(segments: list[dict]) -> tuple[float, int]:
    return sum(s["seconds"] for s in segments), sum(s["to"] - s["from"] for s in segments)
