"""experiments/floor.py: the floor's timing, the routes' multiples of it, the stage clock."""
import importlib.util
import types
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from lf_flame.optics.camera import PlenopticCamera
from lf_flame.tomo.exact import ExactOperator

ROOT = Path(__file__).resolve().parents[1]


@pytest.fixture(scope="module")
def floor():
    spec = importlib.util.spec_from_file_location("floor_script", ROOT / "experiments" / "floor.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def test_the_floor_reads_and_transforms_every_lit_view(floor, monkeypatch):
    """One call per repeat, each reading the lit views into the canvas and one FFT of all of them each way."""
    import scipy.fft
    op = ExactOperator(PlenopticCamera(n_rows=12, n_cols=10), [-5.0, 5.0], precision="float32")
    views = np.ones(op.dimsd, np.float32)
    shapes = []
    rfft2 = scipy.fft.rfft2
    monkeypatch.setattr(scipy.fft, "rfft2", lambda z, **kw: (shapes.append(z.shape), rfft2(z, **kw))[1])
    t = floor.floor_s(op, views, 1, 3)
    assert len(t) == 3 and all(s > 0 for s in t)
    assert shapes == [(len(op._lit),) + op.canvas_shape] * 4                   # a warm-up and three timed


def test_each_route_is_a_multiple_of_its_threads_floor(floor):
    df = pd.DataFrame(dict(version="v", route=["admm"] * 3 + ["frame"] * 2, scene="s", noise="n",
                           threads=[2, 2, 2, 1, 1], time_s=[0.2, 0.3, 0.4, 0.05, 0.07]))
    tab = floor.summary(df, {("v", 2): 0.1, ("v", 1): 0.02}).set_index("route")
    assert tab.loc["admm", "median_s"] == pytest.approx(0.3) and tab.loc["admm", "x_floor"] == pytest.approx(3.0)
    assert tab.loc["frame", "x_floor"] == pytest.approx(3.0) and tab.loc["frame", "worst_s"] == pytest.approx(0.07)


def test_the_clock_times_wrapped_calls_by_category_and_gives_them_back(floor):
    owner = types.SimpleNamespace(f=lambda x: x + 1)
    original = owner.f
    clock = floor.Clock()
    saved = clock.wrap(owner, "f", lambda args: "small" if args[0] < 10 else "large")
    assert owner.f(1) == 2 and owner.f(20) == 21 and owner.f(3) == 4
    assert set(clock.s) == {"small", "large"} and all(v >= 0 for v in clock.s.values())
    setattr(*saved)
    assert owner.f is original


def test_a_route_the_compared_version_cannot_run_is_blank_beside_the_others(floor):
    """``--compare`` against an older checkout: its children time what its package can run; the ratio is per route,
    per pair of children, and a route it lacks is blank rather than an error."""
    rows = [dict(version=v, pair=p, route=r, scene="s", noise="n", threads=1, time_s=t)
            for v, p, r, t in [("before", 0, "admm", 0.4), ("after", 0, "admm", 0.2), ("before", 1, "admm", 0.6),
                               ("after", 1, "admm", 0.2), ("after", 0, "frame", 0.05), ("after", 1, "frame", 0.07)]]
    df = pd.DataFrame(rows)
    tab = floor.versus(floor.summary(df, {("before", 1): 0.1, ("after", 1): 0.1}), df).set_index("route")
    assert tab.loc["admm", "before_median_s"] == pytest.approx(0.5) and tab.loc["admm", "x_faster"] == pytest.approx(2.5)
    assert tab.loc["admm", "x_faster_pairs"] == "2.00-3.00"
    assert np.isnan(tab.loc["frame", "x_faster"]) and tab.loc["frame", "x_faster_pairs"] == "–"
