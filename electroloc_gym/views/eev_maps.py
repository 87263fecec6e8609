"""EEV maps: the expected reading over carriage positions, for one target (paper Fig. 2, 9) or a map (Fig. 14).

An EEV (expected electric voltage) map is the noise-free reading Φ (V) with the carriage at each point
of a 1 mm grid. :func:`eev_map` computes it for a condition's target at the origin, over carriage positions
relative to the target; :func:`plot_eev` draws it with the ±kσ detection contour (where the reading leaves
the noise) and the Φ = 0 line. :func:`plot_map_eev` draws a map's (:class:`electroloc_gym.world.scene.Scene`) in
the map frame, from the physics or from the agent's calibrated sensor model, with every object outlined
at its true size and numbered; the colours of conductors and insulators are the ones the episode frames
(:mod:`electroloc_gym.views.render`) use. Matplotlib is imported when a plot is drawn, not before.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import NDArray

from electroloc_gym.world.conditions import Condition
from electroloc_gym.world.sensor import expected_reading

__all__ = ["eev_map", "plot_eev", "plot_map_eev"]

_CONDUCTOR, _INSULATOR = "tab:orange", "tab:cyan"
_MATERIAL_LABELS = {"delrin": "Delrin", "pvc": "PVC"}


def eev_map(
    condition: Condition, half_span_mm: float | None = None, step_mm: float = 1.0
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
    ax.set_title(
        f"EEV {condition.name} (signal scale {condition.signal_scale:.2f})\n"
        f"black: |Φ| = {threshold_sigmas:g}σ detection contour; dotted: Φ = 0",
        fontsize=9,
    )
    ax.figure.colorbar(im, ax=ax, label="expected reading Φ (V)")
    return ax


def _map_eev_values(scene: Any, sensor_model: str, seed: int) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    from electroloc_gym.sensor_models.map import make_map_sensor_model
    from electroloc_gym.world.scene import map_eev

    grid, phi = map_eev(scene)
    if sensor_model == "calibrated":
        gx, gy = np.meshgrid(grid, grid, indexing="ij")
        phi = make_map_sensor_model("calibrated", scene, seed).mean_std(-np.stack([gx, gy], axis=-1))[0]
    elif sensor_model != "analytic":
        raise ValueError(f"sensor_model must be 'analytic' or 'calibrated', got {sensor_model!r}")
    return grid, np.asarray(phi, dtype=float)


def plot_map_eev(scene: Any, ax: Any = None, sensor_model: str = "analytic", seed: int = 0) -> Any:
    """Draw a map's EEV like the paper's Fig. 14; returns the axes.

    Grey scale from negative (white) to positive (black) expected reading at each carriage position,
    dotted contours every 1 V, every object outlined at its true size (orange: conductor, cyan:
    insulator) and numbered, and the map origin as a red
    circle (the point the robot localises itself against, as in Fig. 14); one legend below the axes
    explains every number and marker.

    Args:
        scene: the map (:class:`electroloc_gym.world.scene.Scene`).
        ax: matplotlib axes (a new figure if None).
        sensor_model: "analytic" (noise-free physics on a 1 mm grid) or "calibrated" (the agent's
            calibrated grid, interpolated on a 1 mm grid).
        seed: calibration seed.
    """
    import matplotlib.pyplot as plt
    from matplotlib.lines import Line2D
    from matplotlib.patches import Circle

    grid, phi = _map_eev_values(scene, sensor_model, seed)
    if ax is None:
        _, ax = plt.subplots(figsize=(6.4, 6.6))
    # Fig. 14's scale is ±10 V; ours is ±max|Φ| rounded up to a volt so that a map that does not
    # saturate stays visible.
    lim = float(min(scene.saturation_V, max(1.0, np.ceil(np.abs(phi).max()))))
    im = ax.imshow(
        phi.T,
        origin="lower",
        extent=(grid[0], grid[-1], grid[0], grid[-1]),
        cmap="gray_r",
        vmin=-lim,
        vmax=lim,
        interpolation="nearest",
    )
    ax.contour(
        grid, grid, phi.T, levels=np.arange(-lim + 1.0, lim, 1.0), colors="tab:blue", linewidths=0.4, linestyles=":"
    )
    water = scene.water.conductivity_uScm
    handles = []
    for i, o in enumerate(scene.objects, start=1):
        color = _CONDUCTOR if o.contrast(water) > 0 else _INSULATOR
        ax.add_patch(Circle(o.xy_mm, o.radius_mm, fill=False, color=color, lw=1.6))
        ax.text(
            *o.xy_mm,
            str(i),
            fontsize=9,
            fontweight="bold",
            ha="center",
            va="center",
            color=color,
            bbox=dict(boxstyle="circle,pad=0.15", fc="white", ec=color, lw=0.8, alpha=0.9),
        )
        material = _MATERIAL_LABELS.get(o.material, o.material)
        handles.append(
            Line2D(
                [],
                [],
                marker=f"${i}$",
                color=color,
                ms=7,
                ls="none",
                label=f"{material} {o.shape} Ø{o.diameter_mm:g} mm",
            )
        )
    ax.plot(0.0, 0.0, "o", mfc="none", mec="tab:red", ms=9, mew=1.8)
    ax.set_xlim(grid[0], grid[-1])
    ax.set_ylim(grid[0], grid[-1])
    ax.set_aspect("equal")
    ax.set_xlabel("carriage x (mm, map frame)")
    ax.set_ylabel("carriage y (mm, map frame)")
    ax.set_title(f"map EEV '{scene.name}' ({sensor_model} model)", fontsize=10)
    ax.figure.colorbar(im, ax=ax, label="expected reading Φ (V)", shrink=0.8)
    handles += [
        Line2D([], [], color=_CONDUCTOR, lw=1.6, label="conductor (true size)"),
        Line2D([], [], color=_INSULATOR, lw=1.6, label="insulator (true size)"),
        Line2D([], [], marker="o", mfc="none", mec="tab:red", mew=1.8, ls="none", label="map origin (0, 0)"),
        Line2D([], [], color="tab:blue", lw=0.6, ls=":", label="1 V contours"),
    ]
    ax.legend(
        handles=handles,
        loc="upper center",
        bbox_to_anchor=(0.5, -0.13),
        ncol=3,
        fontsize=7,
        frameon=False,
        handlelength=1.5,
        columnspacing=1.0,
    )
    return ax
