"""The plant is frozen and built in one pass; the runtime's parameter store is the one
owner of what varies per copy (docs/architecture.md)."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest

import dynamics
import envs
from envs import observation
from envs.plant import Plant
from envs.tasks import arm, disk

ARM = "Lagrange/TwoLinkArm-v1"
ENVS = Path(envs.__file__).parent


def test_the_plant_is_frozen():
    plant = gym.make(ARM).unwrapped.plant
    assert dataclasses.is_dataclass(plant)
    with pytest.raises(dataclasses.FrozenInstanceError):
        plant.p = None
    with pytest.raises(dataclasses.FrozenInstanceError):
        plant.observation = None
    # and so are the arrays it holds: nothing writes a limit, a bound or the record in place
    for array in (
        plant.input_low,
        plant.limits,
        plant.goal_low,
        plant.observation.low,
        plant.observation.ops,
    ):
        with pytest.raises(ValueError, match="read-only"):
            array[0] = 0
    with pytest.raises(ValueError, match="read-only"):
        plant.p.m2 = 0.0


def test_a_parameter_is_compiled_in_once(monkeypatch):
    calls, rebuilt = [], []
    compile_ = dynamics.Model.compile
    monkeypatch.setattr(dynamics.Model, "compile", lambda self, **p: calls.append(p) or
                        compile_(self, **p))  # fmt: skip
    with_parameters = dynamics.System.with_parameters
    monkeypatch.setattr(dynamics.System, "with_parameters", lambda self, **p: rebuilt.append(p) or
                        with_parameters(self, **p))  # fmt: skip
    env = gym.make(ARM, m2=2.0).unwrapped
    assert calls == [{"m2": 2.0}] and rebuilt == []
    assert env.system.parameters["m2"] == 2.0 and env.plant.p.m2 == 2.0
    assert env._rt.parameters.model_params.tolist() == env.system.parameter_vector.tolist()


@pytest.mark.filterwarnings("ignore:Task .TwoLinkArm.:RuntimeWarning")  # input limits of m2
def test_observed_parameters_are_context_features_of_the_compiled_observation():
    plant = Plant.build(arm.TASK, {"randomize": {"m2": (0.5, 2.0)}, "observe_params": True})
    ops = plant.ops
    context = ops[ops[:, 1] == observation.OP_CONTEXT]
    assert context[:, 0].tolist() == [plant.obs_size - 1]  # the last column ...
    assert context[:, 2].tolist() == [list(plant.system.parameters).index("m2")]  # ... of m2
    assert plant.columns[-1][:3] == ("param m2", 0.5, 2.0)
    assert plant.observation.declared == plant.obs_size - 1
    derived = Plant.build(disk.TASK)  # speed error, heading error: Derived features
    assert (derived.ops[:, 1] == observation.OP_DERIVED).sum() == len(derived.derived)


@pytest.mark.filterwarnings("ignore:Task .TwoLinkArm.:RuntimeWarning")  # input limits of m2
def test_the_store_writes_each_copy_s_parameters_and_the_perturber_reads_them():
    vec = gym.make_vec(ARM, 3, vectorization_mode="vector_entry_point",
                       randomize={"m2": (0.5, 2.0)}, perturb={"push": {"force": 5.0}})  # fmt: skip
    _, info = vec.reset(seed=0, options={"params": {"m2": np.array([0.6, 0.7, 0.8])}})
    rt = vec.unwrapped._rt
    store = rt.parameters
    column = list(rt.system.parameters).index("m2")
    assert store.P[:, column].tolist() == [0.6, 0.7, 0.8] == info["params"]["m2"].tolist()
    assert store.pins[:, column].all() and store.drawn.all()
    assert store.model_params is store.P  # the array the step and the perturber get
    assert not hasattr(rt.perturber, "P")


def test_envs_take_no_parameter_vector_out_of_the_system():
    for path in ENVS.glob("*.py"):
        assert "kernels()" not in path.read_text(encoding="utf-8"), path.name
