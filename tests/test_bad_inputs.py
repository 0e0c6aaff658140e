"""Bad inputs on the randomisation, per-copy values, perturbation, benchmark, training and
model surfaces end in a clear refusal naming the problem (or, where the input is valid, in
the right behaviour), never in a numba error, a traceback or a silent impossible plant.

One table per class of the reliability issue: each entry is what a user hands in and the
words its one-line error must contain. The cache's umask cases are in
tests/dynamics/test_cache.py, the declarations of a task in tests/envs/test_declarations.py."""

from __future__ import annotations

import dataclasses
import functools
import importlib
import importlib.util
import types
import warnings

import gymnasium as gym
import numpy as np
import pytest
import sympy as sp
import sympy.physics.mechanics as me

import dynamics
import envs
from agents.common import UserError
from dynamics.spec import ModelSpec, Param
from envs.checks import DeclarationError
from examples import cart_pole

ARM, DISK, CRANK = "Lagrange/TwoLinkArm-v1", "Lagrange/RollingDisk-v1", "Lagrange/CrankSlider-v1"
BASE = cart_pole.TASK


def _make(env_id, **kw):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # limits at nominal values
        gym.make(env_id, **kw).reset(seed=0)


def _vec_reset(env_id, n, **kw):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        vec = gym.make_vec(env_id, n, vectorization_mode="vector_entry_point", **kw)
    vec.reset(seed=0)
    return vec


def _start_far_out(rng, p):
    return {"x": 10.0}, {}


def _nan_point(x, goal, p):
    return {"x": np.nan}


def _start_typo(rng, p):
    return {"x": rng.uniform(-0.1, 0.1) * p.m_pol}, {}  # p.m_pole misspelt


def _start_unknown_state(rng, p):
    return {"thetaa": 0.1}, {}


def _point_typo(x, goal, p):
    return {"x": x.xx}


def _point_unknown_state(x, goal, p):
    return {"theta_dott": 0.0}


def _former_start(rng, p):  # the former form: arrays (x, g)
    return np.array([rng.uniform(-0.5, 0.5), rng.uniform(-0.1, 0.1), 0.0, 0.0]), np.zeros(0)


def _named_start(rng, p):
    return {"x": rng.uniform(-0.5, 0.5), "theta": rng.uniform(-0.1, 0.1)}, {}


def _former_holding(g, x, system):  # examples/series_elastic.py's function before names
    q = system.parameters
    x0 = np.zeros((len(g), 4))
    x0[:, 0] = g[:, 0] + q["m"] * q["g"] * q["l"] * np.sin(g[:, 0]) / (2 * q["k"])
    x0[:, 1] = g[:, 0]
    return x0


def _x_star():
    goal = (envs.Goal("x*", "m", -1.0, 1.0),)
    return dataclasses.replace(BASE, goal=goal, operating_point={"x": "x*"})


def _undeclared_symbol():
    q = me.dynamicsymbols("q")
    m, k = sp.symbols("m k")  # k is used in V but not declared
    return ModelSpec("spring", (q,), m * q.diff() ** 2 / 2, k * q**2 / 2, {m: Param(1.0, "kg")})


def _nan_default():
    return Param(float("nan"), "kg")


# ---- 1. physical bodies ------------------------------------------------------------------
# (what the user does, the exception, the words its message must contain)
BODIES = {
    "disk moments drawn apart": (
        lambda: _make(DISK, randomize={"I": (0.015, 0.03), "J": (0.03, 0.06)}),
        ValueError,
        ["body 'disk'", "J at its high end", "Same('I')"],
    ),
    "a thin disk's J above 2 I": (
        lambda: dynamics.get_model("rolling_disk").compile(J=0.05),
        ValueError,
        ["triangle inequality"],
    ),
    "a bicycle frame's product of inertia x 4": (
        lambda: dynamics.get_model("whipple_bicycle").compile(I_Bxz=9.6),
        ValueError,
        ["rear frame", "not positive definite"],
    ),
    "per-copy values of an impossible disk": (
        lambda: _vec_reset(DISK, 2, randomize={}).reset(options={"params": {"J": 0.09}}),
        ValueError,
        ["body 'disk'"],
    ),
    "a condition broken off the all-low/all-high diagonal": (
        lambda: _make(CRANK, randomize={"l": (0.25, 0.4), "R": (0.05, 0.2), "h": (-0.1, 0.1)}),
        ValueError,
        ["l > R + |h|", "at its high end"],
    ),
    "a boolean parameter value": (lambda: _make(ARM, m2=True), TypeError, ["'m2'", "number"]),
    "a boolean in a distribution": (
        lambda: envs.Uniform(True, 2.0),
        TypeError,
        ["Uniform.low", "booleans"],
    ),
    "a boolean per-copy value": (
        lambda: _vec_reset(ARM, 2, randomize={}).reset(options={"params": {"m2": True}}),
        TypeError,
        ["options['params']['m2']", "booleans"],
    ),
    "Same before its parameter": (
        lambda: _make(DISK, randomize={"J": envs.Same("I"), "I": (0.02, 0.03)}),
        ValueError,
        ["Same('I')", "declared before"],
    ),
    "a randomised value beyond the parameter range": (
        lambda: _make(ARM, randomize={"m2": (1.0, 1e60)}),
        ValueError,
        ["out of range"],
    ),
}


