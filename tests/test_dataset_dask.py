"""Dataset rendering on a shared Dask cluster (:func:`lf_flame.learn.dataset.generate` with ``scheduler=``).

The serial-vs-``workers=2`` equality of every array lives in ``tests/test_dataset.py``."""
import dataclasses
import time
from concurrent.futures import ThreadPoolExecutor

import h5py
import numpy as np
from distributed.diagnostics.plugin import SchedulerPlugin

from lf_flame.learn import dataset as D
from lf_flame.optics.camera import PlenopticCamera
from lf_flame.config import DatasetConfig

CAM = PlenopticCamera(n_rows=20, n_cols=10)  # the tiny presets of tests/test_dataset.py
CFG = DatasetConfig(n_samples={"shapes": 6, "flame": 4}, rays_per_pixel=1, seed=3)
SLOPES = [CAM.slope_for_depth(d) for d in (20.0, 10.0, 0.0, -10.0)]

KEYS = ("raw", "gt", "params", "done", "split/train", "split/val", "split/test")
#: Task states in which the scheduler holds a task under its key (and would hand it to
#: another client submitting the same key).
LIVE = ("released", "waiting", "queued", "no-worker", "processing", "memory")


class _LiveClients(SchedulerPlugin):
    """Records, at every transition, which clients want the tasks the scheduler holds: the
    most clients with live tasks at one time, and the keys live while they were."""

    def __init__(self, scheduler, ignore=()):
        self.scheduler, self.ignore, self.most, self.keys_then = scheduler, set(ignore), 0, set()

    def transition(self, key, start, finish, *args, **kwargs):
        live = {ts.key: {c.client_key for c in ts.who_wants} - self.ignore
                for ts in self.scheduler.tasks.values() if ts.state in LIVE}
        clients = set().union(*live.values()) if live else set()
        if len(clients) > self.most:
            self.most, self.keys_then = len(clients), set(live)


def _wait_for(event_name):
    from distributed import Event
    Event(event_name).wait(120)


def test_concurrent_runs_with_other_settings_on_one_scheduler_keep_their_own_samples(tmp_path):
    """Two datasets that differ only in their seed, rendered at the same time through one
    scheduler (one worker thread, so their tasks queue side by side): each file equals its
    serial twin. Dask reuses a live task by its key, so keys must carry the settings.

    The worker's one thread is held by a task waiting on an event until both runs have
    tasks queued on the scheduler, so the runs overlap every time; a scheduler plugin
    checks that they did (two clients with live tasks at once)."""
    from distributed import Client, Event, LocalCluster
    cfgs = {"s3": CFG, "s4": dataclasses.replace(CFG, seed=4)}
    serial = {k: D.generate(tmp_path / "serial" / k / "shapes.h5", CAM, c, "shapes", SLOPES, progress=False)
              for k, c in cfgs.items()}
    with LocalCluster(n_workers=1, threads_per_worker=1, processes=True, dashboard_address=":0") as cluster, \
            Client(cluster) as holder, ThreadPoolExecutor(2) as pool:
        seen = _LiveClients(cluster.scheduler, ignore={holder.id})
        cluster.scheduler.add_plugin(seen)
        go = Event("both-runs-queued", client=holder)
        hold = holder.submit(_wait_for, "both-runs-queued", pure=False)
        runs = {k: pool.submit(D.generate, tmp_path / "dask" / k / "shapes.h5", CAM, c, "shapes", SLOPES,
                               progress=False, scheduler=cluster.scheduler_address) for k, c in cfgs.items()}
        t0 = time.monotonic()
        while seen.most < 2 and time.monotonic() - t0 < 60 and not any(r.done() for r in runs.values()):
            time.sleep(0.05)
        go.set()
        hold.result()
        dask = {k: r.result() for k, r in runs.items()}
    assert seen.most == 2, "the two runs never had tasks on the scheduler at the same time"
    for k in cfgs:
        with h5py.File(serial[k], "r") as f, h5py.File(dask[k], "r") as g:
            for key in KEYS:
                assert np.array_equal(f[key][:], g[key][:]), (k, key)
            assert f.attrs["digest"] == g.attrs["digest"]
    # and while they overlapped, each run's tasks were under keys of its own
    assert len({k.rsplit("-", 1)[0] for k in seen.keys_then if k.startswith("shapes-dataset")}) == 2, seen.keys_then
