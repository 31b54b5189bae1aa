"""The commands' figures (lf_flame.measure.figures and its users): planes in object-space mm,
titled with their depths (never "-0.0"), with colour bars that name their units."""
import numpy as np
import pytest

from lf_flame.cli import main
from lf_flame.measure.figures import plane_extent_mm, signed


def _texts(fig):
    """Every axes' title, x and y label, in order of the figure's axes."""
    return [(ax.get_title(), ax.get_xlabel(), ax.get_ylabel()) for ax in fig.axes]


def test_signed_never_writes_minus_zero():
    assert [signed(v) for v in (-0.0, -0.01, 0.04, 19.76, -9.98)] == ["+0.0", "+0.0", "+0.0", "+19.8", "-10.0"]
    assert signed(-0.0004, 3) == "+0.000" and signed(2.2814, 3) == "+2.281"


def test_a_plane_extent_is_the_lenslet_grids_field_at_its_depth(small_camera):
    for d in (-10.0, 0.0, 20.0):
        left, right, bottom, top = plane_extent_mm(small_camera, d)
        h, w = small_camera.field_of_view_mm(d)
        assert (top - bottom, right - left) == pytest.approx((h, w), rel=1e-9)


def test_refocus_writes_a_figure_in_mm_not_a_strip_of_lenslets(small_camera, tmp_path, capsys):
    """'refocus --out planes.png' draws a figure: one panel per plane in mm, titled with its
    slope and depth, one colour bar with units; the stack stays available as .npz."""
    from PIL import Image

    from lf_flame.cli.optics import refocus_figure
    from lf_flame.simulate import scenes
    from lf_flame.simulate import tracer as simulate
    cam = small_camera
    raw = simulate.render(cam, scenes.point_scene(cam, 10.0, size_mm=0.2), 2, 0)
    np.savez(tmp_path / "p.npz", raw=raw, camera=cam.to_json())
    depths = ["10", "-0.001", "-10"]
    args = ["refocus", str(tmp_path / "p.npz"), *[a for d in depths for a in ("--depth", d)]]
    assert main(args + ["--out", str(tmp_path / "planes.png")]) == 0
    with Image.open(tmp_path / "planes.png") as im:
        w, h = im.size
    assert w > 4 * 3 * cam.n_cols and h > 4 * cam.n_rows        # not 3 planes of 41 x 41 pixels side by side
    assert main(args + ["--out", str(tmp_path / "planes.npz")]) == 0
    with np.load(tmp_path / "planes.npz") as z:
        stack, slopes, stored = z["stack"], z["slopes"], z["depths_mm"]
    assert stack.shape == (3, cam.n_rows, cam.n_cols) and np.allclose(stored, [10.0, -0.001, -10.0])
    fig = refocus_figure(stack, slopes, cam, method="shift-sum")
    panels, bar = fig.axes[:3], fig.axes[3:]
    assert len(bar) == 1 and "a.u." in bar[0].get_ylabel()
    titles = [ax.get_title() for ax in panels]
    assert [t.split("\n")[1] for t in titles] == ["depth +10.0 mm", "depth +0.0 mm", "depth -10.0 mm"]
    assert all(t.startswith("slope ") and "-0.0" not in t for t in titles)
    assert all(ax.get_xlabel() == "x (mm)" for ax in panels) and panels[0].get_ylabel() == "y (mm)"
    # each panel spans its plane's field in mm
    assert panels[2].images[0].get_extent() == pytest.approx(plane_extent_mm(cam, -10.0))
    # views without a camera: slopes alone, axes in lenslets
    fig = refocus_figure(stack, slopes, None)
    assert "mm" not in fig.axes[0].get_title() and fig.axes[0].get_xlabel() == "column (lenslet)"


def test_temperature_figure_has_mm_a_kelvin_bar_a_masked_legend_and_the_truth(small_camera):
    from lf_flame.cli.temperature_planes import NO_TEMPERATURE, temperature_figure
    cam = small_camera
    truth = np.full((2, cam.n_rows, cam.n_cols), np.nan)
    truth[:, 10:30, 12:28] = np.linspace(1750.0, 1900.0, 16)
    est = truth + 5.0
    est[:, 10:14] = np.nan                                   # masked
    fig = temperature_figure(est, [10.0, -0.02], np.isfinite(est), cam, truth)
    assert len(fig.axes) == 2 * 2 + 1 and "(K)" in fig.axes[-1].get_ylabel()
    titles = [t for t, _, _ in _texts(fig)[:4]]
    assert titles[0].startswith("estimate +10.0 mm") and titles[1].startswith("estimate +0.0 mm")
    assert titles[2:] == ["truth +10.0 mm", "truth +0.0 mm"]
    assert all(x == "x (mm)" for _, x, _ in _texts(fig)[:4])
    assert [t.get_text() for t in fig.legends[0].get_texts()] == [NO_TEMPERATURE]
    # no truth: one row
    assert len(temperature_figure(est, [10.0, -0.02], np.isfinite(est), cam).axes) == 2 + 1


def test_reconstruction_figure_titles_the_truth_with_its_own_depth():
    """Planes found at -0.01 and +19.76 mm hold the flames at 0 and +20 mm: the truth's panels
    say +0.0 and +20.0, the reconstruction's +0.0 (not -0.0) and +19.8."""
    from lf_flame.tomo.files import reconstruction_figure
    from lf_flame.tomo.solvers import Reconstruction
    planes = np.random.default_rng(0).random((2, 12, 6))
    rec = Reconstruction(planes, (-0.01, 19.76), ((0.13, 0.13), (0.14, 0.14)), "admm", {"iters": 3},
                         np.array([0.1]), 0.5)
    fig = reconstruction_figure(rec, planes, planes, truth_depths_mm=[0.0, 20.0])
    titles = [t for t, _, _ in _texts(fig)[:6]]
    assert titles == ["reconstructed +0.0 mm", "refocused +0.0 mm", "truth +0.0 mm",
                      "reconstructed +19.8 mm", "refocused +19.8 mm", "truth +20.0 mm"]
    assert len(fig.axes) == 6 + 2                            # two colour bars: emission, refocused
    assert all(x == "x (mm)" for _, x, _ in _texts(fig)[:6])