# the bicycle is derived and compiled for this case alone in the fast suite (about 6 s of CPU
# from a cold cache): with -m slow, as every model compiled for one test
SLOW_BODIES = ("a bicycle frame's product of inertia x 4",)


@pytest.mark.parametrize(
    "case", [pytest.param(c, marks=pytest.mark.slow) if c in SLOW_BODIES else c for c in BODIES]
)
def test_no_impossible_body_is_simulated(case):
    make, error, words = BODIES[case]
    with pytest.raises(error) as info:
        make()
    for w in words:
        assert w in str(info.value), (w, str(info.value))


def test_a_non_negative_parameter_refuses_a_negative_value_and_range():
    from dynamics.system import check_parameters
    from envs.randomize_checks import check_support

    with pytest.raises(ValueError, match="'mu' of toy must not be negative"):
        check_parameters("toy", ("mu",), (0.1,), (False,), {"mu": -0.1}, (True,))
    assert check_parameters("toy", ("mu",), (0.1,), (False,), {"mu": 0.0}, (True,)) == [0.0]
    module = types.SimpleNamespace(POSITIVE=(False,), NONNEGATIVE=(True,))
    system = types.SimpleNamespace(name="toy", parameters={"mu": 0.1}, kernel_module=module)
    with pytest.raises(ValueError, match="must be non-negative, so low must be >= 0"):
        check_support(system, "mu", (-0.1, 0.2), (-0.1, 0.2))
    check_support(system, "mu", (0.0, 0.2), (0.0, 0.2))


def test_inertial_randomisation_draws_each_declared_body_as_a_whole():
    from agents.learning.randomization import env_kwargs

    kw = env_kwargs(DISK, {"inertial": 0.25})
    assert kw["randomize"]["J"] == {"dist": "same", "parameter": "I"}
    params = _vec_reset(DISK, 16, **kw).reset(seed=3)[1]["params"]
    np.testing.assert_allclose(params["I"] / 0.0225, params["J"] / 0.045)  # one factor
    assert np.ptp(params["I"]) > 0  # and it varies from copy to copy


def test_robustness_grids_skip_and_report_impossible_points_only():
    from benchmarks.robustness import quantities

    scales = [0.5, 1.0, 2.0]
    qs = {q.name: q for q in quantities(DISK, 3, ["inertial"], scales)}
    assert [x for x, _ in qs["J"].points] == [0.5, 1.0]  # J x 2 > 2 I: no disk
    assert [x for x, _ in qs["J"].impossible] == [2.0]
    assert "triangle inequality" in qs["J"].impossible[0][1]
    assert [x for x, _ in qs["body disk"].points] == scales  # scaled as a whole: all fine
    assert [x for x, _ in qs["m"].points] == scales


# ---- 3. commands: arguments checked before work, one line -----------------------------------
COMMANDS = {
    "unknown env": (["--envs", "Lagrange/TwoLinkArm-v9"], "Did you mean"),
    "misspelt quantity": (["--envs", ARM, "--quantities", "m22"], "Did you mean 'm2'"),
    "nan scale": (["--scales", "1,nan"], "scale nan must be a finite number"),
    "huge scale": (["--scales", "0.5,1e300"], "scale 1e300"),
    "negative seed": (["--seed", "-1"], "--seed must be >= 0"),
    "huge episodes": (["--episodes", "100000000"], "--episodes must be within"),
    "misspelt agent": (["--agents", "lqq"], "Did you mean 'lqr'"),
    "--out a file": (["--out", __file__], "is a file, not a folder"),
    "render a missing file": (["--render", "/nonexistent/results.json"], "is not a file"),
}


@pytest.mark.parametrize("case", COMMANDS)
def test_the_robustness_benchmark_checks_every_argument_first(case, capsys, tmp_path):
    from benchmarks import robustness

    argv, words = COMMANDS[case]
    if "--out" not in argv:
        argv = [*argv, "--out", str(tmp_path / "out")]
    with pytest.raises(SystemExit) as info:
        robustness.main(argv)
    err = capsys.readouterr().err.strip()
    assert info.value.code == 2 and words in err and "Traceback" not in err
    assert not (tmp_path / "out" / "results.json").exists()


@pytest.mark.parametrize("content", ["{", '{"rows": []}', "\x00\x01"])
def test_render_refuses_a_truncated_or_foreign_file(content, capsys, tmp_path):
    from benchmarks import robustness

    path = tmp_path / "results.json"
    path.write_bytes(content.encode("latin-1"))
    with pytest.raises(SystemExit) as info:
        robustness.main(["--render", str(path), "--out", str(tmp_path / "out")])
    err = capsys.readouterr().err
    assert info.value.code == 2 and "--render" in err and "Traceback" not in err


