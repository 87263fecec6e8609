"""One episode as pictures: a grid of belief snapshots (like the paper's Fig. 10 / 13) and an animated GIF.

:func:`record_episode` runs one seeded episode and keeps a :class:`~electroloc_gym.views.render.Snapshot`
after every observation (and the env's ``rgb_array`` frames if asked); :func:`plot_episode` lays the
snapshots out as a grid with one EEV colorbar, one legend for every marker, and a last panel of the
belief's spread and the estimate's error against the observations used; :func:`save_gif` writes the
frames as a GIF with Pillow (matplotlib's own image dependency). ``electroloc demo`` calls :func:`demo`.

Example::

    import gymnasium as gym
    import electroloc_gym
    from electroloc_gym.demo import plot_episode, record_episode

    env = gym.make("ElectroLocGlobal-v0", render_mode="rgb_array")
    episode = record_episode(env, seed=3)
    plot_episode(episode).savefig("global.png")
"""

from __future__ import annotations

import io
import os
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, cast

import numpy as np
from numpy.typing import NDArray

from electroloc_gym.baselines.rollout import run_episode
from electroloc_gym.engines.numba_core.task import LOCALIZATION_METRICS
from electroloc_gym.options import message_words
from electroloc_gym.protocol import SUCCESS_SPREAD_MM
from electroloc_gym.registry import PAPER_ENV_ID
from electroloc_gym.utils.fileio import atomic_write_bytes, check_output_path, save_figure_atomic
from electroloc_gym.views.render import Snapshot, draw_snapshot, eev_colorbar, legend_handles, snapshot

__all__ = ["Episode", "record_episode", "plot_episode", "save_gif", "demo", "check_output_path", "MAX_PANELS"]

#: Most belief snapshots in the grid (first and last always shown, the rest evenly spaced).
MAX_PANELS = 7


@dataclass
class Episode:
    """A recorded episode.

    Attributes:
        snapshots: one per observation fused (the first is taken by ``reset``).
        infos: the ``info`` dict after each observation (``reset``'s first).
        frames: the env's ``rgb_array`` frames, one per observation (empty unless recorded).
        label: what ran (agent and seed), for titles.
        success_spread_mm: the env's success threshold on the spread, mm.
        outcome: the final info → how the episode ended, in words (the env's task's ``metrics.outcome``).
    """

    snapshots: list[Snapshot] = field(default_factory=list)
    infos: list[dict[str, Any]] = field(default_factory=list)
    frames: list[NDArray[np.uint8]] = field(default_factory=list)
    label: str = ""
    success_spread_mm: float = SUCCESS_SPREAD_MM
    outcome: Callable[[dict[str, Any]], str] = LOCALIZATION_METRICS.outcome

    @property
    def final_info(self) -> dict[str, Any]:
        """The last info dict."""
        return self.infos[-1]


def _task_metrics(env: Any) -> Any:
    """The metrics of ``env``'s task (its env-table entry's; an env of no entry: the localisation metrics)."""
    entry: Any = getattr(env.unwrapped, "entry", None)
    try:
        return cast("Any", entry()).task_class.metrics if callable(entry) else LOCALIZATION_METRICS
    except (LookupError, ValueError):
        return LOCALIZATION_METRICS


def record_episode(
    env: Any, seed: int = 0, agent: Any = None, frames: bool = False, label: str | None = None
) -> Episode:
    """Run one episode of ``env`` from ``reset(seed=seed)`` and record it.

    The episode is the benchmark's (:func:`electroloc_gym.baselines.rollout.run_episode`): an agent that
    sets ``done`` ends it.

    Args:
        env: an env of this package (``gym.make(...)``); ``render_mode="rgb_array"`` if ``frames``.
        seed: reset seed; the default random agent's action space is seeded with it too.
        agent: anything with the project's agent call, ``predict(obs, deterministic=True) -> (action, state)``
            and optionally ``reset(env)`` (the paper's controllers from ``make_agent``, a loaded learned
            policy, an SB3 model); default: uniform random moves (``env.action_space.sample()``).
        frames: also keep ``env.render()`` after every observation (for :func:`save_gif`).
        label: a title for the figures (default: the agent and the seed).

    Raises:
        ValueError: ``frames`` without ``render_mode="rgb_array"``.
    """
    if frames and env.render_mode != "rgb_array":
        raise ValueError(f"frames=True needs an env made with render_mode='rgb_array', got {env.render_mode!r}")
    name = "random moves" if agent is None else getattr(agent, "name", type(agent).__name__)
    ep = Episode(
        label=label if label is not None else f"{name}, seed {seed}",
        success_spread_mm=float(env.unwrapped.success_spread_mm),
        outcome=_task_metrics(env).outcome,
    )
    if agent is None:
        agent = _RandomMoves(seed)  # the random walk is part of the seeded episode
    elif not hasattr(agent, "reset"):
        agent = _Unbound(agent)

    def record(info: dict[str, Any]) -> None:
        ep.snapshots.append(snapshot(env))
        ep.infos.append(dict(info))
        if frames:
            ep.frames.append(env.render())

    run_episode(env, agent, seed, on_step=record)
    return ep


