"""Compiled models are cached on disk, pickle without re-deriving, and survive concurrency."""

import contextlib
import pickle
import shutil
import stat
import subprocess
import sys
import warnings
from pathlib import Path

import numpy as np
import pytest

import dynamics
import dynamics.derive
from dynamics import cache


def test_warm_compile_neither_builds_nor_derives(monkeypatch):
    dynamics.get_model("bead_on_rotating_rod").compile()  # make sure it is cached

    def forbidden(*args, **kwargs):
        raise AssertionError("a warm compile must not derive")

    monkeypatch.setattr(dynamics.derive, "derive", forbidden)
    model = dynamics.get_model("bead_on_rotating_rod")
    system = model.compile(Omega=3.0)
    assert model._spec is None  # the factory was not even called
    assert system.parameters["Omega"] == 3.0


def test_system_pickles_and_deep_copies():
    import copy

    system = dynamics.get_model("two_link_arm").compile(m2=2.0)
    x = np.array([0.3, -0.2, 0.1, 0.4])
    for clone in (pickle.loads(pickle.dumps(system)), copy.deepcopy(system)):
        assert clone.parameters == system.parameters
        np.testing.assert_array_equal(
            clone.state_derivative(0.0, x, [1.0, 0.5]), system.state_derivative(0.0, x, [1.0, 0.5])
        )


@pytest.mark.slow  # a cold derivation and numba compilation in a new process: ~1.2 s
def test_pickle_rebuilds_from_its_own_source_in_a_fresh_cache(tmp_path):
    system = dynamics.get_model("two_link_arm").compile()
    blob = pickle.dumps(system)
    code = (
        "import pickle, sys, numpy as np\n"
        "s = pickle.loads(sys.stdin.buffer.read())\n"
        "print(repr(float(s.energy(np.array([0.3, 0.2, 0.0, 0.0])))))\n"
    )
    env = {"LAGRANGE_GYM_CACHE": str(tmp_path), "PATH": "", "OMP_NUM_THREADS": "1"}
    out = subprocess.run(
        [sys.executable, "-c", code],
        input=blob,
        capture_output=True,
        env=env,
        check=True,
        timeout=300,
    )
    assert float(out.stdout) == float(system.energy(np.array([0.3, 0.2, 0.0, 0.0])))


@pytest.mark.slow  # four cold derivations and numba compilations: ~10 s
def test_concurrent_cold_compiles_derive_once_and_agree(tmp_path):
    """Four processes compiling the same model into an empty cache at once: one derives,
    the others wait on its lock and load its file."""
    code = (
        "import dynamics, dynamics.derive, numpy as np\n"
        "derive = dynamics.derive.derive\n"
        "def counted(spec):\n"
        "    print('derived')\n"
        "    return derive(spec)\n"
        "dynamics.derive.derive = counted\n"
        "s = dynamics.get_model('bead_on_rotating_rod').compile()\n"
        "print(repr(float(s.state_derivative(0.3, np.array([0.1, 0.2]))[1])))\n"
    )
    env = {"LAGRANGE_GYM_CACHE": str(tmp_path), "OMP_NUM_THREADS": "1", "PYTHONPATH": "."}
    procs = [
        subprocess.Popen(
            [sys.executable, "-c", code], stdout=subprocess.PIPE, stderr=subprocess.PIPE, env=env
        )
        for _ in range(4)
    ]
    outs = [p.communicate(timeout=300) for p in procs]
    assert all(p.returncode == 0 for p in procs), [o[1].decode()[-500:] for o in outs]
    lines = [o[0].decode().split() for o in outs]
    assert sum(line.count("derived") for line in lines) == 1
    assert len({line[-1] for line in lines}) == 1
    assert not list(tmp_path.glob(".*.tmp"))  # no temporary files left behind


def test_write_atomic_leaves_old_file_on_failure(tmp_path):
    target = tmp_path / "model.py"
    cache.write_atomic(target, "old")

    class Boom:
        def __str__(self):
            raise RuntimeError("boom")

    with pytest.raises(TypeError):
        cache.write_atomic(target, Boom())
    assert target.read_text() == "old"
    assert not list(tmp_path.glob(".*.tmp"))