def test_agents_lqr_checks_its_output_file_before_the_work(capsys, tmp_path):
    from agents import lqr

    with pytest.raises(SystemExit) as info:
        lqr.main([ARM, "--plot", str(tmp_path / "no" / "such" / "folder.png")])
    err = capsys.readouterr()
    assert info.value.code == 2 and "does not exist" in err.err and err.out == ""


# ---- 4. bounds on perturbation and randomisation numbers -------------------------------------
BOUNDS = {
    "push duration 1e300": (
        lambda: _make(ARM, perturb={"push": {"force": 1.0, "duration": 1e300}}),
        ["duration", "longer than an episode"],
    ),
    "delay of 1e9 control periods": (
        lambda: _make(ARM, perturb={"delay": 10**9}),
        ["delay", "no command would ever act"],
    ),
    "when = 2**70": (
        lambda: _make(ARM, randomize={"m2": envs.Uniform(0.9, 1.1, when=2**70)}),
        ["2147483647"],
    ),
    "a start function far outside the limits": (
        lambda: envs.LagrangianEnv(dataclasses.replace(BASE, start=_start_far_out)),
        ["`start`", "beyond `limits['x']`"],
    ),
    "a handover shaping of 1e308": (
        lambda: importlib.import_module("agents.control.handover").handover_options(
            {"level": 1.0, "shaping": 1e308}
        ),
        ["shaping in [0, 1e+06]"],
    ),  # fmt: skip
}


@pytest.mark.parametrize("case", BOUNDS)
def test_numbers_that_would_break_the_env_are_refused_when_it_is_made(case):
    make, words = BOUNDS[case]
    with pytest.raises(ValueError) as info:
        make()
    for w in words:
        assert w in str(info.value), (w, str(info.value))


def test_choice_weights_near_the_float_limit_draw_normally():
    vec = _vec_reset(ARM, 4, randomize={"m2": envs.Choice((0.9, 1.1), weights=(1e308, 1e308))})
    params = vec.reset(seed=1)[1]["params"]["m2"]
    assert set(params.tolist()) <= {0.9, 1.1}


# ---- 5. records that stay true ---------------------------------------------------------------
def test_a_resume_with_another_randomisation_is_refused(tmp_path):
    import yaml

    from agents.learning.rundir import check_resume_randomize as check_resume

    config = {"env_id": ARM, "algo": "ppo", "hyperparams": {"randomize": {"inertial": 0.25}}}
    (tmp_path / "config.yml").write_text(yaml.safe_dump(config))
    check_resume(tmp_path, {"inertial": 0.25})  # the same: resumes
    with pytest.raises(UserError, match="was trained with randomised: every mass"):
        check_resume(tmp_path, {"inertial": 0.5})
    with pytest.raises(UserError, match="not nominal parameters"):
        check_resume(tmp_path, None)


def test_the_zero_baseline_applies_zero_input_to_a_one_sided_input():
    from agents.control.policies import ZeroPolicy

    env = envs.LagrangianEnv(dataclasses.replace(BASE, max_input=((0.0, 10.0),)))
    obs, _ = env.reset(seed=0)
    policy = ZeroPolicy(env)
    action, _ = policy.predict(obs)
    assert action.tolist() == [-1.0]  # the bottom of [0, 10]: no force, not 5 N
    assert env.step(action)[4]["input"].tolist() == [0.0]
    assert policy.description == "zero input"


# ---- 6. a user's model checked like the task -------------------------------------------------
MODELS = {
    "a symbol used but not declared": (_undeclared_symbol, ValueError, ["potential uses k"]),
    "a NaN default": (_nan_default, ValueError, ["Param.default must be finite"]),
    "a boolean default": (lambda: Param(True, "kg"), TypeError, ["Param.default"]),
    "a factory that returns no spec": (
        lambda: dynamics.Model(lambda: 42).spec,
        TypeError,
        ["returned int, not a dynamics.ModelSpec"],
    ),
    "an operating-point function giving NaN": (
        lambda: envs.LagrangianEnv(dataclasses.replace(BASE, operating_point=_nan_point)),
        DeclarationError,
        ["`operating_point`", "NaN or inf"],
    ),
    "a start function's slip": (
        lambda: envs.LagrangianEnv(dataclasses.replace(BASE, start=_start_typo)),
        DeclarationError,
        ["`start`", "function _start_typo", "fails on a sample draw", "Did you mean 'm_pole'"],
    ),
    "a start function naming an unknown state": (
        lambda: envs.LagrangianEnv(dataclasses.replace(BASE, start=_start_unknown_state)),
        DeclarationError,
        ["`start`", "unknown state 'thetaa'", "Did you mean 'theta'"],
    ),
    "an operating-point function's slip": (
        lambda: envs.LagrangianEnv(dataclasses.replace(BASE, operating_point=_point_typo)),
        DeclarationError,
        ["`operating_point`", "function _point_typo", "(x, goal, p)", "'xx'", "Did you mean 'x'"],
    ),
    "an operating-point function naming an unknown state": (
        lambda: envs.LagrangianEnv(dataclasses.replace(BASE, operating_point=_point_unknown_state)),
        DeclarationError,
        ["`operating_point`", "unknown state 'theta_dott'", "Did you mean 'theta_dot'"],
    ),
    "a goal the operating point needs, unobserved": (
        lambda: envs.LagrangianEnv(_x_star()),
        DeclarationError,
        ["`observation`", "'x*'", "operating point needs"],
    ),
}


