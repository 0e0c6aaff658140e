"""The built-in tasks' drawings on the engine's viewer (`envs.rendering`): the arm, the
bead on its rod, the rolling disk seen by a camera that follows it, the crank and slider."""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from ..rendering import FLOOR, GHOST, GOAL, INK, JOINT, LINK, TRACK, Frame2D, _bar, _dot, _pygame


def _arm_points(theta1: float, theta2: float, l: float, length2: float):
    """Shoulder, elbow and tip; angles from the downward vertical, counter-clockwise +."""
    elbow = (l * math.sin(theta1), -l * math.cos(theta1))
    tip = (elbow[0] + length2 * math.sin(theta2), elbow[1] - length2 * math.cos(theta2))
    return (0.0, 0.0), elbow, tip


def draw_arm(
    surface, x: Sequence[float], goal: Sequence[float] | None, l: float, length2: float
) -> None:
    """The two-link arm (links of length l and length2) and, faint, its goal configuration."""
    frame = Frame2D(surface.get_width(), 1.1 * (l + length2))
    w = 0.08 * frame.scale
    if goal is not None:
        a, b, c = (frame(*p) for p in _arm_points(goal[0], goal[1], l, length2))
        _bar(surface, a, b, w, GHOST)
        _bar(surface, b, c, w, GHOST)
        _dot(surface, c, 0.06 * frame.scale, GOAL, filled=False)
    a, b, c = (frame(*p) for p in _arm_points(x[0], x[1], l, length2))
    _bar(surface, a, b, w, LINK)
    _bar(surface, b, c, w, LINK)
    for p in (a, b):
        _dot(surface, p, 0.05 * frame.scale, JOINT)
    _dot(surface, c, 0.03 * frame.scale, INK)
    _, gfxdraw = _pygame()
    gfxdraw.hline(
        surface, int(a[0] - 0.2 * frame.scale), int(a[0] + 0.2 * frame.scale), int(a[1]), INK
    )


def draw_bead(surface, r: float, phi: float, target: float, rod_length: float) -> None:
    """The rod (angle phi above the horizontal) through its pivot, the bead at distance r,
    and the target distance marked on the rod."""
    frame = Frame2D(surface.get_width(), 0.65 * rod_length)
    c, s = math.cos(phi), math.sin(phi)
    half = rod_length / 2
    _bar(surface, frame(-half * c, -half * s), frame(half * c, half * s), 0.02 * frame.scale, LINK)
    tx, ty = target * c, target * s
    _bar(surface, frame(tx - 0.04 * s, ty + 0.04 * c), frame(tx + 0.04 * s, ty - 0.04 * c), 3, GOAL)
    _dot(surface, frame(0.0, 0.0), 0.025 * frame.scale, JOINT)
    _dot(surface, frame(r * c, r * s), 0.035 * frame.scale, INK)


class Camera:
    """A pinhole camera looking at `target` from azimuth `azimuth` (about the vertical y,
    from +z towards +x) and `elevation` above the horizontal, `distance` metres away."""

    def __init__(self, target, azimuth: float, elevation: float, distance: float, size: int):
        ce, se = math.cos(elevation), math.sin(elevation)
        self.forward = np.array([ce * math.sin(azimuth), -se, ce * math.cos(azimuth)])
        self.right = np.cross(self.forward, [0.0, 1.0, 0.0])
        self.right /= np.linalg.norm(self.right)
        self.up = np.cross(self.right, self.forward)
        self.eye = np.asarray(target, dtype=np.float64) - distance * self.forward
        self.focal = 1.2 * size
        self.size = size

    def depth(self, p) -> np.ndarray:
        return (np.asarray(p) - self.eye) @ self.forward

    def __call__(self, p) -> np.ndarray:
        """Pixel coordinates of world points p (..., 3) in front of the camera."""
        d = np.asarray(p) - self.eye
        z = d @ self.forward
        return np.stack(
            [
                self.size / 2 + self.focal * (d @ self.right) / z,
                self.size / 2 - self.focal * (d @ self.up) / z,
            ],
            axis=-1,
        )

    def segment(self, surface, a, b, color, near: float = 0.1) -> None:
        """A line from world point a to b, clipped to the part in front of the camera."""
        pygame, _ = _pygame()
        da, db = self.depth(a), self.depth(b)
        if da < near and db < near:
            return
        a, b = np.asarray(a, float), np.asarray(b, float)
        if da < near:
            a = a + (b - a) * (near - da) / (db - da)
        elif db < near:
            b = b + (a - b) * (near - db) / (da - db)
        pa, pb = self(a), self(b)
        pygame.draw.aaline(surface, color, pa.tolist(), pb.tolist())


def disk_axes(theta: float, phi: float, psi: float):
    """World (x, y up, z) directions of the rolling disk: i' (rolling direction), j'
    (contact to centre), k' (axle), and a material spoke turned by psi."""
    cf, sf, ct, st = math.cos(phi), math.sin(phi), math.cos(theta), math.sin(theta)
    hx = np.array([cf, 0.0, -sf])  # heading frame: H.z = i', H.y = vertical
    hy = np.array([0.0, 1.0, 0.0])
    i_ = np.array([sf, 0.0, cf])
    j_ = ct * hx + st * hy
    k_ = -st * hx + ct * hy
    spoke = math.cos(psi) * j_ - math.sin(psi) * i_
    return i_, j_, k_, spoke


