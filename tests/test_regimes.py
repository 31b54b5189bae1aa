"""Scene regimes: ``paper`` varies only what the paper states, ``varied`` is the
scenes as they were before regimes existed, bit for bit."""
import numpy as np
import pytest

from lf_flame.learn import dataset
from lf_flame.simulate import scenes
from lf_flame.config import DatasetConfig
from lf_flame.simulate.scenes import FLAME_HEIGHT_MEAN_MM, FLAME_HEIGHT_SD_MM, PAPER_RELATIVE_SD, REGIMES, flame_scene, shapes_scene


def _same_scene(a, b):
    assert len(a.layers) == len(b.layers)
    for la, lb in zip(a.layers, b.layers):
        np.testing.assert_array_equal(la.radiance, lb.radiance)
        if la.alpha is None:
            assert lb.alpha is None
        else:
            np.testing.assert_array_equal(la.alpha, lb.alpha)
        assert (la.depth_offset_mm, la.centre_mm, la.size_mm) == (lb.depth_offset_mm, lb.centre_mm, lb.size_mm)
    assert a.objects == b.objects
    assert a.effects == b.effects


def test_paper_relative_sd_is_the_flames_mean_coefficient_of_variation():
    cv = np.asarray(FLAME_HEIGHT_SD_MM) / np.asarray(FLAME_HEIGHT_MEAN_MM)
    assert PAPER_RELATIVE_SD == pytest.approx(cv.mean(), rel=1e-12)
    assert 0.06 < PAPER_RELATIVE_SD < 0.08
    assert REGIMES == ("paper", "varied")


def test_paper_flames_vary_only_in_height(small_camera):
    rng = np.random.default_rng(11)
    n = 200
    objs = [flame_scene(small_camera, rng, regime="paper").objects for _ in range(n)]
    for k in range(len(scenes.PAPER_DEPTHS_MM)):
        per = [o[k] for o in objs]
        for key in ("centre_x_mm", "base_y_mm", "radiance", "sway", "phase"):
            assert len({p[key] for p in per}) == 1, key
        assert per[0]["radiance"] == 1.0 and per[0]["sway"] == 0.0 and per[0]["phase"] == 0.0
        assert {p["regime"] for p in per} == {"paper"}
        h = np.array([p["height_template_mm"] for p in per])
        assert len(np.unique(h)) == n
        mu, sd = FLAME_HEIGHT_MEAN_MM[k], FLAME_HEIGHT_SD_MM[k]
        assert abs(h.mean() - mu) < 4 * sd / np.sqrt(n)           # standard error of the mean
        assert abs(h.std(ddof=1) / sd - 1) < 4 / np.sqrt(2 * (n - 1))  # standard error of the sd
    # the lateral position is the nominal scene's
    nominal = flame_scene(small_camera, np.random.default_rng(0), vary=False).objects
    assert [o["centre_x_mm"] for o in objs[0]] == [o["centre_x_mm"] for o in nominal]


def test_paper_shapes_are_the_template_with_the_flames_relative_spread(small_camera):
    rng = np.random.default_rng(12)
    n = 300
    objs = [shapes_scene(small_camera, rng, regime="paper", texels_per_lenslet=1.0).objects for _ in range(n)]
    nominal = shapes_scene(small_camera, np.random.default_rng(0), vary=False).objects
    tol = 4 / np.sqrt(2 * (n - 1))  # relative standard error of a sample sd, 4 sigma
    for k, nom in enumerate(nominal):
        per = [o[k] for o in objs]
        assert all(p["angle_deg"] == 0.0 and p["radiance"] == 1.0 and p["regime"] == "paper" for p in per)
        size = np.array([p["size_mm"] for p in per])
        assert abs(size.mean() / nom["size_mm"] - 1) < 4 * PAPER_RELATIVE_SD / np.sqrt(n)
        assert abs(size.std(ddof=1) / size.mean() / PAPER_RELATIVE_SD - 1) < tol
        for axis in ("centre_y_mm", "centre_x_mm"):
            off = np.array([p[axis] for p in per]) - nom[axis]
            assert abs(off.mean()) < 4 * PAPER_RELATIVE_SD * nom["size_mm"] / np.sqrt(n)
            assert abs(off.std(ddof=1) / (PAPER_RELATIVE_SD * nom["size_mm"]) - 1) < tol