def test_reconstruct_titles_its_truth_with_the_scenes_depths(tmp_path, monkeypatch):
    """'reconstruct' at planes beside the flames' depths (0.5 mm nearer the first, -0.02 for 0): the
    figure's truth panels carry the flames' own depths, its planes theirs, none '-0.0'."""
    from lf_flame.optics.camera import PlenopticCamera
    from lf_flame.simulate.scenes import PAPER_DEPTHS_MM
    from lf_flame.simulate.scenes_depth import carried_depths
    from lf_flame.tomo import files
    figures = []

    def spy(*args, **kwargs):
        figures.append(original(*args, **kwargs))
        return figures[-1]
    original = files.reconstruction_figure
    monkeypatch.setattr(files, "reconstruction_figure", spy)
    (tmp_path / "small.toml").write_text("[camera]\nn_rows = 41\nn_cols = 41\n")
    assert main(["simulate", "--scene", "flame", "--data-config", str(tmp_path / "small.toml"), "--rays-per-pixel",
                 "1", "--out", str(tmp_path / "flame.npz")]) == 0
    true = carried_depths(PlenopticCamera(n_rows=41, n_cols=41), PAPER_DEPTHS_MM)   # the flames' on this camera
    planes = [true[0] - 0.5, true[1], -0.02, true[3]]
    assert true[2] == 0.0 and main(["reconstruct", str(tmp_path / "flame.npz"), "--depths",
                                    ",".join(f"{d:.6f}" for d in planes), "--out", str(tmp_path / "r.h5")]) == 0
    titles = [t for t, _, _ in _texts(figures[0])[:12]]
    rec = files.load_reconstruction(tmp_path / "r.h5")       # the fills that ran, as the command prints them
    assert figures[0]._suptitle.get_text() == f"admm, {files.iterations_note(rec)}, {rec.time_s:.2f} s"
    assert "fills" in figures[0]._suptitle.get_text()
    assert titles[2::3] == [f"truth {d:+.1f} mm" for d in true]
    assert titles[0::3] == [f"reconstructed {d:+.1f} mm" for d in planes[:2]] + ["reconstructed +0.0 mm",
                                                                                  f"reconstructed {planes[3]:+.1f} mm"]


def test_a_truth_plane_is_titled_with_the_layers_it_is_nearest_to():
    """``truth_depths``: a plane holding a flame and a sliver of another flame's light (a layer shared linearly
    between it and a far plane) is titled with its own flame's depth; a plane given only slivers takes their
    light-weighted mean; layers between two planes of a dense stack count toward the nearer plane."""
    from lf_flame.simulate.scenes import FLAME_EFFECTS
    from lf_flame.simulate.layers import Layer, Scene
    from lf_flame.tomo.truth import truth_depths

    def layer(d, level=1.0):
        return Layer(radiance=np.full((4, 4), level, np.float32), alpha=None, depth_offset_mm=d, centre_mm=(0.0, 0.0),
                     size_mm=(1.0, 1.0))
    scene = Scene("t", (layer(-12.77), layer(0.0, 3.0)), FLAME_EFFECTS, ())
    np.testing.assert_allclose(truth_depths(scene, [-12.78, 0.13]), [-12.77, 0.0], atol=1e-9)
    np.testing.assert_allclose(truth_depths(Scene("t", (layer(0.3),), FLAME_EFFECTS, ()), [0.0, 1.0, 5.0]),
                               [0.3, 0.3, np.nan])
    dense = Scene("t", tuple(layer(d) for d in (0.1, 0.2, 0.6, 0.9)), FLAME_EFFECTS, ())
    got = truth_depths(dense, [0.0, 1.0])
    assert got[0] == pytest.approx((0.9 * 0.1 + 0.8 * 0.2) / 1.7) and got[1] == pytest.approx(
        (0.6 * 0.6 + 0.9 * 0.9) / 1.5)


def test_a_dense_stacks_sums_stand_below_the_top_of_their_plot():
    """The volume figure (more than six planes): each row's sum over each plane is drawn with headroom, so that the
    refocused planes' sums (each holds all the light: a flat line) do not lie on the plot's top edge."""
    from lf_flame.tomo.files import reconstruction_figure
    from lf_flame.tomo.solvers import Reconstruction
    planes = np.random.default_rng(1).random((9, 10, 8))
    refocused = np.broadcast_to(planes.mean(axis=0), planes.shape).copy()       # the same light on every plane
    rec = Reconstruction(planes, tuple(np.arange(9.0) - 4), ((0.13, 0.13),) * 9, "admm", {"iters": 3},
                         np.array([0.1]), 0.5)
    fig = reconstruction_figure(rec, refocused)
    sums = [ax for ax in fig.axes if ax.get_title().endswith("summed over each plane")]
    assert len(sums) == 2
    for ax in sums:
        top = max(float(np.max(line.get_ydata())) for line in ax.get_lines())
        assert ax.get_ylim()[0] == 0 and ax.get_ylim()[1] >= 1.05 * top, (ax.get_title(), ax.get_ylim(), top)
