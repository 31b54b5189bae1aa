import h5py
import numpy as np
import pytest

from lf_flame.learn import dataset as D
from lf_flame.optics.camera import PlenopticCamera
from lf_flame.config import DatasetConfig
from lf_flame.refocus.shift_and_sum import aperture_mask, refocus

CAM = PlenopticCamera(n_rows=20, n_cols=10)
CFG = DatasetConfig(n_samples={"shapes": 6, "flame": 4}, rays_per_pixel=1, seed=3)
SLOPES = [CAM.slope_for_depth(d) for d in (20.0, 10.0, 0.0, -10.0)]


def test_generate_writes_consistent_file(tmp_path):
    p = D.generate(tmp_path / "shapes.h5", CAM, CFG, "shapes", SLOPES, progress=False)
    ds = D.LightFieldDataset(p)
    assert ds.n == 6 and ds.camera == CAM and np.allclose(ds.slopes, SLOPES)
    raw, gt = ds.raw(2), ds.gt(2)
    assert raw.shape == CAM.sensor_shape and gt.shape == (4, 20, 10)
    assert 0 <= gt.min() and gt.max() <= 1 and raw.max() > 0
    # ground truth is the shift-and-sum of the stored raw image at the stored slopes
    assert np.allclose(gt, np.clip(refocus(raw, SLOPES, 15, aperture_mask(15, "circular")), 0, 1), atol=1e-6)
    idx = np.concatenate([ds.splits[k] for k in ("train", "val", "test")])
    assert sorted(idx) == list(range(6)) and all(len(v) for v in ds.splits.values())
    assert [o["name"] for o in ds.params(0)] == ["rectangle", "triangle", "circle", "square"]


def test_killed_run_resumes_to_identical_file(tmp_path, monkeypatch):
    full = D.generate(tmp_path / "a" / "flame.h5", CAM, CFG, "flame", SLOPES, progress=False)
    real = D.make_sample
    calls = {"n": 0}

    def dying(*a, **k):
        calls["n"] += 1
        if calls["n"] == 3:
            raise KeyboardInterrupt("killed")
        return real(*a, **k)

    monkeypatch.setattr(D, "make_sample", dying)
    target = tmp_path / "b" / "flame.h5"
    with pytest.raises(KeyboardInterrupt):
        D.generate(target, CAM, CFG, "flame", SLOPES, progress=False)
    assert not target.exists()  # never a half-written final file
    with h5py.File(str(target) + ".partial", "r") as f:
        assert f["done"][:].sum() == 2
    monkeypatch.setattr(D, "make_sample", real)
    D.generate(target, CAM, CFG, "flame", SLOPES, progress=False)
    with h5py.File(full, "r") as a, h5py.File(target, "r") as b:
        assert np.array_equal(a["raw"][:], b["raw"][:]) and np.array_equal(a["gt"][:], b["gt"][:])
        # the time of every run, the killed one's two samples too (the stage times of 'tables' read it)
        assert b.attrs["wall_time_s"] > b.attrs["wall_time_s_last_run"] > 0


def test_corrupt_and_mismatched_files(tmp_path):
    bad = tmp_path / "bad.h5"
    bad.write_bytes(b"not an hdf5 file at all")
    with pytest.raises(ValueError, match="corrupt"):
        D.LightFieldDataset(bad)
    p = D.generate(tmp_path / "shapes.h5", CAM, CFG, "shapes", SLOPES, progress=False)
    with pytest.raises(ValueError, match="another camera"):
        D.check_dataset(p, camera=PlenopticCamera(n_rows=20, n_cols=12))
    trunc = tmp_path / "trunc.h5"
    trunc.write_bytes(p.read_bytes()[:5000])
    with pytest.raises(ValueError, match="corrupt"):
        D.LightFieldDataset(trunc)
    import h5py
    import shutil
    noattr = tmp_path / "noattr.h5"          # its camera attribute deleted: named, not a KeyError in train
    shutil.copy(p, noattr)
    with h5py.File(noattr, "r+") as f:
        del f.attrs["camera"]
    with pytest.raises(ValueError, match=r"lacks its attributes \['camera'\]"):
        D.LightFieldDataset(noattr)


def test_partial_with_other_settings_refused(tmp_path, monkeypatch):
    target = tmp_path / "shapes.h5"
    monkeypatch.setattr(D, "make_sample", lambda *a, **k: (_ for _ in ()).throw(KeyboardInterrupt()))
    with pytest.raises(KeyboardInterrupt):
        D.generate(target, CAM, CFG, "shapes", SLOPES, progress=False)
    with pytest.raises(ValueError, match="different"):
        D.generate(target, CAM, CFG, "shapes", [0.0, 0.0, 0.0, 0.0], progress=False)


