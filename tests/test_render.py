"""Episode pictures: frames, snapshot grids, GIFs and map EEVs read only the envs' public accessors."""

from __future__ import annotations

import gymnasium as gym
import matplotlib
import numpy as np
import pytest

import electroloc_gym  # noqa: F401  (registers the ids)
from electroloc_gym.cli import main
from electroloc_gym.demo import check_output_path, plot_episode, record_episode, save_gif
from electroloc_gym.views.render import (
    EpisodeRenderer,
    GlobalEpisodeRenderer,
    legend_handles,
    plot_map_eev,
    snapshot,
)

matplotlib.use("Agg")

SMALL = dict(n_particles=300, sensor_model="analytic")

#: The env accessors a picture may read (ground truth included: pictures may show it, agents may not).
PUBLIC = (
    "condition",
    "belief",
    "position_mm",
    "path_mm",
    "n_observations",
    "last_reading_V",
    "target_mm",
    "scene",
    "success_spread_mm",
    "render_mode",
)


class PublicOnly:
    """A view of an env exposing only :data:`PUBLIC`; any other attribute (e.g. ``_target``) raises."""

    def __init__(self, env):
        self._env = env.unwrapped

    @property
    def unwrapped(self):
        return self

    def __getattr__(self, name):
        if name not in PUBLIC:
            raise AttributeError(f"renderer read {name!r}, which is not a public accessor")
        return getattr(self._env, name)


@pytest.fixture
def target_env():
    env = gym.make("ElectroLoc-v0", render_mode="rgb_array", **SMALL)
    yield env
    env.close()


def test_snapshot_reads_public_accessors_only(target_env) -> None:
    target_env.reset(seed=1)
    target_env.step(np.array([0.5, -0.5], dtype=np.float32))
    snap = snapshot(PublicOnly(target_env))
    u = target_env.unwrapped
    np.testing.assert_array_equal(snap.truth_mm, u.target_mm)
    np.testing.assert_array_equal(snap.position_mm, u.position_mm)
    assert snap.path_mm.shape == (2, 2)
    assert snap.particles_mm.shape == (300, 2)
    assert snap.n_observations == 2 and not snap.is_global
    assert snap.spread_mm == pytest.approx(u.belief.spread())


def test_frame_drawn_from_public_view_equals_env_render(target_env) -> None:
    target_env.reset(seed=2)
    target_env.step(np.zeros(2, dtype=np.float32))
    frame = target_env.render()
    assert frame.dtype == np.uint8 and frame.ndim == 3 and frame.shape[2] == 3
    assert frame.std() > 10  # a picture, not a blank canvas
    r = EpisodeRenderer("rgb_array")
    try:
        np.testing.assert_array_equal(r.draw(PublicOnly(target_env)), frame)
    finally:
        r.close()


def test_record_episode_is_seeded_and_complete() -> None:
    def run():
        env = gym.make("ElectroLoc-v0", max_observations=5, **SMALL)
        return record_episode(env, seed=3)

    a, b = run(), run()
    n = a.final_info["n_observations"]
    assert len(a.snapshots) == len(a.infos) == n
    assert [s.n_observations for s in a.snapshots] == list(range(1, n + 1))
    assert a.final_info["success"] or n == 5
    assert [tuple(i["position_mm"]) for i in a.infos] == [tuple(i["position_mm"]) for i in b.infos]
    assert a.frames == []


def test_record_episode_with_an_agent() -> None:
    class StayAgent:
        name = "stay"

        def __init__(self):
            self.bound = None

        def reset(self, env):
            self.bound = env

        def predict(self, obs, state=None, episode_start=None, deterministic=True):
            return np.zeros(2, dtype=np.float32), state

    env = gym.make("ElectroLoc-v0", max_observations=3, **SMALL)
    agent = StayAgent()
    ep = record_episode(env, seed=0, agent=agent)
    assert agent.bound is not env and not hasattr(agent.bound, "unwrapped")  # bound to the env's agent view
    assert agent.bound.n_observations == env.unwrapped.n_observations
    assert len({tuple(i["position_mm"]) for i in ep.infos}) == 1  # it never moved
    assert ep.label == "stay, seed 0"


def test_frames_need_rgb_array() -> None:
    env = gym.make("ElectroLoc-v0", **SMALL)
    with pytest.raises(ValueError, match="render_mode='rgb_array'"):
        record_episode(env, frames=True)


def test_episode_grid_has_colorbar_and_a_legend_for_every_marker() -> None:
    ep = record_episode(gym.make("ElectroLoc-v0", max_observations=4, **SMALL), seed=4)
    fig = plot_episode(ep, max_panels=3)
    labels = [t.get_text() for leg in fig.legends for t in leg.get_texts()]
    for needle in ("sensors", "emitter +", "emitter −", "particles", "path", "true target", "estimate", "spread"):
        assert any(needle in lab for lab in labels), (needle, labels)
    assert any("expected reading" in ax.get_ylabel() for ax in fig.axes)  # the EEV colorbar
    n_panels = min(3, len(ep.snapshots)) + 1  # snapshots plus the spread/error panel
    assert len(fig.axes) == n_panels + 1


