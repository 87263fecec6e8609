"""Matplotlib frames of an episode (paper Fig. 10, 13): ``env.render()``, snapshot grids and GIF frames.

Renderers read only the env's public accessors (on ``env.unwrapped``): ``condition``, ``belief``,
``position_mm``, ``path_mm``, ``n_observations``, ``last_reading_V``, and the ground truth a picture may
show but an agent may not act on — ``target_mm`` (ElectroLoc-v0) or the map ``scene`` with the true
carriage ``position_mm`` (ElectroLocGlobal-v0). :func:`snapshot` copies those values once; every
drawing function takes a :class:`Snapshot`, so a frame, a grid panel (:mod:`electroloc_gym.demo`) and
a GIF frame show the same thing.

Markers follow the paper's figures: sensors are diamonds, emitters squares, the path asterisks; the
particles are dots; the estimate is a plus inside a dashed circle of radius √trace Σ (the spread the
success rule tests). Behind them lies the EEV of the true target (or of the map), on a grid that covers
the allowed box and the carriage's arms, cached per target (or map). Objects are coloured as in
the EEV maps of :mod:`electroloc_gym.views.eev_maps` (the paper's Fig. 2, 9, 14), whose functions are
re-exported here. Everything renders off-screen with the Agg canvas unless ``render_mode="human"``.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, cast

import numpy as np
from numpy.typing import NDArray

from electroloc_gym.utils.fileio import save_figure_atomic
from electroloc_gym.views.eev_maps import _CONDUCTOR, _INSULATOR, eev_map, plot_eev, plot_map_eev
from electroloc_gym.world.conditions import Condition
from electroloc_gym.world.sensor import electrode_positions_mm, expected_reading

if TYPE_CHECKING:
    from matplotlib.backends.backend_agg import FigureCanvasAgg

__all__ = [
    "eev_map",
    "plot_eev",
    "plot_map_eev",
    "Snapshot",
    "snapshot",
    "draw_snapshot",
    "eev_colorbar",
    "legend_handles",
    "FrameRenderer",
    "EpisodeRenderer",
    "GlobalEpisodeRenderer",
    "save_figure_atomic",
]

_SENSOR = dict(marker="D", color="k", ms=6, ls="none")
_EMITTER_POS = dict(marker="s", color="tab:red", ms=6, ls="none")
_EMITTER_NEG = dict(marker="s", color="tab:blue", ms=6, ls="none")
_ESTIMATE = dict(marker="+", color="tab:green", ms=11, mew=2.2, ls="none")


# ---- the EEV behind a frame ---------------------------------------------------------------------------
@functools.lru_cache(maxsize=16)
def _target_eev(condition: Condition, target: tuple[float, float], step_mm: float = 1.0):
    """EEV of a target at ``target`` over carriage positions in the world frame (grid, Φ[ix, iy])."""
    h = _view_half_width_mm(condition)
    grid = np.arange(-h, h + 1e-9, step_mm)
    gx, gy = np.meshgrid(grid, grid, indexing="ij")
    return grid, expected_reading(condition, np.asarray(target) - np.stack([gx, gy], axis=-1))


def _view_half_width_mm(condition: Condition) -> float:
    """Half-width of an episode picture, mm: the allowed box plus the carriage's arms (every electrode in view)."""
    return condition.allowed_half_width_mm + condition.geometry.spacing_mm / 2.0 + 4.0


@functools.lru_cache(maxsize=8)
def _scene_eev(scene: Any, half_span_mm: float):
    from electroloc_gym.world.scene import map_eev

    return map_eev(scene, step_mm=1.0, half_span_mm=half_span_mm)


# ---- snapshots of an env ------------------------------------------------------------------------------
@dataclass(frozen=True)
class Snapshot:
    """What a picture of an episode shows at one moment, copied from the env's public accessors.

    Attributes:
        condition: the episode's condition (geometry, noise, boxes).
        scene: the map of ElectroLocGlobal-v0, or None for ElectroLoc-v0.
        truth_mm: ground truth the belief estimates: the target centre (ElectroLoc-v0) or the true
            carriage position (ElectroLocGlobal-v0), mm.
        position_mm: true carriage position, mm.
        path_mm: carriage positions visited so far, (k, 2) mm.
        particles_mm: the belief's particles, (M, 2) mm.
        estimate_mm: the belief's mean, mm.
        spread_mm: √trace Σ of the belief, mm.
        n_observations: readings fused so far.
        reading_V: the last reading Φ, V.
    """

    condition: Condition
    scene: Any
    truth_mm: NDArray[np.float64]
    position_mm: NDArray[np.float64]
    path_mm: NDArray[np.float64]
    particles_mm: NDArray[np.float64]
    estimate_mm: NDArray[np.float64]
    spread_mm: float
    n_observations: int
    reading_V: float

    @property
    def is_global(self) -> bool:
        """True for a self-localisation (map) episode."""
        return self.scene is not None