# ---- a cache that protects and repairs itself (issue 11) ---------------------------------


@pytest.fixture
def copied_cache(tmp_path, monkeypatch):
    """A private cache holding a copy of the warm bead model (file and numba files), and the
    path of its module; nothing of it loaded in this process yet."""
    warm = dynamics.get_model("bead_on_rotating_rod").compile()
    _derivative(warm)  # numba writes its cache files at the first call: of derivative_lanes,
    x = np.array([[0.1, 0.2]])  # and of a second kernel, for two index files
    warm._m.derivative_batch(np.zeros(1), x, np.zeros((1, 0)), warm._p, np.empty_like(x))
    source = Path(warm._m.__file__)
    root = tmp_path / "cache"
    (root / "__pycache__").mkdir(parents=True)
    shutil.copy2(source, root / source.name)
    for f in (source.parent / "__pycache__").glob(f"{source.stem}.*"):
        shutil.copy2(f, root / "__pycache__" / f.name)
    monkeypatch.setenv(cache.ENV_VAR, str(root))
    monkeypatch.setattr(cache, "_loaded", {})
    return root / source.name


def _derivative(system):
    return float(system.state_derivative(0.3, np.array([0.1, 0.2]))[1])


def test_new_cache_directory_is_private(tmp_path, monkeypatch):
    monkeypatch.setenv(cache.ENV_VAR, str(tmp_path / "new"))
    assert stat.S_IMODE(cache.cache_dir().stat().st_mode) == 0o700


@pytest.mark.slow  # a cold derivation and numba compilation: ~2.3 s
def test_a_tampered_module_is_not_run_and_is_rebuilt(copied_cache, tmp_path):
    marker = tmp_path / "ran"
    text = copied_cache.read_text()
    copied_cache.write_text(text + f"\nopen({str(marker)!r}, 'w').close()\n")
    system = dynamics.get_model("bead_on_rotating_rod").compile()
    assert not marker.exists()
    assert copied_cache.read_text() == text  # rebuilt from the derivation
    assert _derivative(system) == pytest.approx(0.2**2 * 0 + 4.0 * 0.1 - 9.81 * np.sin(0.6))


