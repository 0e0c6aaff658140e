"""Segway-like wheeled inverted pendulum: two wheels rolling without slipping on the floor carry
an inverted body between them; ride straight at a commanded speed without falling.
`examples.segway:Examples/Segway-v0`.

## Description
A body (mass M, centre of mass l above the axle) pitches about an axle carried by two
wheels of radius r at distance d either side of its middle. Each wheel rolls without
slipping (no sideways slip, no longitudinal slip: three nonholonomic constraints on six
coordinates) and is driven by its own motor mounted on the body, which acts on the body
in reaction. The task: balance and ride straight at a commanded speed v*, drawn at reset,
from rest.

```
        | body              x, y: the axle's middle on the floor (m); psi: heading from
        |  theta            the x axis, counter-clockwise from above (rad); theta: the
   (L)==o==(R)  axle        body's pitch from upright, + tipping forward (rad);
                            phi_l, phi_r: the wheels' spin about the axle, + rolling
                            forward (rad); forward speed v = r (phi_l' + phi_r') / 2.
```

## Action Space
`Box(-1, 1, (2,), float32)`: the motor torques tau_l, tau_r on the left and right wheels
(the body feels -(tau_l + tau_r) in pitch), action 1 = `max_input` = 10 N*m each.
Clipped; NaN or inf raise.

## Observation Space
`Box(low, high, (9,), float32)`: cos theta, sin theta, theta_dot (+-20 rad/s), psi_dot
(+-10 rad/s), phi_l_dot, phi_r_dot (+-40 rad/s), the command v* (in [-1, 1] m/s), the speed
error v - v* (+-6 m/s). The position, heading and wheel angles are cyclic and not
observed (LQR rebuilds x', y' from the rolling constraints).

## Rewards
A quadratic cost: `speed` = -(v - v*)^2 (in [-36, 0]), `pitch` = -theta^2 (wrapped, in
[-pi^2, 0]), `turn` = -0.1 psi_dot^2 (in [-10, 0]), `effort` = -0.01 |action|^2 (in
[-0.02, 0]).

## Starting State
At rest at the origin, heading psi uniform in +-pi, pitch theta uniform in +-0.05 rad;
v* uniform in [-1, 1] m/s.

## Episode End
Termination: |theta| > 0.5 rad (fallen), or divergence; the step then pays the early-end
penalty. Truncation: 300 steps (6 s at 50 Hz). Success (at the last step): |v - v*| < 0.1
m/s, |psi_dot| < 0.1 rad/s, |theta| < 0.1 rad. `info["constraint_residual"]`: the rolling
constraints' residual (m/s), kept at round-off by a projection after every step.

## Arguments
`gymnasium.make("Examples/Segway-v0", **params)` with the model's parameters by name: M,
l, I_pitch, I_roll, I_yaw (the body), m_w, r, J_w, K_w (each wheel: mass, radius, spin and
diametral inertia), d (half the track), g; and the env's options.

## Version History
* v0: initial version.
"""

import numpy as np
import sympy as sp
import sympy.physics.mechanics as me

import envs
from dynamics.spec import ModelSpec, Param

ID = "Examples/Segway-v0"
SPEEDS = (-1.0, 1.0)
"""Commanded speeds are drawn uniformly from this range (m/s)."""


def segway() -> ModelSpec:
    """Coordinates (x, y, psi, theta, phi_l, phi_r), see the module's sketch; the left
    wheel at +d along the axle (to the left of the heading). Inputs tau_l, tau_r: motor
    torques, body on wheel (N*m). Rolling: the contact point of each wheel is at rest."""
    x, y, psi, th, ph_l, ph_r = me.dynamicsymbols("x y psi theta phi_l phi_r")
    M, l, Ip, Ir, Iy = sp.symbols("M l I_pitch I_roll I_yaw", positive=True)
    m_w, r, J, K, d, g = sp.symbols("m_w r J_w K_w d g", positive=True)
    tau_l, tau_r = sp.symbols("tau_l tau_r")
    N = me.ReferenceFrame("N")  # N.z up
    H = N.orientnew("H", "Axis", (psi, N.z))  # heading: H.x forward, H.y left
    B = H.orientnew("B", "Axis", (th, H.y))  # the body: B.z along it, tips to +H.x
    axle = x * N.x + y * N.y
    centre = axle + l * B.z
    v_c, w_b = centre.dt(N), B.ang_vel_in(N)
    T = M * v_c.dot(v_c) / 2 + w_b.dot(me.inertia(B, Ir, Ip, Iy).dot(w_b)) / 2
    for side, ph in ((1, ph_l), (-1, ph_r)):
        v_w = (axle + side * d * H.y).dt(N)
        T += m_w * v_w.dot(v_w) / 2 + (J * ph.diff() ** 2 + K * psi.diff() ** 2) / 2
    v = x.diff() * sp.cos(psi) + y.diff() * sp.sin(psi)  # the axle's forward speed
    constraints = (
        v - d * psi.diff() - r * ph_l.diff(),  # left wheel: no longitudinal slip
        v + d * psi.diff() - r * ph_r.diff(),  # right wheel
        -x.diff() * sp.sin(psi) + y.diff() * sp.cos(psi),  # no sideways slip
    )
    forces = {ph_l: tau_l, ph_r: tau_r, th: -tau_l - tau_r}  # motors between body, wheels
    params = {
        M: Param(10.0, "kg", "mass of the body"),
        l: Param(0.3, "m", "height of the body's centre of mass above the axle"),
        Ip: Param(0.5, "kg*m^2", "the body's central moment of inertia in pitch"),
        Ir: Param(0.5, "kg*m^2", "the body's central moment of inertia in roll"),
        Iy: Param(0.2, "kg*m^2", "the body's central moment of inertia in yaw"),
        m_w: Param(1.0, "kg", "mass of each wheel"),
        r: Param(0.15, "m", "wheel radius"),
        J: Param(0.0113, "kg*m^2", "each wheel's moment of inertia about its axle"),
        K: Param(0.0056, "kg*m^2", "each wheel's moment of inertia about a diameter"),
        d: Param(0.25, "m", "half the distance between the wheels"),
        g: Param(9.81, "m/s^2"),
    }
    return ModelSpec(
        "segway",
        (x, y, psi, th, ph_l, ph_r),
        sp.expand(T),
        M * g * l * sp.cos(th),
        params,
        (tau_l, tau_r),
        forces,
        constraints,
    )