@pytest.mark.parametrize("case", MODELS)
def test_a_user_s_model_slip_is_named_in_one_line(case):
    make, error, words = MODELS[case]
    with pytest.raises(error) as info:
        make()
    for w in words:
        assert w in str(info.value), (w, str(info.value))
    assert "\n" not in str(info.value)


def test_named_start_and_operating_point_functions_need_no_warning():
    from examples import series_elastic

    with warnings.catch_warnings():
        warnings.simplefilter("error", DeprecationWarning)
        env = envs.LagrangianEnv(dataclasses.replace(BASE, start=_named_start))
        series = envs.LagrangianEnv(series_elastic.TASK)
    env.reset(seed=0)
    assert abs(env.state[0]) <= 0.5 and abs(env.state[1]) <= 0.1 and not env.state[2:].any()
    series.reset(seed=0)
    x0, _ = series.operating_point()
    t = series._rt.G[0, 0]  # the link at theta*, the spring wound to carry its weight
    assert x0[1] == t and (x0[0] - t) * np.sin(t) > 0 and not x0[2:].any()


def test_former_start_and_operating_point_functions_warn_and_still_work():
    """The former array forms draw and regulate exactly as the named ones do (the same
    generator calls and arithmetic, so equal to the bit)."""
    from examples import series_elastic

    with pytest.warns(DeprecationWarning, match="_former_start returns arrays"):
        former = envs.LagrangianEnv(dataclasses.replace(BASE, start=_former_start))
    named = envs.LagrangianEnv(dataclasses.replace(BASE, start=_named_start))
    assert np.array_equal(former.reset(seed=4)[0], named.reset(seed=4)[0])
    task = dataclasses.replace(series_elastic.TASK, operating_point=_former_holding)
    with pytest.warns(DeprecationWarning, match="_former_holding takes the former form"):
        former = envs.LagrangianEnv(task)
    named = envs.LagrangianEnv(series_elastic.TASK)
    former.reset(seed=2), named.reset(seed=2)
    for a, b in zip(former.operating_point(), named.operating_point()):
        assert np.array_equal(a, b)


def test_every_factory_form_builds_the_model():
    from dynamics.models.bead import bead_on_rotating_rod
    from envs.resolved import _model

    class Holder:
        make = staticmethod(bead_on_rotating_rod)

    class Factory:
        def __call__(self):
            return bead_on_rotating_rod()

    forms = (functools.partial(bead_on_rotating_rod), Holder.__dict__["make"], Factory())
    for form in forms:
        assert _model(form).name == "bead_on_rotating_rod"


# ---- one vocabulary: every misspelt name gets a suggestion ---------------------------------
MISSPELT = {
    "env option": (lambda: _make(ARM, integrater="rk4"), "Did you mean 'integrator'?"),
    "parameter": (lambda: _make(ARM, mm2=2.0), "Did you mean 'm2'?"),
    "integrator option": (lambda: _make(ARM, integrator="rk5"), "Did you mean 'rk4'?"),
    "perturbation key": (lambda: _make(ARM, perturb={"obs_nois": 0.1}), "'obs_noise'?"),
    "push key": (lambda: _make(ARM, perturb={"push": {"forse": 1.0}}), "'force'?"),
    "distribution": (
        lambda: _make(ARM, randomize={"m2": {"dist": "unifrom", "low": 1, "high": 2}}),
        "Did you mean 'uniform'?",
    ),
    "apply": (lambda: envs.Uniform(1, 2, apply="scal"), "Did you mean 'scale'?"),
    "when": (lambda: envs.Uniform(1, 2, when="rest"), "Did you mean 'reset'?"),
    "randomised parameter": (lambda: _make(ARM, randomize={"mm2": (1, 2)}), "'m2'?"),
    "model": (lambda: dynamics.get_model("two_link_armm"), "Did you mean 'two_link_arm'"),
    "task algorithm": (lambda: dataclasses.replace(BASE, algo="pop"), "Did you mean 'ppo'?"),
    "task integrator": (
        lambda: dataclasses.replace(BASE, integrator="rk5"),
        "Did you mean 'rk4'?",
    ),
    "algorithm": (
        lambda: importlib.import_module("agents.learning.hparams").check_algo_name("sax"),
        "Did you mean 'sac'?",
    ),
}


