"""Pygame drawings of the Lagrange environments, in the manner of Gymnasium's classic control.

`Viewer` owns the window (render_mode "human") or an off-screen surface ("rgb_array"); the
`draw_*` functions draw one frame of a system on a pygame Surface from its state. World
coordinates are metres with y up; `Frame2D` and `Camera` map them to pixels.
"""

from __future__ import annotations

import math
import os
from collections.abc import Callable, Sequence

import numpy as np

SIZE = 500
"""Frames are SIZE x SIZE pixels: rgb_array frames have shape (SIZE, SIZE, 3), uint8."""

WHITE = (255, 255, 255)
INK = (30, 30, 30)
LINK = (0, 150, 170)
JOINT = (204, 170, 0)
GOAL = (220, 60, 60)
GHOST = (190, 205, 210)
FLOOR = (225, 225, 225)
TRACK = (90, 120, 200)


def _pygame():
    try:
        import pygame
        from pygame import gfxdraw
    except ImportError as exc:  # pragma: no cover - pygame is a dependency
        raise ImportError("Rendering needs pygame: pip install pygame.") from exc
    return pygame, gfxdraw


class Viewer:
    """A window ("human") or an off-screen canvas ("rgb_array") showing one frame per call.

    rgb_array needs no display (pygame surfaces only, as Gymnasium's classic control);
    human needs one, and warns when SDL found none and shows the frames nowhere."""

    def __init__(self, render_mode: str, fps: int, size: int = SIZE):
        pygame, _ = _pygame()
        self.render_mode, self.fps, self.size = render_mode, fps, size
        if render_mode == "human":
            pygame.display.init()
            driver = pygame.display.get_driver()
            if driver in ("dummy", "offscreen") and "SDL_VIDEODRIVER" not in os.environ:
                import gymnasium

                gymnasium.logger.warn(
                    f"render_mode='human' found no display (SDL chose the {driver!r} video "
                    "driver), so no window opens; use render_mode='rgb_array' for frames."
                )
            self.screen = pygame.display.set_mode((size, size))
        else:
            self.screen = pygame.Surface((size, size))
        self.clock = pygame.time.Clock()

    def show(self, draw: Callable) -> np.ndarray | None:
        """Clear, `draw(surface)`, then show (human) or return an (H, W, 3) uint8 frame."""
        pygame, _ = _pygame()
        surface = pygame.Surface((self.size, self.size))
        surface.fill(WHITE)
        draw(surface)
        self.screen.blit(surface, (0, 0))
        if self.render_mode == "human":
            pygame.event.pump()
            self.clock.tick(self.fps)
            pygame.display.flip()
            return None
        return np.transpose(np.array(pygame.surfarray.pixels3d(self.screen)), axes=(1, 0, 2))

    def close(self) -> None:
        pygame, _ = _pygame()
        if self.render_mode == "human":
            pygame.display.quit()


class Frame2D:
    """Plane world (x right, y up, metres) -> pixels, `extent` metres from centre to edge."""

    def __init__(self, size: int, extent: float, centre: tuple[float, float] = (0.0, 0.0)):
        self.scale = size / (2 * extent)
        self.size = size
        self.cx, self.cy = centre

    def __call__(self, x: float, y: float) -> tuple[float, float]:
        return (
            self.size / 2 + (x - self.cx) * self.scale,
            self.size / 2 - (y - self.cy) * self.scale,
        )


def _bar(surface, a, b, width: float, color) -> None:
    """A filled bar of pixel `width` from pixel point a to b."""
    _, gfxdraw = _pygame()
    dx, dy = b[0] - a[0], b[1] - a[1]
    n = math.hypot(dx, dy) or 1.0
    ox, oy = -dy / n * width / 2, dx / n * width / 2
    pts = [
        (a[0] + ox, a[1] + oy),
        (b[0] + ox, b[1] + oy),
        (b[0] - ox, b[1] - oy),
        (a[0] - ox, a[1] - oy),
    ]
    gfxdraw.aapolygon(surface, pts, color)
    gfxdraw.filled_polygon(surface, pts, color)


def _dot(surface, p, radius: float, color, filled: bool = True) -> None:
    _, gfxdraw = _pygame()
    x, y, r = int(round(p[0])), int(round(p[1])), max(1, int(round(radius)))
    gfxdraw.aacircle(surface, x, y, r, color)
    if filled:
        gfxdraw.filled_circle(surface, x, y, r, color)


def draw_generic(surface, x: Sequence[float], plant) -> None:
    """Any system, one row per coordinate: a dial for each angle (the hand at the angle,
    counter-clockwise from the right) and a slider for each other coordinate within its
    limit (or +-1 when it has none), the rate as a bar beside it."""
    pygame, gfxdraw = _pygame()
    pygame.font.init()
    names, n = plant.system.coordinates, plant.system.n_q
    size = surface.get_width()
    row = size / max(n, 1)
    font = pygame.font.Font(None, max(14, int(row / 5)))
    for i, name in enumerate(names):
        cy = (i + 0.5) * row
        radius = 0.35 * min(row, size / 3)
        label = font.render(name, True, INK)
        surface.blit(label, (8, cy - label.get_height() / 2))
        if plant.periodic[i]:
            cx = size / 2
            _dot(surface, (cx, cy), radius, GHOST)
            _dot(surface, (cx, cy), radius, INK, filled=False)
            tip = (cx + radius * math.cos(x[i]), cy - radius * math.sin(x[i]))
            _bar(surface, (cx, cy), tip, 4, LINK)
            _dot(surface, (cx, cy), 4, JOINT)
        else:
            bound = plant.limits[i] if np.isfinite(plant.limits[i]) else 1.0
            left, right = 0.25 * size, 0.85 * size
            gfxdraw.hline(surface, int(left), int(right), int(cy), INK)
            frac = 0.5 + 0.5 * max(-1.0, min(1.0, x[i] / bound))
            _dot(surface, (left + frac * (right - left), cy), 0.25 * radius, LINK)
        rate = x[n + i]
        bound = plant.limits[n + i] if np.isfinite(plant.limits[n + i]) else 10.0
        width = 0.1 * size * max(-1.0, min(1.0, rate / bound))
        x0 = 0.92 * size
        _bar(surface, (x0, cy), (x0 + width, cy), 6, TRACK)
