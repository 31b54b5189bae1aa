"""Dataset rendering on a shared Dask cluster (:func:`lf_flame.learn.dataset.generate` with ``scheduler=``).

The serial-vs-``workers=2`` equality of every array lives in ``tests/test_dataset.py``."""
import dataclasses
from concurrent.futures import ThreadPoolExecutor

import h5py
import numpy as np

from lf_flame.learn import dataset as D
from lf_flame.optics.camera import PlenopticCamera
from lf_flame.config import DatasetConfig

CAM = PlenopticCamera(n_rows=20, n_cols=10)  # the tiny presets of tests/test_dataset.py
CFG = DatasetConfig(n_samples={"shapes": 6, "flame": 4}, rays_per_pixel=1, seed=3)
SLOPES = [CAM.slope_for_depth(d) for d in (20.0, 10.0, 0.0, -10.0)]

KEYS = ("raw", "gt", "params", "done", "split/train", "split/val", "split/test")


def test_concurrent_runs_with_other_settings_on_one_scheduler_keep_their_own_samples(tmp_path):
    """Two datasets that differ only in their seed, rendered at the same time through one
    scheduler (one worker thread, so their tasks queue side by side): each file equals its
    serial twin. Dask reuses a live task by its key, so keys must carry the settings."""
    from distributed import LocalCluster
    cfgs = {"s3": CFG, "s4": dataclasses.replace(CFG, seed=4)}
    serial = {k: D.generate(tmp_path / "serial" / k / "shapes.h5", CAM, c, "shapes", SLOPES, progress=False)
              for k, c in cfgs.items()}
    with LocalCluster(n_workers=1, threads_per_worker=1, processes=True, dashboard_address=":0") as cluster, \
            ThreadPoolExecutor(2) as pool:
        runs = {k: pool.submit(D.generate, tmp_path / "dask" / k / "shapes.h5", CAM, c, "shapes", SLOPES,
                               progress=False, scheduler=cluster.scheduler_address) for k, c in cfgs.items()}
        dask = {k: r.result() for k, r in runs.items()}
    for k in cfgs:
        with h5py.File(serial[k], "r") as f, h5py.File(dask[k], "r") as g:
            for key in KEYS:
                assert np.array_equal(f[key][:], g[key][:]), (k, key)
            assert f.attrs["digest"] == g.attrs["digest"]