@pytest.mark.parametrize("case", MISSPELT)
def test_every_misspelt_name_gets_a_suggestion(case):
    make, words = MISSPELT[case]
    with pytest.raises(ValueError) as info:
        make()
    assert words in str(info.value)


def test_one_table_of_algorithms_names_what_agents_train():
    """A task naming an algorithm agents.train cannot train is refused, not trained as PPO."""
    from agents.learning.hparams import algorithms
    from dynamics.checks import ALGORITHMS, INTEGRATORS
    from dynamics.methods import METHODS

    assert tuple(algorithms()) == ALGORITHMS
    assert INTEGRATORS == tuple(METHODS)
    with pytest.raises(DeclarationError, match="algo"):
        dataclasses.replace(BASE, algo="a2c")


# ---- 7. no code from a declaration: text in any field sympy would parse is refused ---------
def _spec_with(planted, **fields):
    """A one-coordinate spec whose `fields` carry text that, were it evaluated, would write
    the file `planted`."""
    q = me.dynamicsymbols("q")
    m, inertia = sp.symbols("m I")
    params = {m: Param(1.0, "kg"), inertia: Param(1.0, "kg m^2")}
    code = f"__import__('pathlib').Path({str(planted)!r}).write_text('ran') and I"
    base = dict(kinetic=m * q.diff() ** 2 / 2, potential=0 * q, parameters=params)
    base.update({k: v(code, q) for k, v in fields.items()})
    return ModelSpec("planted", (q,), **base)


TEXT_FIELDS = {
    "a body's principal moment": {"bodies": lambda c, q: {"b": (c, "I", "I")}},
    "a body's tensor entry": {"bodies": lambda c, q: {"b": ((c, 0, 0), (0, 1, 0), (0, 0, 1))}},
    "the kinetic energy": {"kinetic": lambda c, q: c},
    "a force": {"forces": lambda c, q: {q: c}},
    "a constraint": {"constraints": lambda c, q: (c,)},
    "an output": {"outputs": lambda c, q: {"y": c}},
    "a condition": {"conditions": lambda c, q: {"I > 0": c}},
    "an input": {"inputs": lambda c, q: (c,)},
    "a coordinate": {"kinetic": lambda c, q: q.diff() ** 2},  # (below: coordinates as text)
}


@pytest.mark.parametrize("case", TEXT_FIELDS)
def test_text_in_a_declaration_is_refused_before_sympy_sees_it(case, tmp_path):
    planted = tmp_path / "planted"
    fields = TEXT_FIELDS[case]
    if case == "a coordinate":
        code = f"__import__('pathlib').Path({str(planted)!r}).write_text('ran')"
        with pytest.raises(TypeError, match="coordinates is text"):
            ModelSpec("planted", (code,), 0, 0, {})
    else:
        with pytest.raises(TypeError, match="is text") as info:
            _spec_with(planted, **fields)
        assert "parse_expression" in str(info.value)
    assert not planted.exists()  # the planted side effect never ran


def test_an_energy_that_is_no_expression_is_named():
    with pytest.raises(TypeError, match="kinetic must be a sympy expression.*got list"):
        _spec_with("unused", kinetic=lambda c, q: [q.diff() ** 2])


# ---- 8. a run's record is not rewritten by a resume with other settings ---------------------
BEAD = "Lagrange/BeadOnRod-v1"
RESUMES = {  # (train's arguments on resuming, the words of the refusal)
    "another seed": ({"seed": 3}, ["seed: 0 in the run, 3 given"]),
    "another n_envs": ({"n_envs": 2}, ["n_envs: 8 in the run, 2 given"]),
    "another hyperparameters file": (
        {"hyperparams": "gamma.yml"},
        ["hyperparams[gamma]", "0.5 given", "--hyperparams"],
    ),
}


def _recorded_run(run_dir):
    """A run directory as agents.train leaves it after a checkpoint (seed 0, 8 envs, the
    packaged hyperparameters); the checkpoint's content is never read by the refusal."""
    import yaml

    from agents.learning.hparams import load_hyperparams

    config = {"env_id": BEAD, "algo": "ppo", "seed": 0, "n_timesteps": 512, "n_envs": 8}
    config["hyperparams"] = load_hyperparams("ppo", BEAD)
    (run_dir / "checkpoints").mkdir(parents=True)
    (run_dir / "checkpoints" / "rl_model_256_steps.zip").write_bytes(b"")
    (run_dir / "config.yml").write_text(yaml.safe_dump(config, sort_keys=False))
    return (run_dir / "config.yml").read_text()


@pytest.mark.parametrize("case", RESUMES)
def test_a_resume_with_another_defining_option_is_refused_unwritten(case, tmp_path):
    from agents.train import train

    before = _recorded_run(tmp_path / "run")
    (tmp_path / "gamma.yml").write_text(f"{BEAD}:\n  gamma: 0.5\n")
    given, words = RESUMES[case]
    if "hyperparams" in given:
        given = {"hyperparams": tmp_path / given["hyperparams"]}
    with pytest.raises(UserError) as info:
        train(BEAD, timesteps=512, run_dir=tmp_path / "run", resume=True, **given)
    for w in words:
        assert w in str(info.value), (w, str(info.value))
    assert (tmp_path / "run" / "config.yml").read_text() == before