def test_existing_file_kept_until_new_settings_are_done(tmp_path, monkeypatch, capsys):
    """A finished dataset asked for with other settings is rebuilt beside it, saying what differs (it had been
    replaced with its path printed only), and kept until the new one is done."""
    p = D.generate(tmp_path / "flame.h5", CAM, CFG, "flame", SLOPES, progress=False)
    before = p.read_bytes()
    assert D.generate(p, CAM, CFG, "flame", SLOPES, progress=False) == p and p.read_bytes() == before
    assert capsys.readouterr().out == ""
    monkeypatch.setattr(D, "make_sample", lambda *a, **k: (_ for _ in ()).throw(KeyboardInterrupt()))
    with pytest.raises(KeyboardInterrupt):
        D.generate(p, CAM, CFG, "flame", [0.0, 0.0, 0.0, 0.0], progress=False)
    assert p.read_bytes() == before  # the finished file is untouched by the interrupted rebuild
    assert "made with other settings (slopes: [" in capsys.readouterr().out
    (tmp_path / "flame.h5.partial").unlink()
    with pytest.raises(KeyboardInterrupt):
        D.generate(p, CAM, DatasetConfig(n_samples={"shapes": 6, "flame": 4}, rays_per_pixel=1, seed=4), "flame",
                   SLOPES, progress=False)
    assert "dataset_config.seed: 3 -> 4" in capsys.readouterr().out


def test_shards_merge_into_the_unsharded_file(tmp_path, monkeypatch):
    full = D.generate(tmp_path / "a" / "shapes.h5", CAM, CFG, "shapes", SLOPES, progress=False)
    target = tmp_path / "b" / "shapes.h5"
    s1 = D.generate(target, CAM, CFG, "shapes", SLOPES, progress=False, shard=(1, 2))
    s2 = D.generate(target, CAM, CFG, "shapes", SLOPES, progress=False, shard=(2, 2))
    assert s1.name == "shapes.shard-1-of-2.h5" and not target.exists()
    with h5py.File(s1, "r") as f:
        assert list(f["done"][:]) == [1, 0, 1, 0, 1, 0]
    # the merge renders nothing: every sample comes from a shard
    monkeypatch.setattr(D, "make_sample", lambda *a, **k: pytest.fail("rendered a sample shards had"))
    D.generate(target, CAM, CFG, "shapes", SLOPES, progress=False)
    with h5py.File(full, "r") as a, h5py.File(target, "r") as b:
        for key in ("raw", "gt", "params", "split/train"):
            assert np.array_equal(a[key][:], b[key][:])
    assert s2.exists()  # shards are left for the user to delete


@pytest.mark.parametrize("bad", [(0, 2), (3, 2), (1,)])
def test_bad_shard_rejected(tmp_path, bad):
    with pytest.raises(ValueError, match="shard"):
        D.generate(tmp_path / "x.h5", CAM, CFG, "shapes", SLOPES, progress=False, shard=bad)


def test_rendering_on_dask_writes_the_serial_files_arrays(tmp_path):
    """Two local Dask workers render, this process writes in arrival order: every array and the
    content digest equal the serial run's."""
    a = D.generate(tmp_path / "a" / "shapes.h5", CAM, CFG, "shapes", SLOPES, progress=False)
    b = D.generate(tmp_path / "b" / "shapes.h5", CAM, CFG, "shapes", SLOPES, progress=False, workers=2)
    with h5py.File(a, "r") as f, h5py.File(b, "r") as g:
        for k in ("raw", "gt", "params", "done", "split/train", "split/val", "split/test"):
            assert np.array_equal(f[k][:], g[k][:]), k
        assert f.attrs["digest"] == g.attrs["digest"]


def test_a_partial_dataset_another_run_is_writing_is_not_called_corrupt(tmp_path, capsys):
    """A second ``dataset`` run on the ``--out`` a first one is still rendering into: HDF5 cannot lock the partial
    file, and the message said it was corrupt and to delete it (the first run's work); it names the other run."""
    import json
    import subprocess
    import sys
    from pathlib import Path

    from lf_flame.cli import main
    from lf_flame.config import load_data_config
    cfg = str(Path(__file__).resolve().parents[1] / "data_gen" / "quick.toml")
    cam, _ = load_data_config(cfg)
    slopes = tmp_path / "slopes.json"
    slopes.write_text(json.dumps(dict(slopes=[2.275, 1.17, 0.0, -1.245], camera=json.loads(cam.to_json()))))
    out = tmp_path / "d.h5"
    partial = tmp_path / "d.h5.partial"
    h5py.File(partial, "w").close()
    holder = subprocess.Popen([sys.executable, "-c", f"import h5py, time; f = h5py.File({str(partial)!r}, 'a'); "
                               "print('open', flush=True); time.sleep(60)"], stdout=subprocess.PIPE, text=True)
    try:
        assert holder.stdout.readline().strip() == "open"
        assert main(["dataset", "--data-config", cfg, "--scene", "flame", "--slopes", str(slopes), "--out", str(out),
                     "--quiet"]) == 2
    finally:
        holder.kill()
        holder.wait()
    err = capsys.readouterr().err
    assert "being written by another run" in err and "delete it" not in err and partial.exists()