def snapshot(env: Any) -> Snapshot:
    """Copy what a picture needs from ``env`` (a Gymnasium env of this package, wrapped or not)."""
    u = env.unwrapped
    b = u.belief
    scene = getattr(u, "scene", None)
    position = np.array(u.position_mm, dtype=float)
    truth = position if scene is not None else np.array(u.target_mm, dtype=float)
    return Snapshot(
        condition=u.condition,
        scene=scene,
        truth_mm=truth,
        position_mm=position,
        path_mm=np.array(u.path_mm, dtype=float).reshape(-1, 2),
        particles_mm=np.array(b.particles, dtype=float),
        estimate_mm=np.array(b.mean(), dtype=float),
        spread_mm=float(b.spread()),
        n_observations=int(u.n_observations),
        reading_V=float(u.last_reading_V),
    )


def _background(snap: Snapshot) -> tuple[NDArray, NDArray, str, float]:
    """(grid, Φ, colormap, limit) of the EEV drawn behind the snapshot."""
    if snap.is_global:
        grid, phi = _scene_eev(snap.scene, _view_half_width_mm(snap.condition))
        lim = float(min(snap.scene.saturation_V, max(1.0, np.ceil(np.abs(phi).max()))))
        return grid, phi, "gray_r", lim
    grid, phi = _target_eev(snap.condition, (float(snap.truth_mm[0]), float(snap.truth_mm[1])))
    return grid, phi, "RdBu_r", max(float(np.abs(phi).max()), 1e-12)


def eev_colorbar(fig: Any, snap: Snapshot, cax: Any = None, ax: Any = None, **kwargs: Any) -> Any:
    """A colorbar of the EEV shading :func:`draw_snapshot` uses for ``snap`` (into ``cax`` or beside ``ax``)."""
    from matplotlib.cm import ScalarMappable
    from matplotlib.colors import Normalize

    _, _, cmap, lim = _background(snap)
    what = "map EEV" if snap.is_global else "EEV of the true target"
    return fig.colorbar(
        ScalarMappable(Normalize(-lim, lim), cmap),
        cax=cax,
        ax=ax,
        label=f"{what}: expected reading Φ (V)\nwith the carriage at that point",
        **kwargs,
    )


def draw_snapshot(ax: Any, snap: Snapshot, *, title: bool = True, electrodes: bool = True) -> None:
    """Draw one moment of an episode into ``ax``: EEV, box, objects, particles, truth, estimate, path."""
    from matplotlib.patches import Circle

    grid, phi, cmap, lim = _background(snap)
    ax.imshow(
        phi.T,
        origin="lower",
        extent=(grid[0], grid[-1], grid[0], grid[-1]),
        cmap=cmap,
        vmin=-lim,
        vmax=lim,
        alpha=0.75 if not snap.is_global else 0.6,
        interpolation="nearest",
    )
    h = snap.condition.allowed_half_width_mm
    ax.plot([-h, h, h, -h, -h], [-h, -h, h, h, -h], color="0.35", lw=0.9)
    p = snap.particles_mm
    ax.scatter(p[:, 0], p[:, 1], s=2.0, c="tab:blue" if snap.is_global else "k", alpha=0.45, linewidths=0)
    if snap.is_global:
        water = snap.scene.water.conductivity_uScm
        for o in snap.scene.objects:
            color = _CONDUCTOR if o.contrast(water) > 0 else _INSULATOR
            ax.add_patch(Circle(o.xy_mm, o.radius_mm, fill=False, color=color, lw=1.0))
        ax.plot(0.0, 0.0, "o", mfc="none", mec="tab:red", ms=7, mew=1.4)
    else:
        ax.add_patch(
            Circle(tuple(snap.truth_mm), snap.condition.target.radius_mm, fill=False, color=_CONDUCTOR, lw=2.0)
        )
    path = snap.path_mm
    ax.plot(path[:, 0], path[:, 1], "*-", color="tab:purple", lw=1.0, ms=6, mec="tab:purple")
    if electrodes:
        el = electrode_positions_mm(snap.condition, snap.position_mm)
        for a, b in (("emitter+", "emitter-"), ("S1", "S2")):  # the carriage's two arms
            ax.plot([el[a][0], el[b][0]], [el[a][1], el[b][1]], color="0.25", lw=0.8)
        ax.plot(*el["emitter+"], **_EMITTER_POS)
        ax.plot(*el["emitter-"], **_EMITTER_NEG)
        for s in ("S1", "S2"):
            ax.plot(*el[s], **_SENSOR)
    ax.add_patch(Circle(tuple(snap.estimate_mm), snap.spread_mm, fill=False, color="tab:green", lw=1.4, ls="--"))
    ax.plot(*snap.estimate_mm, **_ESTIMATE)
    m = _view_half_width_mm(snap.condition)
    ax.set_xlim(-m, m)
    ax.set_ylim(-m, m)
    ax.set_aspect("equal")
    ax.tick_params(labelsize=7)
    if title:
        ax.set_title(
            f"observation {snap.n_observations}: Φ = {snap.reading_V:+.2f} V, spread {snap.spread_mm:.1f} mm",
            fontsize=8.5,
        )