def test_a_resume_with_the_run_s_own_settings_passes_the_check(tmp_path):
    from agents.learning.hparams import load_hyperparams
    from agents.learning.rundir import check_resume_defines

    _recorded_run(tmp_path)
    hp = load_hyperparams("ppo", BEAD)
    check_resume_defines(tmp_path, {"seed": 0, "n_envs": 8, "hyperparams": hp, "algo": "ppo"})


@pytest.mark.parametrize("command", ["train", "check", "evaluate", "lqr", "plan"])
def test_every_seed_keeps_to_numpy_s_limit(command, capsys):
    module = importlib.import_module(f"agents.{command}")
    with pytest.raises(SystemExit) as info:
        module.main([BEAD, "--seed", str(2**32)])
    err = capsys.readouterr().err
    assert info.value.code == 2 and "seed from 0 to 2**32 - 1" in err and "Traceback" not in err


# ---- 9. commands that say what is wrong, before any work -----------------------------------
def _learning_bench():
    spec = importlib.util.spec_from_file_location(
        "learning_bench", dynamics.__path__[0] + "/../benchmarks/learning.py"
    )
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def _results(tmp_path, name, text=None, **row):
    """A results.csv of the learning benchmark (one BeadOnRod run, `row` changed)."""
    base = {"system": BEAD, "algo": "ppo", "seed": 0, "success": 0.9, "n": 20, "low": 0.7,
            "high": 0.97, "to80_s": "", "to80_steps": "", "trained_steps": 100,
            "train_s": 5.0, "lqr_share": "", "note": "", "budget_s": 60.0}  # fmt: skip
    base.update(row)
    path = tmp_path / name
    if text is None:
        text = ",".join(base) + "\n" + ",".join(str(v) for v in base.values()) + "\n"
    path.write_text(text)
    return str(path)


LEARNING_COMMANDS = {  # argv (tmp_path -> list), words of the one-line error
    "unknown env id": (lambda d: ["Lagrange/BeadOnRd-v1"], "Did you mean 'Lagrange/BeadOnRod-v1'"),
    "a negative seed": (lambda d: [BEAD, "--seeds=-1"], "expected an integer >= 0, got -1"),
    "no learner": (lambda d: [BEAD, "--algos", ""], "--algos names nothing"),
    "a misspelt learner": (lambda d: [BEAD, "--algos", "ppo,sacc"], "Did you mean 'sac'?"),
    "a learner twice": (lambda d: [BEAD, "--algos", "ppo,ppo"], "--algos names ppo twice"),
    "an env twice": (lambda d: [BEAD, BEAD], "given twice"),
    "--from the same file twice": (
        lambda d: ["--from", _results(d, "a.csv"), _results(d, "a.csv")],
        "is given twice",
    ),
    "--from one run in two files": (
        lambda d: ["--from", _results(d, "a.csv"), _results(d, "b.csv")],
        "give each run once",
    ),
    "--from a header alone": (
        lambda d: ["--from", _results(d, "h.csv", text="system,algo\n")],
        "lacks the column(s) seed",
    ),
    "--from a file without runs": (
        lambda d: ["--from", _results(d, "h.csv", text=",".join(_learning_bench().FIELDS))],
        "holds no runs",
    ),
    "--from a missing file": (lambda d: ["--from", str(d / "none.csv")], "is not a file"),
    "--from a value that is no number": (
        lambda d: ["--from", _results(d, "x.csv", success="lots")],
        "column 'success' must be a number, got 'lots'",
    ),
}


@pytest.mark.parametrize("case", LEARNING_COMMANDS)
def test_the_learning_benchmark_refuses_in_one_line_before_work(case, capsys, tmp_path):
    argv, words = LEARNING_COMMANDS[case]
    out = tmp_path / "out"
    with pytest.raises(SystemExit) as info:
        _learning_bench().main([*argv(tmp_path), "--out", str(out)])
    err = capsys.readouterr().err
    assert info.value.code == 2 and words in err, err
    assert "Traceback" not in err and len(err.strip().splitlines()) == 1
    assert not out.exists()


def test_runs_read_back_are_labelled_by_their_own_budget(tmp_path, capsys):
    bench = _learning_bench()
    assert bench.main(["--from", _results(tmp_path, "a.csv"), "--out", str(tmp_path)]) == 0
    assert "not in 60 s" in (tmp_path / "results.md").read_text()  # not the default 600 s


def test_a_hyperparameters_file_naming_only_a_misspelt_env_is_refused(tmp_path):
    from agents.learning.hparams import load_hyperparams

    path = tmp_path / "hp.yml"
    path.write_text("Lagrange/BeadOnRd-v1:\n  gamma: 0.9\n")
    with pytest.raises(UserError, match="Did you mean 'Lagrange/BeadOnRod-v1'"):
        load_hyperparams("ppo", BEAD, path)


