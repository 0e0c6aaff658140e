"""Compiled models are cached on disk, pickle without re-deriving, and survive concurrency."""

import pickle
import subprocess
import sys

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


def test_concurrent_cold_compiles_agree(tmp_path):
    """Several processes compiling the same model into an empty cache at once."""
    code = (
        "import dynamics, numpy as np\n"
        "s = dynamics.get_model('bead_on_rotating_rod').compile()\n"
        "print(repr(float(s.state_derivative(0.3, np.array([0.1, 0.2]))[1])))\n"
    )
    env = {"LAGRANGE_GYM_CACHE": str(tmp_path), "OMP_NUM_THREADS": "1", "PYTHONPATH": "."}
    procs = [
        subprocess.Popen(
            [sys.executable, "-c", code], stdout=subprocess.PIPE, stderr=subprocess.PIPE, env=env
        )
        for _ in range(2)
    ]
    outs = [p.communicate(timeout=300) for p in procs]
    assert all(p.returncode == 0 for p in procs), [o[1].decode()[-500:] for o in outs]
    assert len({o[0] for o in outs}) == 1
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