def test_gif_has_one_frame_per_observation(tmp_path) -> None:
    from PIL import Image

    env = gym.make("ElectroLoc-v0", max_observations=3, render_mode="rgb_array", **SMALL)
    ep = record_episode(env, seed=5, frames=True)
    env.close()
    path = tmp_path / "ep.gif"
    save_gif(ep.frames, path, fps=4)
    with Image.open(path) as im:
        assert im.format == "GIF"
        assert im.n_frames == len(ep.snapshots)
        assert im.size == (ep.frames[0].shape[1], ep.frames[0].shape[0])
        im.seek(im.n_frames - 1)
        last = np.asarray(im.convert("RGB")).astype(int)
    assert [p.name for p in tmp_path.iterdir()] == ["ep.gif"]  # no temp file left behind

    def green(a):  # the estimate and its spread circle (tab:green): small markers the palette must keep
        return int((np.abs(a.astype(int) - (44, 160, 44)).sum(-1) < 40).sum())

    assert green(ep.frames[-1]) > 50
    assert green(last) >= 0.8 * green(ep.frames[-1])


@pytest.mark.parametrize(
    "kwargs, match", [({"frames": []}, "at least one"), ({"fps": 0}, "fps"), ({"hold_last_s": -1}, "hold_last_s")]
)
def test_gif_bad_input(tmp_path, kwargs, match) -> None:
    args = {"frames": [np.zeros((4, 4, 3), np.uint8)], "path": tmp_path / "x.gif", **kwargs}
    with pytest.raises(ValueError, match=match):
        save_gif(**args)


def test_output_path_checks(tmp_path) -> None:
    (tmp_path / "file").write_text("x")
    with pytest.raises(ValueError, match="gif must be a file path"):
        check_output_path("gif", tmp_path)
    with pytest.raises(ValueError, match="is a file"):
        check_output_path("out", tmp_path / "file" / "x.png")
    with pytest.raises(ValueError, match="empty"):
        check_output_path("out", "")
    check_output_path("out", tmp_path / "new" / "x.png")  # a folder that does not exist yet is fine


def test_cli_demo_writes_png_and_gif(tmp_path, capsys) -> None:
    png, gif = tmp_path / "d.png", tmp_path / "d.gif"
    assert main(["demo", "--sensor-model", "analytic", "--seed", "1", "--out", str(png), "--gif", str(gif)]) == 0
    assert png.stat().st_size > 10_000 and gif.stat().st_size > 10_000
    assert "wrote" in capsys.readouterr().out


def test_cli_demo_bad_output_is_one_line(tmp_path, capsys) -> None:
    """One line naming the output as the front end spells it: ``--gif`` on the command line, ``gif`` from Python."""
    from electroloc_gym.demo import demo

    (tmp_path / "file").write_text("x")
    assert main(["demo", "--gif", str(tmp_path / "file" / "x.gif")]) == 2
    err = capsys.readouterr().err
    assert err.startswith("electroloc demo: error: --gif ") and err.count("\n") == 1 and "Traceback" not in err
    with pytest.raises(ValueError, match=r"^gif ") as info:
        demo(gif=tmp_path / "file" / "x.gif")
    assert str(info.value) == err.removeprefix("electroloc demo: error: --").strip()


def test_cli_demo_one_file_for_both_outputs_names_both_flags(tmp_path, capsys) -> None:
    """``--out`` and ``--gif`` naming one file: one line naming both flags (``out and gif`` from Python)."""
    from electroloc_gym.demo import demo, figure_suffixes

    if "gif" not in figure_suffixes():
        pytest.skip("this matplotlib writes no GIF figure: --out X.gif is refused by its suffix first")
    same = str(tmp_path / "x.gif")
    assert main(["demo", "--out", same, "--gif", same]) == 2
    assert capsys.readouterr().err.strip().splitlines() == [
        f"electroloc demo: error: --out and --gif name the same file {same!r}; one would overwrite the other"
    ]
    with pytest.raises(ValueError, match=r"^out and gif name the same file"):
        demo(out=same, gif=same)
    assert not any(tmp_path.iterdir())


def test_global_frames_and_snapshot() -> None:
    env = gym.make("ElectroLocGlobal-v0", render_mode="rgb_array", **SMALL)
    env.reset(seed=0)
    env.step(np.array([1.0, 0.0], dtype=np.float32))
    snap = snapshot(PublicOnly(env))
    assert snap.is_global
    np.testing.assert_array_equal(snap.truth_mm, env.unwrapped.position_mm)
    r = GlobalEpisodeRenderer("rgb_array")
    try:
        frame = r.draw(PublicOnly(env))
    finally:
        r.close()
    assert frame.ndim == 3 and frame.std() > 10
    labels = [h.get_label() for h in legend_handles(is_global=True)]
    assert "map origin" in labels and "conductor" in labels and "insulator" in labels


def test_map_eev_labels_every_object() -> None:
    import matplotlib.pyplot as plt

    from electroloc_gym.world.scene import BENCHMARK_SCENE

    ax = plot_map_eev(BENCHMARK_SCENE)
    n = len(BENCHMARK_SCENE.objects)
    assert [t.get_text() for t in ax.texts] == [str(i) for i in range(1, n + 1)]  # numbered on the map
    legend = [t.get_text() for t in ax.get_legend().get_texts()]
    for o, label in zip(BENCHMARK_SCENE.objects, legend):  # the legend explains every number, in order
        assert f"Ø{o.diameter_mm:g} mm" in label and o.shape in label
    assert "map origin (0, 0)" in legend and any("conductor" in t for t in legend)
    plt.close(ax.figure)