def test_agents_check_refuses_an_env_named_twice(capsys):
    from agents import check

    with pytest.raises(SystemExit) as info:
        check.main([BEAD, BEAD])
    assert info.value.code == 2 and "given twice" in capsys.readouterr().err


# ---- 10. no traceback where the docs promise one line --------------------------------------
def _params_file(tmp_path, text):
    path = tmp_path / "params.yml"
    path.write_text(text)
    return str(path)


AGENT_COMMANDS = {  # (command, argv (tmp_path -> list), the words of the one-line error)
    "train: a negative mass": (
        "train",
        lambda d: [BEAD, "--params", _params_file(d, "m: -1.0\n")],
        "Parameter 'm' of bead_on_driven_rod must be positive, got -1.0",
    ),
    "check: a negative mass": (
        "check",
        lambda d: [BEAD, "--params", _params_file(d, "m: -1.0\n")],
        "Parameter 'm' of bead_on_driven_rod must be positive, got -1.0",
    ),
    "train: a 400-digit integer": (
        "train",
        lambda d: [BEAD, "--params", _params_file(d, "m: " + "9" * 400 + "\n")],
        "m must be a finite number, got an integer of 400 digits",
    ),
    "check: --out a file": ("check", lambda d: [BEAD, "--out", __file__], "is a file, not a"),
}


@pytest.mark.parametrize("case", AGENT_COMMANDS)
def test_agents_commands_refuse_in_one_line_before_work(case, capsys, tmp_path):
    command, argv, words = AGENT_COMMANDS[case]
    module = importlib.import_module(f"agents.{command}")
    more = ["--run-dir", str(tmp_path / "run")] if command == "train" else ["--episodes", "1"]
    try:
        code = module.main([*argv(tmp_path), *more])
    except SystemExit as exc:
        code = exc.code
    err = capsys.readouterr().err
    assert code == 2 and words in err and "Traceback" not in err, err
    assert not (tmp_path / "run").exists()


def test_the_lqr_shaping_is_defined_at_gamma_one():
    """gamma 1 is allowed by the hyperparameter rules: the potential's range is then the
    undiscounted sum over the horizon, the limit of (1 - gamma^H) / (1 - gamma)."""
    from agents.learning.shaping import discounted_steps

    assert discounted_steps(1.0, 200) == 200.0
    # continuous at 1: at 1 - 1e-12 the quotient is 200 (1 - 1e-10); its numerator, about
    # 2e-10, carries a round-off of about 1e-16, a relative 1e-6 at most
    assert discounted_steps(1.0 - 1e-12, 200) == pytest.approx(200.0, rel=1e-6)
    assert discounted_steps(0.5, 3) == 1.75


# ---- 11. leftovers of earlier rounds: each named in one line --------------------------------
def _plan_with_guess(guess):
    from agents.control.ilqr import plan

    env = envs.LagrangianEnv(BASE)
    env.reset(seed=0)
    return plan(env, horizon=0.2, guess=guess, strict=False, max_iterations=1)


LEFTOVERS = {
    "a plan's guess of the wrong shape": (
        lambda: _plan_with_guess(np.zeros((5, 3))),
        ValueError,
        ["plan: guess must be actions of shape (N, 1)", "got shape (5, 3)"],
    ),
    "a plan's guess with NaN": (
        lambda: _plan_with_guess(np.full((5, 1), np.nan)),
        ValueError,
        ["plan: guess must be finite"],
    ),
    "a ragged state at a vector reset": (
        lambda: _vec_reset(ARM, 2).reset(options={"state": [[0.1, 0.0, 0.0, 0.0], [0.2]]}),
        ValueError,
        ["options['state']", "ragged rows"],
    ),
    "LQRHints.R of the wrong length": (
        lambda: dataclasses.replace(BASE, lqr=envs.LQRHints(R=(1.0, 2.0))),
        DeclarationError,
        ["`lqr.R`", "one per action component (1: F)", "(1.0, 2.0)"],
    ),
    "NaN in the operating point": (
        lambda: dataclasses.replace(BASE, operating_point={"theta": float("nan")}),
        DeclarationError,
        ["`operating_point['theta']`", "must be finite"],
    ),
    "a goal given as a name": (
        lambda: dataclasses.replace(BASE, goal=("x*",)),
        DeclarationError,
        ["`goal`", "tuple of Goal", "envs.Goal('x*'"],
    ),
    "a ModelSpec where its factory is expected": (
        lambda: dataclasses.replace(BASE, model=cart_pole.TASK.model()),
        DeclarationError,
        ["`model`", "ModelSpec 'cart_pole' itself", "not my_spec()"],
    ),
    "a kinetic energy given as a list": (
        lambda: _spec_with("unused", kinetic=lambda c, q: [q.diff() ** 2]),
        TypeError,
        ["kinetic must be a sympy expression", "got list"],
    ),
}