def draw_disk(
    surface, x: Sequence[float], command: Sequence[float], radius: float, track=None
) -> None:
    """The rolling disk seen in perspective from a camera that follows it: the floor grid,
    the track of the contact point, the disk with two spokes, and an arrow along the
    commanded heading from the contact point. x = [x, z, theta, phi, psi, ...];
    command = (speed, heading)."""
    cx, cz, theta, phi, psi = x[:5]
    contact = np.array([cx, 0.0, cz])
    cam = Camera(
        contact + [0, radius, 0],
        math.radians(35.0),
        math.radians(28.0),
        8 * radius,
        surface.get_width(),
    )
    step = 0.5
    span = 12
    gx, gz = round(cx / step) * step, round(cz / step) * step
    for k in range(-span, span + 1):
        cam.segment(
            surface,
            [gx + k * step, 0, gz - span * step],
            [gx + k * step, 0, gz + span * step],
            FLOOR,
        )
        cam.segment(
            surface,
            [gx - span * step, 0, gz + k * step],
            [gx + span * step, 0, gz + k * step],
            FLOOR,
        )
    if track is not None and len(track) > 1:
        pts = [np.array([px, 0.0, pz]) for px, pz in track]
        for a, b in zip(pts[:-1], pts[1:]):
            cam.segment(surface, a, b, TRACK)
    heading = command[1]
    arrow = contact + 3 * radius * np.array([math.sin(heading), 0.0, math.cos(heading)])
    cam.segment(surface, contact, arrow, GOAL)
    side = 0.4 * radius * np.array([math.cos(heading), 0.0, -math.sin(heading)])
    back = arrow - 0.5 * radius * np.array([math.sin(heading), 0.0, math.cos(heading)])
    cam.segment(surface, arrow, back + side, GOAL)
    cam.segment(surface, arrow, back - side, GOAL)
    i_, j_, k_, spoke = disk_axes(theta, phi, psi)
    centre = contact + radius * j_
    alpha = np.linspace(0.0, 2 * np.pi, 48, endpoint=False)
    rim = centre + radius * (np.cos(alpha)[:, None] * j_ + np.sin(alpha)[:, None] * i_)
    _, gfxdraw = _pygame()
    pix = cam(rim).tolist()
    gfxdraw.filled_polygon(surface, pix, LINK)
    gfxdraw.aapolygon(surface, pix, INK)
    other = math.cos(psi + np.pi / 2) * j_ - math.sin(psi + np.pi / 2) * i_
    for d in (spoke, other):
        a, b = cam(centre - radius * d), cam(centre + radius * d)
        _bar(surface, a, b, 3, JOINT)
    _dot(surface, cam(contact), 3, INK)


def draw_crank(
    surface, theta: float, slider: float, target: float, R: float, l: float, h: float, s: float
) -> None:
    """Problem 7/3's mechanism (x right, y up, axle O at the origin): the disk, drawn with
    radius 1.5 R, turned to `theta` (angle of the pin P from +x, counter-clockwise), its
    mass centre G at s along OP, the rod PS of length l, the slider S at x = `slider` on
    the line y = -h, and the slider's target."""
    x_max = R + l
    extent = 0.6 * (x_max + 1.6 * R)
    frame = Frame2D(surface.get_width(), extent, centre=(0.5 * (x_max - 1.6 * R), -h / 2))
    _, gfxdraw = _pygame()
    line = frame(0.0, -h)[1] + 0.03 * l * frame.scale
    gfxdraw.hline(surface, 0, surface.get_width(), int(line), INK)
    c, sn = math.cos(theta), math.sin(theta)
    _dot(surface, frame(0.0, 0.0), 1.5 * R * frame.scale, GHOST)
    _dot(surface, frame(0.0, 0.0), 1.5 * R * frame.scale, INK, filled=False)
    _dot(surface, frame(s * c, s * sn), 0.08 * R * frame.scale, INK, filled=False)  # G
    tx = frame(target, -h)
    size = 0.12 * l * frame.scale
    _bar(surface, (tx[0], tx[1] - 1.2 * size), (tx[0], tx[1] + 1.2 * size), 3, GOAL)
    sx = frame(slider, -h)
    box = [
        (sx[0] - size, sx[1] - 0.5 * size),
        (sx[0] + size, sx[1] - 0.5 * size),
        (sx[0] + size, sx[1] + 0.5 * size),
        (sx[0] - size, sx[1] + 0.5 * size),
    ]
    gfxdraw.filled_polygon(surface, box, INK)
    pin = frame(R * c, R * sn)
    _bar(surface, pin, sx, 0.04 * l * frame.scale, LINK)
    _dot(surface, frame(0.0, 0.0), 0.1 * R * frame.scale, INK)
    _dot(surface, pin, 0.1 * R * frame.scale, JOINT)
