"""benchmarks/baselines.py's results file: a run of some envs replaces their rows only."""

import csv
import importlib.util
import json
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def _benchmark():
    spec = importlib.util.spec_from_file_location("baselines", ROOT / "benchmarks/baselines.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def _csv(path: Path, rows: list[dict]) -> Path:
    with open(path, "w", encoding="utf-8", newline="") as f:
        writer = csv.DictWriter(f, fieldnames=list(rows[0]))
        writer.writeheader()
        writer.writerows(rows)
    return path


def test_a_subset_replaces_its_envs_rows_and_keeps_the_others_with_their_run(tmp_path):
    bench = _benchmark()
    first = {"command": "all", "finished": "2026-01-01T00:00:00+00:00"}
    rows = [
        {"env_id": "A-v0", "agent": "zero", "success_rate": "0.1"},
        {"env_id": "B-v0", "agent": "zero", "success_rate": "0.2"},
    ]
    results = tmp_path / "agents.json"
    # the first form: one run's facts beside its rows
    results.write_text(json.dumps({**first, "rows": rows}), encoding="utf-8")
    again = {"command": "B only", "finished": "2026-02-01T00:00:00+00:00"}
    new = [
        {"env_id": "B-v0", "agent": "zero", "success_rate": "0.9"},
        {"env_id": "B-v0", "agent": "ppo", "success_rate": "1.0"},
    ]
    bench.write_results(results, _csv(tmp_path / "b.csv", new), again, merge=True)
    data = json.loads(results.read_text(encoding="utf-8"))
    assert data["runs"] == [first, again]
    assert [(r["env_id"], r["agent"], r["success_rate"], r["run"]) for r in data["rows"]] == [
        ("A-v0", "zero", "0.1", 0),
        ("B-v0", "zero", "0.9", 1),
        ("B-v0", "ppo", "1.0", 1),
    ]
    # measuring A again leaves the first run measuring nothing: it is dropped
    third = {"command": "A only", "finished": "2026-03-01T00:00:00+00:00"}
    a_rows = [{"env_id": "A-v0", "agent": "zero", "success_rate": "0.3"}]
    bench.write_results(results, _csv(tmp_path / "a.csv", a_rows), third, merge=True)
    data = json.loads(results.read_text(encoding="utf-8"))
    assert data["runs"] == [again, third]
    assert [(r["env_id"], r["success_rate"], r["run"]) for r in data["rows"]] == [
        ("B-v0", "0.9", 0),
        ("B-v0", "1.0", 0),
        ("A-v0", "0.3", 1),
    ]
    # without merging (every env was run) the file holds that one run
    bench.write_results(results, _csv(tmp_path / "all.csv", rows), first)
    data = json.loads(results.read_text(encoding="utf-8"))
    assert data["runs"] == [first] and [r["run"] for r in data["rows"]] == [0, 0]


def test_the_committed_results_name_a_run_for_every_row():
    data = json.loads((ROOT / "docs" / "data" / "agents.json").read_text(encoding="utf-8"))
    assert data["runs"] and all(0 <= r["run"] < len(data["runs"]) for r in data["rows"])
    assert {"Lagrange/Bicycle-v0"} <= {r["env_id"] for r in data["rows"]}
