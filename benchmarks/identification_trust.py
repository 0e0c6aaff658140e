"""Is every estimate right or flagged? Records like a user's, each unknown judged.

    python benchmarks/identification_trust.py

Records made by the project's own simulation with sensor noise (std 1e-3 rad or m,
1e-2 per s) that the fit is not told: the rolling disk recorded on its env at 100 and
20 Hz, the arm driven fast (rates to 45 rad/s), the arm with its shoulder held by a stiff
servo and only the elbow driven, the arm with friction on its joints (the elbow's on the
relative rate), the arm's positions alone at its env's 20 Hz, and the arm at 100 Hz under
LQR. Each unknown is *right* (the truth within 3 standard errors, that error at most 25 %
of the value), *flagged* (listed in `Identification.undetermined`, kept at its given value)
or *wrong*. Prints a Markdown table and the totals.
"""

from __future__ import annotations

import os
import sys
import warnings
from pathlib import Path

os.environ.setdefault("OMP_NUM_THREADS", "1")
sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

import numpy as np  # noqa: E402

import dynamics  # noqa: E402
from agents.common import check_env_id  # noqa: E402
from agents.control.recording import fit as env_fit  # noqa: E402
from agents.control.recording import record  # noqa: E402
from dynamics.excite import multisine  # noqa: E402
from dynamics.identify import REL_STD, identify  # noqa: E402
from dynamics.regression import with_noise  # noqa: E402
from dynamics.regressor import with_friction  # noqa: E402

ARM = dict(m1=1.3, m2=0.8, Ibar1=0.1, Ibar2=0.06)
NOISE = (1e-3, 1e-2)
MOTORS = {"max_input": [29.43, 7.3575]}


def simulate(system, x0, controls, seconds=20.0, h=0.01):
    """{t, q, qd, u} of `system` stepped from x0 (10 substeps a sample); controls(k, x) -> u."""
    t = np.arange(int(round(seconds / h)) + 1) * h
    x, X, U = np.asarray(x0, dtype=float), [], []
    for k in range(len(t)):
        u = controls(k, x)
        X.append(x)
        U.append(u)
        x = system.step(x, u, dt=h, substeps=10)
    X = np.array(X)
    n = X.shape[1] // 2
    return {"t": t, "q": X[:, :n], "qd": X[:, n:], "u": np.array(U)}


def noisy(data, seed=0):
    return with_noise(data, NOISE, seed)


def judge(fit, truth: dict) -> dict:
    out = {}
    for name, true in truth.items():
        if name in fit.undetermined:
            out[name] = "flagged"
            continue
        value = fit.parameters.get(name)
        if value is None:  # a friction coefficient
            kind, joint = name.split("_", 1)
            value = fit.friction[joint][kind]
        s = fit.std[name]
        right = abs(value - true) <= 3 * s and s <= REL_STD * abs(value)
        off = f"{value / true - 1:+.1%}, {(value - true) / s:+.1f} sd"
        out[name] = "right" if right else f"wrong ({off})"
    return out


def env_case(env_id, plant, rate, keys=("t", "q", "qd", "u")):
    data = record(check_env_id(env_id, lagrange=True), 20.0, plant, NOISE, rate=rate)
    truth = dict(zip(data["plant_names"].tolist(), data["plant_values"].tolist()))
    fit = env_fit(env_id, {k: data[k] for k in keys})
    return judge(fit, {k: truth[k] for k in fit.unknown}), fit.warnings


def arm_cases():
    arm = dynamics.get_model("two_link_arm")
    system = arm.compile(**ARM)
    t = np.arange(2001) * 0.01
    fast = multisine([14.0, 6.0], period=10.0, harmonics=4, fraction=0.9)(t)
    data = noisy(simulate(system, [0.1, 0.2, 0, 0], lambda k, x: fast[k]))
    yield "arm driven fast, q and qd", judge(identify(arm, data), ARM), []
    elbow = multisine([3.0], period=10.0, harmonics=4, fraction=0.5)(t)[:, 0]
    held = noisy(simulate(system, [0.3, 0.2, 0, 0], lambda k, x: np.array(
        [-2000 * (x[0] - 0.3) - 90 * x[2], elbow[k]])))  # fmt: skip
    yield "arm, shoulder held by a servo, elbow driven", judge(identify(arm, held), ARM), []
    joints = {"shoulder": ("theta1", "viscous+coulomb"),
              "elbow": ("theta2 - theta1", "viscous+coulomb")}  # fmt: skip
    friction = {"viscous_shoulder": 0.1, "coulomb_shoulder": 0.3,
                "viscous_elbow": 0.08, "coulomb_elbow": 0.25}  # fmt: skip
    drive = multisine([6.0, 3.0], period=10.0, harmonics=4, fraction=0.8)(t)
    plant = with_friction(arm, joints).compile(**ARM, **friction)
    data = noisy(simulate(plant, [0.1, 0.2, 0, 0], lambda k, x: drive[k]))
    fit = identify(arm, data, friction=joints)
    yield "arm with joint friction, fitted on its joints", judge(fit, ARM | friction), []


def main() -> int:
    warnings.simplefilter("ignore")
    rows = []
    for rate in (100.0, 20.0):
        verdict, said = env_case("Lagrange/RollingDisk-v1", {"I": 0.0675}, rate)
        rows.append((f"rolling disk (I x 3) on its env at {rate:g} Hz", verdict, said))
    rows += list(arm_cases())
    arm_plant = {"m2": 0.25} | MOTORS
    verdict, said = env_case("Lagrange/TwoLinkArm-v1", arm_plant, None, ("t", "q", "u"))
    rows.append(("arm (m2 x 0.25), positions only at its env's 20 Hz", verdict, said))
    verdict, said = env_case("Lagrange/TwoLinkArm-v1", arm_plant, 100.0)
    rows.append(("arm (m2 x 0.25) at 100 Hz under LQR", verdict, said))
    print("| record | right | flagged | wrong | warned |\n|---|---|---|---|---|")
    totals = {"right": 0, "flagged": 0, "wrong": 0}
    for label, verdict, said in rows:
        cols = {k: [n for n, v in verdict.items() if v.startswith(k)] for k in totals}
        for k in totals:
            totals[k] += len(cols[k])
        wrong = ", ".join(f"{n} {verdict[n][6:]}" for n in cols["wrong"])
        print(f"| {label} | {', '.join(cols['right'])} | {', '.join(cols['flagged'])} | "
              f"{wrong} | {'yes' if said else ''} |")  # fmt: skip
    print(f"\n{totals['right']} right, {totals['flagged']} flagged, {totals['wrong']} wrong")
    return 0


if __name__ == "__main__":
    sys.exit(main())
