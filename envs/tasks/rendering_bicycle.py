"""The Whipple bicycle drawn in perspective: frame, wheels, fork and handlebar, rider.

The points follow the model's own frames (`dynamics.models.bicycle`): N.x forward, N.y
right, N.z down; heading psi about N.z, lean phi about the heading axis, pitch theta about
the rear axle, the steering axis tilted back by lam, steer delta about it. A camera behind
and to the left of the rider follows the rear contact, turning with the heading, so lean
shows as the frame tilting and steer as the front wheel and handlebar turning.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from .rendering import FLOOR, GHOST, GOAL, INK, JOINT, LINK, TRACK, Camera, _bar, _dot, _pygame


def _rx(a: float) -> np.ndarray:
    c, s = math.cos(a), math.sin(a)
    return np.array([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]])


def _ry(a: float) -> np.ndarray:
    c, s = math.cos(a), math.sin(a)
    return np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])


def _rz(a: float) -> np.ndarray:
    c, s = math.cos(a), math.sin(a)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def bicycle_points(q: Sequence[float], p) -> dict[str, np.ndarray]:
    """World points (N axes, metres) of the bicycle at coordinates q = (x, y, psi, phi,
    theta, delta, theta_R, theta_F) and parameters p (w, c, lam, r_R, r_F, x_B, z_B); the
    columns of 'B', 'H' are the rear and front frames' axes in N."""
    x, y, psi, phi, theta, delta, th_R, th_F = (float(v) for v in q[:8])
    L = _rz(psi) @ _rx(phi)  # heading, then lean about the heading axis
    B = L @ _ry(theta)  # rear frame: pitch about the rear axle L.y
    E = B @ _ry(p.lam)  # E.z: the steering axis, pointing down and forward
    H = E @ _rz(delta)  # front frame: steer about E.z; H.y the front axle
    Hr = H @ _ry(-p.lam)  # H turned back by lam: N's axes in the reference configuration
    P = np.array([x, y, 0.0])
    R = P - p.r_R * L[:, 2]  # rear wheel centre
    S = R + B @ np.array([p.w + p.c, 0.0, p.r_R])  # steering axis at ground level
    F = S + Hr @ np.array([-p.c, 0.0, -p.r_F])  # front wheel centre
    axis = E[:, 2]
    head_low = S - (p.r_F + 0.15) * axis
    head_top = S - (p.r_F + 0.45) * axis
    seat = R + B @ np.array([0.2, 0.0, -0.55])
    shoulders = seat + B @ np.array([0.3, 0.0, -0.5])
    crank = R + B @ np.array([0.4, 0.0, -0.05])
    rider = R + B @ np.array([p.x_B, 0.0, p.z_B + p.r_R])
    return dict(
        P=P,
        R=R,
        S=S,
        F=F,
        head_low=head_low,
        head_top=head_top,
        seat=seat,
        crank=crank,
        rider=rider,
        shoulders=shoulders,
        B=B,
        H=H,
        th_R=th_R,
        th_F=th_F,
    )


def _up(v) -> np.ndarray:
    """N components (x forward, y right, z down) -> the camera's world (y up)."""
    v = np.asarray(v, float)
    return np.stack([v[..., 0], -v[..., 2], v[..., 1]], axis=-1)


def _wheel(surface, cam, centre, plane_x, plane_z, radius, turn, color) -> None:
    """A wheel: rim in the plane of `plane_x`, `plane_z` and two spokes turned by `turn`."""
    _, gfxdraw = _pygame()
    a = np.linspace(0.0, 2 * np.pi, 48, endpoint=False)[:, None]
    rim = centre + radius * (np.cos(a) * plane_x + np.sin(a) * plane_z)
    pix = cam(_up(rim)).tolist()
    gfxdraw.aapolygon(surface, pix, INK)
    for k in range(2):
        b = turn + k * np.pi / 2
        d = radius * (math.cos(b) * plane_x + math.sin(b) * plane_z)
        _bar(surface, cam(_up(centre - d)), cam(_up(centre + d)), 1.5, color)
    _dot(surface, cam(_up(centre)), 3, INK)


def draw_bicycle(surface, x: Sequence[float], speed_goal: float, p, track=None) -> None:
    """One frame of the bicycle from the state row x (q then q'), the commanded speed shown
    as an arrow of that length (m/s as metres) ahead of the rear contact, and the rear
    contact's past track [(x, y), ...]."""
    pts = bicycle_points(x, p)
    psi = float(x[2])
    heading = np.array([math.cos(psi), math.sin(psi), 0.0])
    left = np.array([math.sin(psi), -math.cos(psi), 0.0])
    target = pts["P"] + 0.45 * p.w * heading
    view = _up(heading - 0.35 * left)  # looking ahead and right: from behind, to the left
    azimuth = math.atan2(view[0], view[2])
    cam = Camera(
        _up(target + np.array([0, 0, -0.7])), azimuth, math.radians(15), 3.0, surface.get_width()
    )
    step, span = 0.5, 14
    gx, gy = round(pts["P"][0] / step) * step, round(pts["P"][1] / step) * step
    for k in range(-span, span + 1):
        for a, b in (((k, -span), (k, span)), ((-span, k), (span, k))):
            cam.segment(
                surface,
                _up([gx + a[0] * step, gy + a[1] * step, 0.0]),
                _up([gx + b[0] * step, gy + b[1] * step, 0.0]),
                FLOOR,
            )
    if track is not None and len(track) > 1:
        ground = [_up([tx, ty, 0.0]) for tx, ty in track]
        for a, b in zip(ground[:-1], ground[1:]):
            cam.segment(surface, a, b, TRACK)
    tip = pts["P"] + 0.3 * speed_goal * heading
    cam.segment(surface, _up(pts["P"]), _up(tip), GOAL)
    upright = pts["P"] - 1.2 * np.array([0.0, 0.0, 1.0])  # the vertical through P
    cam.segment(surface, _up(pts["P"]), _up(upright), GHOST)
    B, H = pts["B"], pts["H"]
    _wheel(surface, cam, pts["R"], B[:, 0], B[:, 2], p.r_R, -pts["th_R"], JOINT)
    _wheel(surface, cam, pts["F"], H[:, 0], H[:, 2], p.r_F, -pts["th_F"], JOINT)
    px = lambda v: cam(_up(v))  # noqa: E731
    for a, b in (
        ("R", "crank"),
        ("R", "seat"),
        ("crank", "seat"),
        ("seat", "head_top"),
        ("crank", "head_low"),
        ("head_low", "head_top"),
    ):
        _bar(surface, px(pts[a]), px(pts[b]), 4, LINK)
    _bar(surface, px(pts["head_low"]), px(pts["F"]), 3, INK)  # the fork
    bar = 0.25 * H[:, 1]
    _bar(surface, px(pts["head_top"] - bar), px(pts["head_top"] + bar), 3, INK)  # handlebar
    _bar(surface, px(pts["seat"]), px(pts["shoulders"]), 6, INK)  # the rider's torso,
    _bar(surface, px(pts["shoulders"]), px(pts["head_top"]), 3, INK)  # arms
    _dot(surface, px(pts["shoulders"] - 0.15 * B[:, 2]), 8, INK)  # and head
    _dot(surface, px(pts["rider"]), 4, GOAL)  # the rear frame's mass centre
