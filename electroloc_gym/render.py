"""Matplotlib figures: EEV maps (Fig. 2 / Fig. 9), belief snapshots (Fig. 10) and episode frames.

Everything renders off-screen with the Agg canvas unless ``render_mode="human"`` asks for a window.
"""

from __future__ import annotations

import functools
from typing import Any

import numpy as np
from numpy.typing import NDArray

from electroloc_gym.conditions import Condition
from electroloc_gym.fileio import save_figure_atomic
from electroloc_gym.sensor import electrode_positions_mm, expected_reading

__all__ = ["eev_map", "plot_eev", "FrameRenderer", "EpisodeRenderer", "save_figure_atomic"]


def eev_map(condition: Condition, half_span_mm: float | None = None, step_mm: float = 1.0
            ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Expected reading (V) over carriage positions relative to the target: (grid_mm, Φ[ix, iy]).

    ``Φ[i, j]`` is the noise-free reading with the carriage at ``(grid[i], grid[j])`` and the target
    at the origin (the paper's EEV, Fig. 2 / Fig. 9).
    """
    h = 1.2 * condition.allowed_half_width_mm if half_span_mm is None else half_span_mm
    grid = np.arange(-h, h + 1e-9, step_mm)
    gx, gy = np.meshgrid(grid, grid, indexing="ij")
    carriage = np.stack([gx, gy], axis=-1)
    return grid, expected_reading(condition, -carriage)


def plot_eev(condition: Condition, ax: Any = None, threshold_sigmas: float = 2.0) -> Any:
    """Draw the EEV of ``condition`` with the ±kσ detection contour; returns the axes."""
    import matplotlib.pyplot as plt

    grid, phi = eev_map(condition)
    if ax is None:
        _, ax = plt.subplots(figsize=(5.5, 4.6))
    vmax = max(float(np.abs(phi).max()), 1e-12)
    im = ax.pcolormesh(grid, grid, phi.T, cmap="RdBu_r", vmin=-vmax, vmax=vmax, shading="auto")
    thr = threshold_sigmas * condition.noise_std_V
    if thr < vmax:
        ax.contour(grid, grid, np.abs(phi).T, levels=[thr], colors="k", linewidths=1.0)
    ax.contour(grid, grid, phi.T, levels=[0.0], colors="0.4", linewidths=0.6, linestyles=":")
    ax.set_aspect("equal")
    ax.set_xlabel("carriage x − target x (mm)")
    ax.set_ylabel("carriage y − target y (mm)")
    ax.set_title(f"EEV {condition.name} (scale {condition.signal_scale:.2f}); black: ±{threshold_sigmas:g}σ")
    ax.figure.colorbar(im, ax=ax, label="expected reading Φ (V)")
    return ax


@functools.lru_cache(maxsize=16)
def _world_eev(condition: Condition, target: tuple[float, float], step_mm: float = 1.5):
    h = condition.allowed_half_width_mm + 10.0
    grid = np.arange(-h, h + 1e-9, step_mm)
    gx, gy = np.meshgrid(grid, grid, indexing="ij")
    phi = expected_reading(condition, np.asarray(target) - np.stack([gx, gy], axis=-1))
    return grid, phi


class FrameRenderer:
    """A 5×5-inch frame that env renderers draw into: off-screen (``rgb_array``) or a window (``human``)."""

    def __init__(self, render_mode: str) -> None:
        if render_mode == "rgb_array":
            from matplotlib.backends.backend_agg import FigureCanvasAgg
            from matplotlib.figure import Figure

            self.fig = Figure(figsize=(5, 5), dpi=96)
            FigureCanvasAgg(self.fig)
        else:
            import matplotlib.pyplot as plt

            self.fig = plt.figure(figsize=(5, 5), dpi=96)  # headless (Agg): draws, just no window
        self.render_mode = render_mode
        self.ax = self.fig.add_subplot(111)

    def finish(self) -> NDArray[np.uint8] | None:
        """Draw the canvas; the RGB array for ``rgb_array``, a short GUI pause for ``human``."""
        self.fig.canvas.draw()
        if self.render_mode == "rgb_array":
            buf = np.asarray(self.fig.canvas.buffer_rgba())
            return np.ascontiguousarray(buf[..., :3])
        import matplotlib.pyplot as plt

        plt.pause(1.0 / 30)
        return None

    def close(self) -> None:
        """Release the figure."""
        import matplotlib.pyplot as plt

        plt.close(self.fig)


class EpisodeRenderer(FrameRenderer):
    """Draws an :class:`~electroloc_gym.envs.localize.ElectroLocEnv` frame like the paper's Fig. 10.

    EEV shading of the true target over carriage positions, the particles, the true target, the
    estimate with its spread circle, the carriage electrodes and the path.
    """

    def draw(self, env: Any) -> NDArray[np.uint8] | None:
        """Draw the env's current state; returns an RGB array for ``rgb_array``."""
        ax = self.ax
        ax.clear()
        c = env.condition
        target = env.unwrapped._target  # the renderer may show the truth; agents may not read it
        grid, phi = _world_eev(c, (float(target[0]), float(target[1])))
        vmax = max(float(np.abs(phi).max()), 1e-12)
        ax.pcolormesh(grid, grid, phi.T, cmap="RdBu_r", vmin=-vmax, vmax=vmax, shading="auto", alpha=0.8)
        h = c.allowed_half_width_mm
        ax.plot([-h, h, h, -h, -h], [-h, -h, h, h, -h], color="0.3", lw=0.8)
        p = env.belief.particles
        ax.scatter(p[:, 0], p[:, 1], s=1.5, c="k", alpha=0.35, linewidths=0)
        est = env.belief.mean()
        spread = env.belief.spread()
        ax.add_patch(_circle(est, spread, "tab:green"))
        ax.plot(*est, "+", color="tab:green", ms=10, mew=2, label="estimate")
        ax.plot(*target, "o", mfc="none", mec="tab:orange", ms=2 * c.target.radius_mm * 0.35 + 4, mew=2,
                label="target")
        path = env.path_mm
        ax.plot(path[:, 0], path[:, 1], "-", color="tab:purple", lw=1.2)
        el = electrode_positions_mm(c, env.position_mm)
        for key, style in (("emitter+", "r^"), ("emitter-", "b^"), ("S1", "ks"), ("S2", "ks")):
            ax.plot(*el[key], style, ms=6)
        ax.set_xlim(-h - 10, h + 10)
        ax.set_ylim(-h - 10, h + 10)
        ax.set_aspect("equal")
        ax.set_title(f"{c.name}: obs {env.n_observations}, spread {spread:.1f} mm", fontsize=9)
        ax.legend(loc="upper right", fontsize=7)
        return self.finish()


def _circle(center: NDArray, radius: float, color: str):
    from matplotlib.patches import Circle

    return Circle(tuple(center), radius, fill=False, color=color, lw=1.2, ls="--")