class _RandomMoves:
    """Uniform random moves from the env's action space, seeded at the start of the episode."""

    def __init__(self, seed: int) -> None:
        self._seed = int(seed)
        self._space: Any = None

    def reset(self, env: Any) -> None:
        self._space = env.action_space
        self._space.seed(self._seed)

    def predict(
        self, obs: Any, state: Any = None, episode_start: Any = None, deterministic: bool = True
    ) -> tuple[Any, Any]:
        return self._space.sample(), state


class _Unbound:
    """An agent without ``reset(env)`` (e.g. a bare SB3 model), given a no-op one."""

    def __init__(self, agent: Any) -> None:
        self._agent = agent

    @property
    def done(self) -> bool:
        return bool(getattr(self._agent, "done", False))

    def reset(self, env: Any) -> None:
        pass

    def predict(
        self, obs: Any, state: Any = None, episode_start: Any = None, deterministic: bool = True
    ) -> tuple[Any, Any]:
        return self._agent.predict(obs, state=state, episode_start=episode_start, deterministic=deterministic)


def _panel_indices(n: int, k: int) -> list[int]:
    """Up to ``k`` indices in [0, n): the first, the last and evenly spaced ones between."""
    if n <= k:
        return list(range(n))
    return sorted({int(round(j * (n - 1) / (k - 1))) for j in range(k)})