def riding(x, goal, p):
    """Upright, riding straight at v* along the current heading: a steady motion (the
    cyclic coordinates as they are), which needs no torque."""
    v, psi = goal.v_star, x.psi
    return {  # theta and the rates of psi and theta 0
        "x": x.x,
        "y": x.y,
        "psi": psi,
        "phi_l": x.phi_l,
        "phi_r": x.phi_r,
        "x_dot": v * np.cos(psi),
        "y_dot": v * np.sin(psi),
        "phi_l_dot": v / p.r,
        "phi_r_dot": v / p.r,
    }


def speed_error(x, a, goal, p):
    return p.r * (x.phi_l_dot + x.phi_r_dot) / 2 - goal.v_star


def speed(x, a, goal, p):
    e = p.r * (x.phi_l_dot + x.phi_r_dot) / 2 - goal.v_star
    return -e * e


def pitch(x, a, goal, p):
    e = envs.wrap(x.theta)
    return -e * e


def turn(x, a, goal, p):
    return -0.1 * x.psi_dot**2


def effort(x, a, goal, p):
    return -0.01 * (a.tau_l**2 + a.tau_r**2)


def success(x, a, goal, p):
    e = p.r * (x.phi_l_dot + x.phi_r_dot) / 2 - goal.v_star
    return (np.abs(e) < 0.1) & (np.abs(x.psi_dot) < 0.1) & (np.abs(envs.wrap(x.theta)) < 0.1)


def failure(x, a, goal, p):
    return np.abs(envs.wrap(x.theta)) > 0.5


TASK = envs.Task(
    name="Segway",
    model=segway,
    actuated=("tau_l", "tau_r"),
    max_input=(10.0, 10.0),
    observation=(
        envs.Angle("theta"),
        envs.Value("theta_dot", unit="rad/s"),
        envs.Value("psi_dot", unit="rad/s"),
        envs.Value("phi_l_dot", unit="rad/s"),
        envs.Value("phi_r_dot", unit="rad/s"),
        envs.Value("v*"),
        envs.Derived("v - v*", speed_error, -6.0, 6.0, "m/s"),
    ),
    terms=(
        envs.Term("speed", -36.0, 0, "-(v - v*)^2", speed),
        envs.Term("pitch", -(np.pi**2), 0, "-theta^2", pitch),
        envs.Term("turn", -10.0, 0, "-0.1 psi_dot^2", turn),
        envs.Term("effort", -0.02, 0, "-0.01 |action|^2", effort),
    ),
    success=success,
    failure=failure,
    goal=(envs.Goal("v*", "m/s", *SPEEDS, doc="commanded forward speed"),),
    start={"psi": (-np.pi, np.pi), "theta": (-0.05, 0.05)},
    limits={
        "x_dot": 5.0,
        "y_dot": 5.0,
        "psi_dot": 10.0,
        "theta_dot": 20.0,
        "phi_l_dot": 40.0,
        "phi_r_dot": 40.0,
    },
    operating_point=riding,
    control_period=0.02,
    substeps=2,
    max_episode_steps=300,
    # x, y, psi and the wheel angles are cyclic, x', y', psi' fixed by the rolling
    lqr=envs.LQRHints(
        states=("theta", "theta_dot", "phi_l_dot", "phi_r_dot"),
        scales={"theta": 0.1, "theta_dot": 1.0, "phi_l_dot": 1.0, "phi_r_dot": 1.0},
        region={"theta": 0.05, "theta_dot": 0.0, "phi_l_dot": 1.0, "phi_r_dot": 1.0},
    ),
)
envs.register(ID, TASK)
