"""The model cache is bounded (least recently used entries pruned, safely), a command lists
and prunes it, and the task functions a user writes keep their machine code inside it."""

from __future__ import annotations

import importlib.util
import os
import sys

import numpy as np
import pytest

from dynamics import pruning
from dynamics.__main__ import main

HOUR = 3600.0


def _entry(root, name, size, age_h, now):
    """A module entry `name` of `size` bytes (with a numba file) last used `age_h` ago."""
    module = root / f"{name}.py"
    module.write_bytes(b"x" * (size // 2))
    (root / "__pycache__").mkdir(exist_ok=True)
    machine = root / "__pycache__" / f"{name}.f-1.py311.1.nbc"
    machine.write_bytes(b"x" * (size - size // 2))
    for f in (module, machine):
        os.utime(f, (now - age_h * HOUR, now - age_h * HOUR))
    return module, machine


@pytest.fixture
def cache_root(tmp_path, monkeypatch):
    root = tmp_path / "cache"
    root.mkdir(mode=0o700)
    monkeypatch.setenv("LAGRANGE_GYM_CACHE", str(root))
    return root


def test_pruning_removes_the_least_recently_used_first_and_keeps_recent_ones(cache_root):
    now = 1e9
    old = _entry(cache_root, "a_old", 1000, 48, now)
    mid = _entry(cache_root, "b_mid", 1000, 24, now)
    new = _entry(cache_root, "c_new", 1000, 0.1, now)  # within the grace hour
    assert [e.name for e in pruning.entries(cache_root)] == ["a_old.py", "b_mid.py", "c_new.py"]
    removed = pruning.prune(cache_root, max_bytes=1500, now=now)
    # 3000 bytes to at most 1500: the two oldest go; the recent one stays even so
    assert [e.name for e in removed] == ["a_old.py", "b_mid.py"]
    assert not any(f.exists() for f in (*old, *mid)) and all(f.exists() for f in new)
    assert pruning.prune(cache_root, max_bytes=0, now=now) == []  # used within GRACE_S
    assert not list(cache_root.glob(".pruned-*"))  # nothing half-removed left behind


def test_pruning_by_age_and_one_pruner_at_a_time(cache_root):
    import fcntl

    now = 1e9
    _entry(cache_root, "a_old", 100, 24 * 40, now)
    _entry(cache_root, "b_mid", 100, 24 * 2, now)
    with open(cache_root / ".prune.lock", "w") as held:
        fcntl.flock(held, fcntl.LOCK_EX)
        assert pruning.prune(cache_root, older_than=30 * 86400, now=now) is None
    removed = pruning.prune(cache_root, older_than=30 * 86400, now=now)
    assert [e.name for e in removed] == ["a_old.py"]


def test_a_build_past_the_bound_prunes_to_the_target(cache_root, monkeypatch):
    now = os.path.getmtime(cache_root)
    for k in range(4):
        _entry(cache_root, f"m{k}", 1 << 20, 48 - k, now)
    monkeypatch.setenv(pruning.LIMIT_ENV, "3M")
    pruning.keep_bounded(cache_root)
    left = pruning.entries(cache_root)
    assert sum(e.size for e in left) <= pruning.TARGET * 3 * 2**20
    assert [e.name for e in left] == ["m2.py", "m3.py"]  # the most recently used stay


SIZES = {"500M": 500 * 2**20, "2G": 2 * 2**30, "1.5G": int(1.5 * 2**30), "4096": 4096}


@pytest.mark.parametrize("text", SIZES)
def test_sizes_and_ages_read(text):
    assert pruning.parse_size(text) == SIZES[text]
    assert pruning.parse_age("30d") == 30 * 86400 and pruning.parse_age("12h") == 12 * HOUR


@pytest.mark.parametrize(
    "argv, words",
    [
        (["cache", "prune", "--max-size", "lots"], "--max-size must be a size such as 500M"),
        (["cache", "prune", "--older-than", "soon"], "--older-than must be an age such as 30d"),
        (["cache", "list", "--max-size", "5M"], "go with prune"),
    ],
)
def test_the_cache_command_refuses_bad_bounds_in_one_line(argv, words, capsys, cache_root):
    with pytest.raises(SystemExit) as info:
        main(argv)
    assert info.value.code == 2 and words in capsys.readouterr().err


def test_the_cache_command_lists_and_prunes(capsys, cache_root):
    import time

    now = time.time()
    _entry(cache_root, "a_old", 2000, 48, now)
    _entry(cache_root, "b_new", 2000, 0, now)
    assert main(["cache", "list"]) == 0
    out = capsys.readouterr().out
    assert "2 compiled models" in out and "a_old.py" in out.split("b_new.py")[0]
    assert main(["cache", "prune", "--older-than", "1d"]) == 0
    assert "removed 1 entries" in capsys.readouterr().out
    assert [e.name for e in pruning.entries(cache_root)] == ["b_new.py"]


def test_a_user_s_task_function_keeps_its_machine_code_in_the_cache(cache_root, tmp_path):
    """numba's files of a function compiled from a user's module go to the cache's
    functions/ folder (counted and pruned with the rest), not to the user's __pycache__."""
    from envs.compiled import compile_task_function

    user = tmp_path / "user"
    user.mkdir()
    (user / "my_terms.py").write_text("def double(x):\n    return x * 2.0\n")
    spec = importlib.util.spec_from_file_location("my_terms", user / "my_terms.py")
    module = importlib.util.module_from_spec(spec)
    sys.modules["my_terms"] = module
    try:
        spec.loader.exec_module(module)
        jitted = compile_task_function(module.double, (np.ones(3),))
    finally:
        del sys.modules["my_terms"]
    assert jitted(np.ones(2)).tolist() == [2.0, 2.0]
    assert not list(user.rglob("*.nbi")) and not list(user.rglob("*.nbc"))
    names = [e.name for e in pruning.entries(cache_root)]
    assert any(n.startswith("functions/user_") and "my_terms.double" in n for n in names)
