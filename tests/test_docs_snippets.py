"""The hand-written pages' snippets run as written: each Python block of the home page, the
scaling-out page and the README saved as a file and run as a script (as a reader would: a "spawn"
worker imports the file, so a missing `if __name__ == "__main__":` guard fails here), and
each command of the agents guide (at the small budgets the page shows) exits 0. The
new-system walkthrough has its own test (tests/test_docs.py)."""

from __future__ import annotations

import os
import re
import shlex
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
DOCS = ROOT / "docs"


def blocks(page: str, language: str) -> list[str]:
    """The page's fenced blocks in `language`; a page under docs/, or README.md."""
    path = ROOT / page if page == "README.md" else DOCS / page
    return re.findall(rf"```{language}\n(.*?)```", path.read_text(encoding="utf-8"), re.S)


def _run(args: list[str], cwd: Path, timeout: float) -> subprocess.CompletedProcess:
    env = {**os.environ, "OMP_NUM_THREADS": "1", "PYTHONPATH": str(ROOT)}
    return subprocess.run(args, cwd=cwd, env=env, capture_output=True, text=True, timeout=timeout)


PYTHON_PAGES = ["index.md", "scaling-out.md", "README.md"]


def test_the_pages_python_blocks_are_found():
    found = {page: blocks(page, "python") for page in PYTHON_PAGES}
    assert all(found.values()), found
    spawn = [b for b in found["scaling-out.md"] if 'context="spawn"' in b]
    assert spawn and all('if __name__ == "__main__":' in b for b in spawn)


@pytest.mark.slow  # starts processes that import the envs: seconds each
@pytest.mark.parametrize("page", PYTHON_PAGES)
def test_each_python_block_runs_as_a_script(page, tmp_path):
    for i, code in enumerate(blocks(page, "python")):
        script = tmp_path / f"snippet_{i}.py"
        script.write_text(code, encoding="utf-8")
        done = _run([sys.executable, str(script)], tmp_path, timeout=600)
        assert done.returncode == 0, f"{page} block {i}:\n{code}\n{done.stderr[-3000:]}"


def agent_commands() -> list[str]:
    """The `python -m agents.*` lines of the agents guide's bash blocks."""
    lines = [ln.strip() for b in blocks("agents.md", "bash") for ln in b.splitlines()]
    return [ln for ln in lines if ln.startswith("python -m agents.")]


def test_the_agents_guide_shows_every_command_with_its_output():
    commands = agent_commands()
    for name in ("check", "train", "evaluate", "lqr", "plan"):
        assert any(c.startswith(f"python -m agents.{name} ") for c in commands), name
    text = (DOCS / "agents.md").read_text(encoding="utf-8")
    assert "<!-- output" not in text  # every placeholder replaced by the printed output


@pytest.mark.slow  # trains for 2,048 steps twice and plans a swing-up: minutes
def test_the_agents_guide_commands_run_as_written(tmp_path):
    # in page order: evaluate reads the run directory that train writes
    for command in agent_commands():
        args = shlex.split(command)
        done = _run([sys.executable, *args[1:]], tmp_path, timeout=900)
        assert done.returncode == 0, f"{command}:\n{done.stdout[-2000:]}\n{done.stderr[-2000:]}"