@pytest.mark.slow  # a cold derivation and numba compilation: ~2.5 s
@pytest.mark.parametrize("damage", ["truncate", "garbage", "binary"])
def test_a_damaged_module_is_rebuilt(copied_cache, damage):
    text = copied_cache.read_bytes()
    copied_cache.write_bytes(
        {"truncate": text[: len(text) // 2], "garbage": b"def (:\n", "binary": b"\xff\xfe\x00"}[
            damage
        ]
    )
    system = dynamics.get_model("bead_on_rotating_rod").compile()
    assert copied_cache.read_bytes() == text
    assert np.isfinite(_derivative(system))


@pytest.mark.slow  # a cold derivation and numba compilation: ~2.5 s
def test_corrupt_numba_cache_files_are_rebuilt(copied_cache):
    numba_files = list((copied_cache.parent / "__pycache__").glob("*.nb[ic]"))
    assert numba_files
    for i, f in enumerate(numba_files):
        f.write_bytes(f.read_bytes()[: 10 * (i % 2)])  # truncated or empty
    before = copied_cache.read_bytes()
    system = dynamics.get_model("bead_on_rotating_rod").compile()
    assert np.isfinite(_derivative(system))
    assert copied_cache.read_bytes() == before  # the module itself was sound: kept


def test_valid_numba_cache_files_are_kept(copied_cache):
    numba_files = sorted((copied_cache.parent / "__pycache__").glob("*.nb[ic]"))
    stamps = [f.stat().st_mtime_ns for f in numba_files]
    _derivative(dynamics.get_model("bead_on_rotating_rod").compile())
    assert [f.stat().st_mtime_ns for f in numba_files] == stamps


@pytest.mark.slow  # a cold derivation and numba compilation: ~2.5 s
def test_read_only_cache_compiles_cold_with_one_warning(tmp_path, monkeypatch):
    # a read-only directory, as seen by a non-root user (root ignores the permission bits)
    root = tmp_path / "ro"
    root.mkdir()
    monkeypatch.setenv(cache.ENV_VAR, str(root))
    monkeypatch.setattr(cache, "_loaded", {})
    monkeypatch.setattr(cache, "_fallback", [])
    real_write = cache.write_atomic

    def read_only(path, data):
        if Path(path).parent == root:
            raise PermissionError(13, "Permission denied", str(path))
        real_write(path, data)

    monkeypatch.setattr(cache, "write_atomic", read_only)
    monkeypatch.setattr(cache, "_lock", lambda name, key: contextlib.nullcontext())
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        a = dynamics.get_model("bead_on_rotating_rod").compile()
        b = dynamics.get_model("particle_cartesian").compile()
    assert len([w for w in caught if "not writable" in str(w.message)]) == 1
    # nothing written: at most the private, empty __pycache__ made before numba would make
    # it with the process umask (a real read-only directory refuses that too)
    assert [p.name for p in root.iterdir()] in ([], ["__pycache__"])
    assert not list(root.rglob("*.*"))
    assert np.isfinite(_derivative(a)) and b.n_q == 3


# ---- a cache that runs only what the project wrote (issue 20) -----------------------------


def _toy(tmp_path, monkeypatch, root=None):
    """A private cache at `root` (default tmp_path/cache), nothing loaded; a module body
    and the file it goes to."""
    root = root or tmp_path / "cache"
    monkeypatch.setenv(cache.ENV_VAR, str(root))
    monkeypatch.setattr(cache, "_loaded", {})
    monkeypatch.setattr(cache, "_fallback", [])
    key = "ab" * 32
    return key, f"KEY = {key!r}\nVALUE = 1\n", root / f"toy_{key[:20]}.py"


def test_a_module_whose_text_differs_from_the_expected_is_rewritten_not_run(tmp_path, monkeypatch):
    """The fused step's loader knows the exact text: an edited body under a recomputed
    (self-consistent) header is not run."""
    key, body, path = _toy(tmp_path, monkeypatch)
    marker = tmp_path / "ran"
    path.parent.mkdir(mode=0o700)
    path.write_text(cache.stamped(key, body + f"open({str(marker)!r}, 'w').close()\n"))
    assert cache.load("toy", key, body).VALUE == 1
    assert not marker.exists()
    assert path.read_text() == cache.stamped(key, body)


def test_numba_files_are_parsed_not_unpickled(copied_cache, tmp_path, monkeypatch):
    """A pickle planted in numba's index is not run by the loader's check; a truncated one
    is found by parsing and removed."""
    marker = tmp_path / "ran"

    class Planted:
        def __reduce__(self):
            return (open, (str(marker), "w"))

    index = sorted((copied_cache.parent / "__pycache__").glob("*.nbi"))
    index[0].write_bytes(pickle.dumps(Planted()) + pickle.dumps(("stamp", {})))
    index[1].write_bytes(index[1].read_bytes()[:-3])
    key = copied_cache.read_text().partition("\n")[0].split()[2]
    assert cache.load("bead_on_rotating_rod", key) is not None
    assert not marker.exists()
    assert not index[1].exists()  # its numba files were discarded: numba recompiles


def test_only_regular_files_of_bounded_size_are_read(tmp_path, monkeypatch):
    """A FIFO as the module and a link to /dev/zero as numba's index would hang the loader
    or fill memory: both are discarded without reading and the module is rewritten."""
    import os
    import signal

    key, body, path = _toy(tmp_path, monkeypatch)
    (path.parent / "__pycache__").mkdir(parents=True, mode=0o700)
    os.mkfifo(path)
    zero = path.parent / "__pycache__" / f"{path.stem}.f-1.py311.nbi"
    zero.symlink_to("/dev/zero")

    def hung(*args):
        raise TimeoutError("the loader blocked on a FIFO or a device")

    previous = signal.signal(signal.SIGALRM, hung)
    signal.alarm(20)
    try:
        assert cache.load("toy", key, body).VALUE == 1
    finally:
        signal.alarm(0)
        signal.signal(signal.SIGALRM, previous)
    assert path.read_text() == cache.stamped(key, body)
    assert not zero.is_symlink()
    with pytest.raises(OSError, match="not a regular file"):
        cache.read_bytes(Path("/dev/zero"))


@pytest.mark.parametrize("unsafe", ["mode 0777", "another owner"])
def test_a_cache_others_can_write_is_bypassed_with_a_warning(tmp_path, monkeypatch, unsafe):
    import os

    root = tmp_path / "shared"
    root.mkdir()
    if unsafe == "mode 0777":
        root.chmod(0o777)
        reason = "writable by others"
    else:
        uid = os.geteuid() + 1
        monkeypatch.setattr(cache.os, "geteuid", lambda: uid)
        reason = "not by this user"
    key, body, _ = _toy(tmp_path, monkeypatch, root)
    with pytest.warns(RuntimeWarning, match=f"model cache is not used .*{reason}"):
        module = cache.load("toy", key, body)
    assert module.VALUE == 1
    assert not list(root.iterdir())  # nothing written to, or run from, the shared directory


def test_cache_key_hashes_every_module_that_derives_or_generates_code():
    """A stale cache must never serve old code: each module imported by the derivation or
    the code generator (transitively, within the package) is hashed into every key."""
    import ast

    from dynamics import model

    root = Path(model.__file__).parent
    seen, todo = set(), ["codegen.py"]
    while todo:
        name = todo.pop()
        seen.add(name)
        tree = ast.parse((root / name).read_text())
        for node in ast.walk(tree):
            if isinstance(node, ast.ImportFrom) and node.level == 1 and node.module:
                dep = node.module.split(".")[0] + ".py"
                if dep not in seen:
                    todo.append(dep)
    assert seen <= set(model._CORE), f"not in the cache key: {sorted(seen - set(model._CORE))}"
    assert "kernels.py" in model._CORE  # the template appended to every module


def test_cache_key_changes_with_the_code_generator(monkeypatch):
    from dynamics import model

    key = dynamics.get_model("two_link_arm").key
    real = Path.read_bytes

    def edited(path):
        data = real(path)
        return data + b"\n# edited\n" if path.name == "program.py" else data

    model._code_fingerprint.cache_clear()
    monkeypatch.setattr(Path, "read_bytes", edited)
    try:
        assert dynamics.get_model("two_link_arm").key != key
    finally:
        monkeypatch.undo()
        model._code_fingerprint.cache_clear()
    assert dynamics.get_model("two_link_arm").key == key


def test_a_factory_is_keyed_on_the_users_modules_it_imports(tmp_path, monkeypatch):
    """A constant the factory imports from another of the user's modules changes the key
    (it was keyed on the factory's own file only and kept serving the old physics)."""
    import importlib
    import sys

    from dynamics import model as model_module

    (tmp_path / "k_consts.py").write_text("LENGTH = 1.0\n")
    (tmp_path / "k_factory.py").write_text(
        "from k_consts import LENGTH\n\n\ndef factory():\n    return LENGTH\n"
    )
    monkeypatch.syspath_prepend(str(tmp_path))
    for name in ("k_consts", "k_factory"):
        sys.modules.pop(name, None)
    importlib.invalidate_caches()
    files = model_module._factory_files("k_factory")
    assert {p.name for p in files} == {"k_factory.py", "k_consts.py"}
    before = model_module._code_fingerprint.__wrapped__("k_factory:factory")
    (tmp_path / "k_consts.py").write_text("LENGTH = 2.0\n")
    assert model_module._code_fingerprint.__wrapped__("k_factory:factory") != before


@contextlib.contextmanager
def _umask(mask: int):
    import os

    old = os.umask(mask)
    try:
        yield
    finally:
        os.umask(old)


def test_a_cache_made_under_umask_002_is_used_its_numba_folder_private(tmp_path, monkeypatch):
    """Under umask 002 (group-writable folders by default) the cache and numba's
    __pycache__ are made 0o700 here, and the second load finds the first one's module."""
    key, body, path = _toy(tmp_path, monkeypatch)
    with _umask(0o002), warnings.catch_warnings():
        warnings.simplefilter("error", RuntimeWarning)  # no "not used" warning
        assert cache.load("toy", key, body).VALUE == 1
        monkeypatch.setattr(cache, "_loaded", {})
        assert cache.load("toy", key).VALUE == 1  # from disk, not rebuilt
    for folder in (path.parent, path.parent / "__pycache__"):
        assert stat.S_IMODE(folder.stat().st_mode) == 0o700


@pytest.mark.parametrize("members, used", [([], True), (["mallory"], False)])
def test_a_group_writable_cache_is_refused_only_when_another_user_is_in_the_group(
    tmp_path, monkeypatch, members, used
):
    """Group write permission is another user's only where the group has another member
    (with a user's private group, the common case under umask 002, it is not)."""
    root = tmp_path / "cache"
    (root / "__pycache__").mkdir(parents=True)
    for folder in (root, root / "__pycache__"):
        folder.chmod(0o775)  # as numba makes it under umask 002
    monkeypatch.setattr(cache, "group_members_besides_me", lambda gid: members)
    key, body, path = _toy(tmp_path, monkeypatch, root)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        assert cache.load("toy", key, body).VALUE == 1
    refused = [w for w in caught if "model cache is not used" in str(w.message)]
    assert path.exists() is used
    assert bool(refused) is not used
    if refused:
        assert "mallory" in str(refused[0].message)


def test_a_group_that_cannot_be_looked_up_counts_as_shared():
    assert cache.group_members_besides_me(2**31 - 7) == ["unknown users"]


@pytest.mark.slow  # two fresh processes compiling with numba: ~5 s
def test_an_edited_helper_in_another_file_is_not_served_from_numba_s_cache(tmp_path):
    """numba keys a cached function on its own file only; the helper it calls lives in
    another file, whose edit must still reach the compiled function."""
    import os

    helper = tmp_path / "helper_mod.py"
    helper.write_text(
        "from numba import njit\n\n\n@njit(cache=True)\ndef helper(x):\n    return x * 2.0\n"
    )
    (tmp_path / "task_mod.py").write_text(
        "from helper_mod import helper\n\n\ndef reward(x):\n    return helper(x) + 1.0\n"
    )
    code = (
        "import numba, task_mod\n"
        "from dynamics.cache import keep_numba_cache_true\n"
        "j = numba.njit(cache=True)(task_mod.reward)\n"
        "keep_numba_cache_true(j, task_mod.reward)\n"
        "print(j(1.0))\n"
    )
    root = Path(__file__).resolve().parents[2]
    env = {**os.environ, "PYTHONPATH": f"{tmp_path}{os.pathsep}{root}",
           "LAGRANGE_GYM_CACHE": str(tmp_path / "cache")}  # fmt: skip

    def run() -> str:
        out = subprocess.run([sys.executable, "-c", code], env=env, cwd=tmp_path,
                             capture_output=True, text=True, check=True)  # fmt: skip
        return out.stdout.strip()

    assert run() == "3.0"
    helper.write_text(helper.read_text().replace("x * 2.0", "x * 5.0"))
    assert run() == "6.0"


def test_a_module_file_another_user_may_write_is_rebuilt_not_run(tmp_path, monkeypatch):
    key, body, path = _toy(tmp_path, monkeypatch)
    marker = tmp_path / "ran"
    path.parent.mkdir(mode=0o700)
    path.write_text(cache.stamped(key, body + f"open({str(marker)!r}, 'w').close()\n"))
    path.chmod(0o666)  # a stamped, self-consistent file anyone may have written
    assert cache.load("toy", key) is None  # discarded, not run
    assert not marker.exists() and not path.exists()