@pytest.mark.parametrize("case", LEFTOVERS)
def test_earlier_leftovers_are_named_in_one_line(case):
    make, error, words = LEFTOVERS[case]
    with pytest.raises(error) as info:
        make()
    for w in words:
        assert w in str(info.value), (w, str(info.value))
    assert "\n" not in str(info.value)


def test_lqr_warns_at_an_operating_point_that_is_no_equilibrium():
    from agents.control.lqr_policy import LQRPolicy

    env = envs.LagrangianEnv(dataclasses.replace(BASE, operating_point={"x_dot": 1.0}))
    env.reset(seed=0)
    with pytest.warns(RuntimeWarning, match="not an equilibrium: dx/dt = 1 there"):
        LQRPolicy(env).design()
    with warnings.catch_warnings():  # the task's own (an equilibrium) designs in silence
        warnings.simplefilter("error", RuntimeWarning)
        LQRPolicy(envs.LagrangianEnv(BASE)).design()


# ---- 12. a user's own system: slips named in the user's words ------------------------------
def _term_typo(x, a, goal, p):
    return -0.1 * x.x_dott**2  # x_dot misspelt


def _term_param_typo(x, a, goal, p):
    return -0.1 * x.x_dot**2 * p.m_pol  # m_pole misspelt


def _with_term(fn):
    term = envs.Term("speed", -10.0, 0.0, "", fn)
    return envs.LagrangianEnv(dataclasses.replace(BASE, terms=(*BASE.terms, term)))


def _with_region(**region):
    hints = envs.LQRHints(region={"x": 0.5, "theta": 0.1, "x_dot": 0.1, "theta_dot": 0.1, **region})
    return envs.LagrangianEnv(dataclasses.replace(BASE, lqr=hints))


OWN_SYSTEM = {
    "a reward term's misspelt state": (
        lambda: _with_term(_term_typo),
        [
            "term 'speed'",
            "x has no name 'x_dott'",
            "Did you mean 'x_dot'?",
            "x's names: x, theta, x_dot, theta_dot",
        ],
    ),  # fmt: skip
    "a reward term's misspelt parameter": (
        lambda: _with_term(_term_param_typo),
        ["p has no name 'm_pol'", "Did you mean 'm_pole'?", "p's names: m_cart, m_pole"],
    ),
    "an operating point naming a misspelt goal": (
        lambda: envs.LagrangianEnv(
            dataclasses.replace(
                BASE, goal=(envs.Goal("x_star", "m", -1, 1),), operating_point={"x": "x_sta"}
            )
        ),
        ["'x_sta'", "Did you mean 'x_star'?", "Goals: x_star", "parameters: m_cart"],
    ),
    "an LQR region reaching into the failure set": (
        lambda: _with_region(x=3.0),
        ["`lqr.region['x']` = 3", "reaches into the failure set", "x = 3", "failure"],
    ),
    "an LQR region reaching beyond the limits": (
        lambda: _with_region(x_dot=12.0),
        ["`lqr.region['x_dot']` = 12", "beyond `limits['x_dot']` = 10"],
    ),
}


@pytest.mark.parametrize("case", OWN_SYSTEM)
def test_a_user_s_system_slip_is_named_with_the_names_it_could_mean(case):
    make, words = OWN_SYSTEM[case]
    with pytest.raises(DeclarationError) as info:
        make()
    for w in words:
        assert w in str(info.value), (w, str(info.value))
    assert "Rows_" not in str(info.value) and "\n" not in str(info.value)


def test_every_check_of_a_parameter_name_raises_one_type(tmp_path):
    """A name that is not a model parameter is refused by one function
    (`dynamics.checks.parameter_name`) wherever it is given, as UnknownParameterError (a
    ValueError): the system, the modes, gym.make's keywords, randomize=, the reset option,
    and the agents' randomisation and --params (as UserError carrying its message)."""
    from agents import params
    from agents.learning.randomization import ranges
    from dynamics.checks import UnknownParameterError
    from dynamics.modes import mass_and_stiffness

    arm_id = "Lagrange/TwoLinkArm-v1"
    system = dynamics.get_model("two_link_arm").compile()
    calls = [
        lambda: system.with_parameters(mm1=1.0),
        lambda: mass_and_stiffness(dynamics.get_model("two_link_arm"), [0.0, 0.0], m22=2.0),
        lambda: gym.make(arm_id, m22=2.0),
        lambda: gym.make(arm_id, randomize={"m22": (1.0, 2.0)}),
        lambda: gym.make(arm_id, randomize={}).reset(options={"params": {"m22": 1.0}}),
    ]
    for call in calls:
        with pytest.raises(UnknownParameterError, match="(?i)unknown (parameter|argument) 'm[m2]"):
            call()
    (tmp_path / "p.yml").write_text("m22: 1.4\n")
    for call in (lambda: ranges(system, {"m22": 0.1}),
                 lambda: params.load(tmp_path / "p.yml", arm_id)):  # fmt: skip
        with pytest.raises(UserError, match="unknown parameter 'm22'"):
            call()