def legend_handles(is_global: bool = False) -> list[Any]:
    """Legend entries for every marker :func:`draw_snapshot` draws."""
    from matplotlib.lines import Line2D

    def mk(label: str, **style: Any) -> Any:
        return Line2D([], [], label=label, **style)

    handles = [
        mk("sensors S1, S2", **_SENSOR),
        mk("emitter +", **_EMITTER_POS),
        mk("emitter −", **_EMITTER_NEG),
        mk("particles (belief)", marker="o", color="tab:blue" if is_global else "k", ms=3, ls="none", alpha=0.6),
        mk("true carriage path" if is_global else "carriage path", marker="*", color="tab:purple", ms=7, lw=1.0),
        mk("estimate (belief mean)", **_ESTIMATE),
        mk("spread √trace Σ (radius)", color="tab:green", lw=1.4, ls="--"),
        mk("allowed box", color="0.35", lw=0.9),
    ]
    if is_global:
        handles += [
            mk("conductor", color=_CONDUCTOR, lw=1.2),
            mk("insulator", color=_INSULATOR, lw=1.2),
            mk("map origin", marker="o", mfc="none", mec="tab:red", ms=7, ls="none"),
        ]
    else:
        handles.insert(
            4, mk("true target (sphere outline)", marker="o", mfc="none", mec=_CONDUCTOR, mew=2.0, ms=9, ls="none")
        )
    return handles


# ---- frames (env.render) ------------------------------------------------------------------------------
class FrameRenderer:
    """A frame that env renderers draw into: off-screen (``rgb_array``) or a window (``human``).

    The frame holds the episode axes, an EEV colorbar beside them and a marker legend below.
    """

    def __init__(self, render_mode: str) -> None:
        size = (6.4, 6.4)
        if render_mode == "rgb_array":
            from matplotlib.backends.backend_agg import FigureCanvasAgg
            from matplotlib.figure import Figure

            self.fig = Figure(figsize=size, dpi=100)
            FigureCanvasAgg(self.fig)
        else:
            import matplotlib.pyplot as plt

            self.fig = plt.figure(figsize=size, dpi=100)  # headless (Agg): draws, just no window
        self.render_mode = render_mode
        self.ax = self.fig.add_axes((0.08, 0.16, 0.72, 0.72))
        self.cax = self.fig.add_axes((0.83, 0.16, 0.03, 0.72))

    def finish(self) -> NDArray[np.uint8] | None:
        """Draw the canvas; the RGB array for ``rgb_array``, a short GUI pause for ``human``."""
        self.fig.canvas.draw()
        if self.render_mode == "rgb_array":
            canvas = cast("FigureCanvasAgg", self.fig.canvas)  # rgb_array figures are built on an Agg canvas
            buf = np.asarray(canvas.buffer_rgba())
            return np.ascontiguousarray(buf[..., :3])
        import matplotlib.pyplot as plt

        plt.pause(1.0 / 30)
        return None

    def draw(self, env: Any) -> NDArray[np.uint8] | None:
        """Draw the env's current state; returns an RGB array for ``rgb_array``."""
        snap = snapshot(env)
        self.ax.clear()
        self.cax.clear()
        draw_snapshot(self.ax, snap)
        eev_colorbar(self.fig, snap, cax=self.cax)
        self.cax.tick_params(labelsize=7)
        self.cax.yaxis.label.set_fontsize(7)
        name = snap.scene.name if snap.is_global else snap.condition.name
        self.ax.set_title(
            f"{name} — observation {snap.n_observations}\nΦ = {snap.reading_V:+.2f} V, spread {snap.spread_mm:.1f} mm",
            fontsize=9,
        )
        for leg in self.fig.legends:
            leg.remove()
        self.fig.legend(
            handles=legend_handles(snap.is_global),
            loc="lower center",
            ncol=3,
            fontsize=7,
            frameon=False,
            bbox_to_anchor=(0.5, 0.0),
        )
        return self.finish()

    def close(self) -> None:
        """Release the figure."""
        import matplotlib.pyplot as plt

        plt.close(self.fig)


class EpisodeRenderer(FrameRenderer):
    """Frames of ElectroLoc-v0 like the paper's Fig. 10 (EEV of the true target, particles, path)."""


class GlobalEpisodeRenderer(FrameRenderer):
    """Frames of ElectroLocGlobal-v0 like the paper's Fig. 13 (map EEV, objects, position belief)."""