@pytest.mark.parametrize("scene", ["shapes", "flame"])
def test_varied_is_the_default_and_paper_differs(small_camera, scene):
    f = scenes.SCENES[scene]
    for seed in (0, 3):
        default = f(small_camera, np.random.default_rng(seed))
        varied = f(small_camera, np.random.default_rng(seed), regime="varied")
        _same_scene(default, varied)
        assert {o["regime"] for o in varied.objects} == {"varied"}
        paper = f(small_camera, np.random.default_rng(seed), regime="paper")
        assert not all(np.array_equal(a.radiance, b.radiance) for a, b in zip(paper.layers, varied.layers))


# Seed 0 on the 41 x 41 camera, drawn by the code before regimes existed (commit 53c7775):
# each object's drawn parameters and each layer's radiance sum.
_OLD_SEED0 = {
    "shapes": (("size_mm", "angle_deg", "radiance"),
               [(1.3218075340274118, -19.338894578858838, 0.9066351196001362),
                (1.8571331031612455, 1.7449996586169156, 0.9675362118938842),
                (1.9052352771038608, 0.0, 0.5167927876527322),
                (1.8513163395010084, 1.6584488099636694, 0.6498559452686924)],
               [460.860991993919, 647.0594414970838, 772.1687755716266, 794.983593348763]),
    "flame": (("height_template_mm", "radiance", "sway", "phase"),
              [(29.666080727218223, 0.6163894095744779, 0.0009916581317117455, 5.109927617709579),
               (25.00684399500312, 0.8917986243935994, 0.03261749948792537, 5.8752333142921085),
               (18.57684769518397, 0.9429617106350278, 0.002015134518327861, 4.584560380312186),
               (13.437503029868134, 0.8165844880996367, 0.017982713432243086, 2.6558221377616955)],
              [1635.73977714777, 2127.852373697795, 1783.3477934524417, 1088.7904618780594]),
}


@pytest.mark.parametrize("scene", ["shapes", "flame"])
def test_varied_matches_the_scenes_before_regimes(small_camera, scene):
    keys, params, sums = _OLD_SEED0[scene]
    kw = dict(template_scale=scenes.TEMPLATE_SCALE) if scene == "flame" else {}   # the scale of that code's flames
    sc = scenes.SCENES[scene](small_camera, np.random.default_rng(0), regime="varied", **kw)
    assert [tuple(o[k] for k in keys) for o in sc.objects] == params
    got = [float(layer.radiance.astype(np.float64).sum()) for layer in sc.layers]
    np.testing.assert_allclose(got, sums, rtol=1e-9)


@pytest.mark.parametrize("scene", ["shapes", "flame"])
def test_nominal_wins_over_regime(small_camera, scene):
    f = scenes.SCENES[scene]
    rng = np.random.default_rng(4)
    state = rng.bit_generator.state
    a = f(small_camera, rng, vary=False, regime="paper")
    assert rng.bit_generator.state == state  # the nominal scene draws nothing
    b = f(small_camera, np.random.default_rng(5), vary=False)
    _same_scene(a, b)
    assert {o["regime"] for o in a.objects} == {"nominal"}


@pytest.mark.parametrize("scene", ["shapes", "flame"])
def test_bad_regime_raises(small_camera, scene):
    with pytest.raises(ValueError, match=r"Received: regime='paper2'"):
        scenes.SCENES[scene](small_camera, np.random.default_rng(0), regime="paper2")


def test_dataset_config_regime():
    assert DatasetConfig(n_samples={"shapes": 3}).regime == "varied"
    assert DatasetConfig(n_samples={"shapes": 3}, regime="paper").regime == "paper"
    with pytest.raises(ValueError, match=r"Received: regime='Paper'"):
        DatasetConfig(n_samples={"shapes": 3}, regime="Paper")


def test_make_sample_passes_the_regime(small_camera, monkeypatch):
    """make_sample draws its scene in the dataset's regime (stopped before rendering)."""
    seen = {}

    class Drawn(Exception):
        pass

    def fake_scene(camera, rng, **kwargs):
        seen.update(kwargs)
        raise Drawn

    monkeypatch.setitem(dataset.SCENES, "flame", fake_scene)
    cfg = DatasetConfig(n_samples={"flame": 3}, regime="paper")
    with pytest.raises(Drawn):
        dataset.make_sample(small_camera, cfg, "flame", 0, slopes=(0.0, 0.0, 0.0, 0.0))
    assert seen == {"regime": "paper"}