def plot_episode(episode: Episode, max_panels: int = MAX_PANELS) -> Any:
    """The episode as a grid: belief snapshots, then spread and error against the observations used.

    Returns a matplotlib Figure (Agg canvas, no window).
    """
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    snaps = episode.snapshots
    idx = _panel_indices(len(snaps), max_panels)
    n_panels = len(idx) + 1
    ncols = 3 if n_panels in (5, 6) else min(4, n_panels)
    nrows = -(-n_panels // ncols)
    fig = Figure(figsize=(3.3 * ncols + 1.2, 3.35 * nrows + 1.4), dpi=110)
    FigureCanvasAgg(fig)
    grid = fig.add_gridspec(
        nrows,
        ncols,
        left=0.05,
        right=0.88,
        top=1 - 0.75 / fig.get_figheight(),
        bottom=1.05 / fig.get_figheight(),
        wspace=0.22,
        hspace=0.32,
    )
    axes = [fig.add_subplot(grid[i // ncols, i % ncols]) for i in range(n_panels)]
    for ax, i in zip(axes, idx):
        draw_snapshot(ax, snaps[i], title=False)
        ax.set_title(
            f"observation {snaps[i].n_observations}: Φ = {snaps[i].reading_V:+.2f} V\n"
            f"spread {snaps[i].spread_mm:.1f} mm",
            fontsize=8.5,
        )
    for ax in axes[: len(idx)]:
        ax.set_xlabel("x (mm)", fontsize=7, labelpad=1)
        ax.set_ylabel("y (mm)", fontsize=7, labelpad=0)
    _plot_progress(axes[-1], episode)
    cax = fig.add_axes((0.905, 1.05 / fig.get_figheight(), 0.012, 1 - 1.8 / fig.get_figheight()))
    eev_colorbar(fig, snaps[0], cax=cax)
    cax.tick_params(labelsize=7)
    cax.yaxis.label.set_fontsize(8)
    first = snaps[0]
    info = episode.final_info
    name = first.scene.name if first.is_global else first.condition.name
    outcome = episode.outcome(info)
    fig.suptitle(
        f"{name}, {episode.label}: {outcome} after {info['n_observations']} observations, "
        f"final error {info['error_mm']:.1f} mm",
        fontsize=11,
    )
    fig.legend(
        handles=legend_handles(first.is_global),
        loc="lower center",
        ncol=6 if ncols >= 4 else 4,
        fontsize=8,
        frameon=False,
        bbox_to_anchor=(0.47, 0.0),
    )
    return fig


def _plot_progress(ax: Any, episode: Episode) -> None:
    """Spread and error (mm) against observations, with the success threshold."""
    n = [i["n_observations"] for i in episode.infos]
    ax.plot(n, [i["spread_mm"] for i in episode.infos], "o-", color="tab:green", ms=3, label="spread √trace Σ")
    ax.plot(n, [i["error_mm"] for i in episode.infos], "s-", color="tab:orange", ms=3, label="error |estimate − truth|")
    thr = episode.success_spread_mm
    ax.axhline(thr, color="k", lw=0.8, ls=":", label=f"success: spread ≤ {thr:g} mm")
    ax.set_yscale("log")
    from matplotlib.ticker import FuncFormatter, LogLocator

    ax.yaxis.set_major_locator(LogLocator(subs=(1.0, 2.0, 3.0, 5.0)))
    ax.yaxis.set_major_formatter(FuncFormatter(lambda v, _pos: f"{v:g}"))
    ax.yaxis.set_minor_formatter(FuncFormatter(lambda _v, _pos: ""))
    from matplotlib.ticker import MaxNLocator

    ax.xaxis.set_major_locator(MaxNLocator(integer=True))
    ax.set_xlabel("observations used", fontsize=8)
    ax.set_ylabel("mm", fontsize=8)
    ax.tick_params(labelsize=7)
    ax.set_title("belief spread and estimate error", fontsize=8.5)
    ax.legend(fontsize=6.5, loc="lower left")
    ax.set_box_aspect(1.0)


def save_gif(
    frames: list[NDArray[np.uint8]], path: str | os.PathLike[str], fps: float = 3.0, hold_last_s: float = 2.0
) -> None:
    """Write RGB frames (H, W, 3 uint8) as a looping GIF, atomically (temp file, then rename).

    Args:
        frames: the frames, all of one size.
        path: output file.
        fps: frames per second (> 0).
        hold_last_s: how long the last frame stays before the loop restarts, s (≥ 0).
    """
    from PIL import Image

    if not frames:
        raise ValueError("frames must hold at least one frame")
    if not (np.isfinite(fps) and fps > 0):
        raise ValueError(f"fps must be a finite number > 0, got {fps!r}")
    if not (np.isfinite(hold_last_s) and hold_last_s >= 0):
        raise ValueError(f"hold_last_s must be a finite number ≥ 0, got {hold_last_s!r}")
    palette = _shared_palette(frames)
    images = [
        Image.fromarray(np.asarray(f, dtype=np.uint8)).quantize(palette=palette, dither=Image.Dither.NONE)
        for f in frames
    ]
    dt = int(round(1000.0 / fps))
    durations = [dt] * len(images)
    durations[-1] = dt + int(round(1000.0 * hold_last_s))
    buf = io.BytesIO()
    images[0].save(
        buf, format="GIF", save_all=True, append_images=images[1:], duration=durations, loop=0, optimize=True
    )
    atomic_write_bytes(path, buf.getvalue())


def figure_suffixes() -> tuple[str, ...]:
    """The file suffixes matplotlib can write a figure to (``png``, ``pdf``, ``svg`` …)."""
    from matplotlib.backend_bases import FigureCanvasBase

    return tuple(sorted(FigureCanvasBase.get_supported_filetypes()))


#: Marker colours every GIF palette keeps (matplotlib's tab colours, black, grey), RGB.
_MARKER_RGB = (
    (31, 119, 180),
    (255, 127, 14),
    (44, 160, 44),
    (214, 39, 40),
    (148, 103, 189),
    (23, 190, 207),
    (0, 0, 0),
    (89, 89, 89),
    (255, 255, 255),
)


def _shared_palette(frames: list[NDArray[np.uint8]]) -> Any:
    """One 255-colour palette for every frame (same colours throughout; smaller GIF deltas).

    Built from up to six evenly spaced frames plus swatches of the marker colours, so that small
    markers (the estimate, the path) keep their colour instead of being merged into the background.
    """
    from PIL import Image

    idx = sorted({int(round(j * (len(frames) - 1) / 5)) for j in range(6)})
    sample = [np.asarray(frames[i], dtype=np.uint8)[::2, ::2] for i in idx]
    width = sample[0].shape[1]
    rows = max(1, sum(a.shape[0] for a in sample) // 50)  # each swatch ≈ 2 % of the sample's pixels
    swatches = [np.broadcast_to(np.array(c, dtype=np.uint8), (rows, width, 3)) for c in _MARKER_RGB]
    return Image.fromarray(np.concatenate([*sample, *swatches], axis=0)).quantize(255, method=Image.Quantize.MEDIANCUT)


def demo(
    condition: str = "fresh-steel-12.7",
    sensor_model: str = "calibrated",
    seed: int = 0,
    out: str | os.PathLike[str] | None = "demo.png",
    gif: str | os.PathLike[str] | None = None,
    names: Mapping[str, str] | None = None,
) -> Episode:
    """``electroloc demo``: one random-move episode of ElectroLoc-v0 as a snapshot grid and/or a GIF.

    ``names``: how a refusal names ``out`` and ``gif`` (the command line's ``--out``, ``--gif``; None: as here).
    """
    import gymnasium as gym

    if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or not 0 <= seed < 2**63:
        raise ValueError(f"seed must be an integer in [0, 2**63), got {seed!r}")
    name = message_words({"out": "out", "gif": "gif"}, names)
    if out is not None:
        check_output_path(name["out"], out, figure_suffixes())
    if gif is not None:
        check_output_path(name["gif"], gif, ("gif",))
    if out is not None and gif is not None and Path(out).resolve() == Path(gif).resolve():
        raise ValueError(
            f"{name['out']} and {name['gif']} name the same file {str(out)!r}; one would overwrite the other"
        )
    env = gym.make(
        PAPER_ENV_ID,
        condition=condition,
        sensor_model=sensor_model,
        render_mode="rgb_array" if gif is not None else None,
    )
    try:
        episode = record_episode(env, seed=seed, frames=gif is not None)
    finally:
        env.close()
    if out is not None:
        save_figure_atomic(plot_episode(episode), out)
    if gif is not None:
        save_gif(episode.frames, gif)
    return episode
