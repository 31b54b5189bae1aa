"""Datasets of raw light fields with their four refocused ground-truth images, in HDF5.

File layout (one file per scene)::

    raw     (n, R*N, C*N) uint16   raw sensor image, value / 65535 = radiance in [0, 1]
    gt      (n, 4, R, C)  float32  shift-and-sum refocused images at the 4 slopes, [0, 1]
    params  (n,)          str      JSON of each sample's scene objects
    done    (n,)          uint8    1 once the sample is completely written
    split/train, split/val, split/test   int64 sample indices (seeded permutation)
    attrs: camera, dataset_config, scene, slopes, depths_mm, provenance (JSON strings),
           digest (hex: :func:`content_digest`, written when the file is finished)

A file is written as ``<name>.partial`` and renamed when every sample is done, so a
finished name is never half-written; re-running resumes the partial file, skipping
finished samples (a sample is marked done only after its data were flushed).

Sharding: ``generate(..., shard=(i, n))`` renders only samples ``k`` with ``k % n == i - 1``
into ``<stem>.shard-i-of-n.h5`` (same layout, its own samples marked done), on any
process or machine. An unsharded run first imports the finished samples of every
matching shard file beside it, then renders whatever is still missing.
"""
from __future__ import annotations

import hashlib
import json
import os
import time
from pathlib import Path

import h5py
import numpy as np
from tqdm import tqdm

from ..optics.camera import PlenopticCamera
from ..config import DatasetConfig, provenance, split_sizes, to_json
from ..refocus.shift_and_sum import aperture_mask, refocus
from ..simulate.scenes import PAPER_DEPTHS_MM, SCENES
from ..simulate.tracer import render

RAW_SCALE = 65535
SCENE_IDS = {"shapes": 1, "flame": 2}
#: Views used for ground truth: those inside the main lens's circular aperture (views
#: outside carry no light and would only dim every refocused image).
GT_MASK = "circular"


def sample_rng(cfg: DatasetConfig, scene: str, index: int, seed: int | None = None) -> np.random.Generator:
    """The generator that draws sample ``index`` of ``scene`` (independent of order and
    sharding) in the stream of ``seed`` (default: the dataset's ``cfg.seed``)."""
    return np.random.default_rng([cfg.seed if seed is None else int(seed), SCENE_IDS[scene], index])


def make_sample(camera: PlenopticCamera, cfg: DatasetConfig, scene: str, index: int, slopes,
                rays_per_pixel: int | None = None, seed: int | None = None):
    """Render one sample: raw image as stored (uint16 counts, (R·N, C·N)), ground truth
    ((4, R, C) float32, refocused from exactly the stored counts), and the scene objects.

    ``seed`` picks the stream that scenes and ray samples are drawn from (default the
    dataset's ``cfg.seed``); another seed gives samples the dataset never holds."""
    seed = cfg.seed if seed is None else int(seed)
    sc = SCENES[scene](camera, sample_rng(cfg, scene, index, seed), regime=cfg.regime)
    raw = render(camera, sc, rays_per_pixel or cfg.rays_per_pixel,
                 seed=(seed * 1_000_003 + SCENE_IDS[scene] * 100_003 + index) % 2**63)
    counts = np.round(raw * RAW_SCALE).astype(np.uint16)
    gt = refocus(counts / np.float32(RAW_SCALE), slopes, camera.pixels_per_lenslet,
                 aperture_mask(camera.pixels_per_lenslet, GT_MASK))
    return counts, np.clip(gt, 0.0, 1.0), sc.objects


def split_indices(n: int, fractions, seed: int) -> dict:
    """Seeded permutation of ``range(n)`` cut into train/val/test by ``fractions``."""
    perm = np.random.default_rng([seed, 0x5B117]).permutation(n)
    n_train, n_val, _ = split_sizes(n, fractions)
    return {"train": np.sort(perm[:n_train]), "val": np.sort(perm[n_train:n_train + n_val]),
            "test": np.sort(perm[n_train + n_val:])}


def _expected_attrs(camera, cfg, scene, slopes):
    return {"camera": camera.to_json(), "dataset_config": to_json(cfg), "scene": scene,
            "slopes": json.dumps([float(s) for s in slopes]), "depths_mm": json.dumps(list(PAPER_DEPTHS_MM))}


def _differences(attrs: dict, expected: dict) -> list[str]:
    """What differs between a dataset's attributes and the wanted ones, as 'key: there -> wanted' (a JSON
    attribute by its fields)."""
    out = []
    for k, v in expected.items():
        old = attrs.get(k)
        if old == v:
            continue
        try:
            a, b = json.loads(old), json.loads(v)
        except (TypeError, ValueError):
            a = b = None
        if isinstance(a, dict) and isinstance(b, dict):
            out += [f"{k}.{f}: {a.get(f)} -> {b.get(f)}" for f in sorted(set(a) | set(b)) if a.get(f) != b.get(f)]
        else:
            out.append(f"{k}: {old} -> {v}")
    return out


#: Attributes that, with the stored arrays, make a dataset's identity (:func:`content_digest`).
IDENTITY_ATTRS = ("camera", "dataset_config", "scene", "slopes", "depths_mm")


def content_digest(f: h5py.File) -> str:
    """SHA-256 of an open dataset's identity: its settings and every stored sample.

    Hashes the :data:`IDENTITY_ATTRS` (camera, dataset settings with regime, seed and rays
    per pixel, scene, slopes, depths), the split indices, each sample's scene objects and
    its ground truth. The ground truth is refocused from exactly the stored raw counts, so
    a change of the counts changes it too; hashing it (n × 4 × R × C float32) costs about a
    second per 400 MB, where the raw images would cost 28× more. Caches computed from a
    dataset (backbone features, the yardsticks, a training run) record this digest and are
    rebuilt when it changes.

    Returns
    -------
    str : 64 hex digits.
    """
    h = hashlib.sha256()
    for k in IDENTITY_ATTRS:
        h.update(f"{k}={f.attrs.get(k, '')}\n".encode())
    for k in ("train", "val", "test"):
        h.update(np.ascontiguousarray(f[f"split/{k}"][:], np.int64).tobytes())
    gt = f["gt"]
    for s in range(0, gt.shape[0], 64):
        h.update(np.ascontiguousarray(gt[s:s + 64]).tobytes())
        for p in f["params"][s:s + 64]:
            h.update(p if isinstance(p, bytes) else str(p).encode())
    return h.hexdigest()


def shard_path(path, shard: tuple[int, int]) -> Path:
    """File of shard ``(i, n)`` (1 <= i <= n) of the dataset at ``path``."""
    path = Path(path)
    return path.with_name(f"{path.stem}.shard-{shard[0]}-of-{shard[1]}{path.suffix}")


def _import_shards(f, path: Path, expected: dict) -> int:
    """Copy finished samples from the shard files beside ``path`` into the open file ``f``."""
    copied = 0
    for sp in sorted(path.parent.glob(f"{path.stem}.shard-*-of-*{path.suffix}")):
        try:
            with h5py.File(sp, "r") as g:
                if any(g.attrs.get(k) != v for k, v in expected.items()):
                    print(f"skipping shard {sp}: made with other settings")
                    continue
                new = np.flatnonzero((g["done"][:] == 1) & (f["done"][:] == 0))
                for i in new:
                    for key in ("raw", "gt", "params"):
                        f[key][i] = g[key][i]
                    f.flush()
                    f["done"][i] = 1
                copied += len(new)
        except (OSError, KeyError) as e:
            raise ValueError(f"shard file {sp} is truncated or corrupt ({e}); delete it or render it again") from None
    f.flush()
    return copied


def _sample_at(index: int, camera, cfg, scene, slopes):
    """:func:`make_sample` with the index first (a Dask task of :func:`generate`)."""
    return make_sample(camera, cfg, scene, index, slopes)


def _store(f, i: int, sample) -> None:
    """Write sample ``i`` into the open dataset, its done flag last (a crash leaves it to do)."""
    counts, gt, objects = sample
    f["raw"][i] = counts
    f["gt"][i] = gt
    f["params"][i] = json.dumps(objects, default=float)
    f.flush()
    f["done"][i] = 1
    f.flush()


def generate(path, camera: PlenopticCamera, cfg: DatasetConfig, scene: str, slopes, progress: bool = True,
             shard: tuple[int, int] | None = None, *, scheduler: str | None = None,
             workers: int | None = None) -> Path:
    """Generate (or resume) the dataset of ``scene`` at ``path``.

    Parameters
    ----------
    path : path-like
        Final file name; work goes to ``path + '.partial'`` until complete.
    camera, cfg : the camera and dataset settings (written as attributes).
    scene : {'shapes', 'flame'}
    slopes : sequence of 4 float
        Ground-truth slopes, one per depth of :data:`PAPER_DEPTHS_MM`.
    shard : (i, n) or None
        Render only shard ``i`` of ``n`` (1 <= i <= n) into :func:`shard_path`.
    scheduler, workers : str, int or None
        Render on Dask (:func:`lf_flame.parallel.dask_client`): the cluster at
        ``scheduler`` (address or scheduler file), or ``workers`` local worker processes.
        This process writes every sample; the file holds the same arrays as a serial run.
        Both None: render here, in order.

    Returns
    -------
    Path of the finished file (the shard's file when sharded).

    Raises
    ------
    ValueError
        Unknown scene, wrong number of slopes, a bad shard, or a partial or shard
        file made with other settings or corrupt.
    """
    if scene not in SCENES:
        raise ValueError(f"scene must be one of {sorted(SCENES)}. Received: {scene!r}")
    if len(slopes) != len(PAPER_DEPTHS_MM):
        raise ValueError(f"need {len(PAPER_DEPTHS_MM)} slopes. Received: {slopes}")
    if shard is not None and not (len(shard) == 2 and 1 <= int(shard[0]) <= int(shard[1])):
        raise ValueError(f"shard must be (i, n) with 1 <= i <= n. Received: shard={shard!r}")
    path = Path(path)
    expected = _expected_attrs(camera, cfg, scene, slopes)
    if path.exists():
        attrs = check_dataset(path)
        differ = _differences(attrs, expected)
        if not differ:
            os.utime(path)  # up to date: tell make so
            return path
        # other settings: build the new file beside it; the old one is replaced only when done
        print(f"{path} was made with other settings ({'; '.join(differ[:4])}): a new dataset is rendered beside "
              "it and replaces it when finished")
    final = path if shard is None else shard_path(path, shard)
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = final.with_name(final.name + ".partial")
    n = int(cfg.n_samples[scene])
    H, W = camera.sensor_shape
    t0 = time.perf_counter()
    try:
        f = h5py.File(tmp, "a")
    except OSError as e:
        if "lock" in str(e).lower():        # HDF5 locks a file open for writing: another run is rendering into it
            raise ValueError(f"partial dataset {tmp} is being written by another run (HDF5 could not lock it: {e}); "
                             "wait for that run, or stop it and run this again to resume its work") from None
        raise ValueError(f"partial dataset {tmp} is corrupt ({e}); delete it to start again") from None
    with f:
        if "done" in f:
            for k, v in expected.items():
                if f.attrs.get(k) != v:
                    raise ValueError(f"partial dataset {tmp} was made with a different {k}; delete it to start again")
        else:
            for k, v in expected.items():
                f.attrs[k] = v
            f.create_dataset("raw", (n, H, W), np.uint16, chunks=(1, H, W), compression="lzf")
            f.create_dataset("gt", (n, 4, camera.n_rows, camera.n_cols), np.float32,
                             chunks=(1, 4, camera.n_rows, camera.n_cols), compression="lzf")
            f.create_dataset("params", (n,), h5py.string_dtype())
            f.create_dataset("done", (n,), np.uint8, fillvalue=0)
            for k, idx in split_indices(n, cfg.split, cfg.seed).items():
                f.create_dataset(f"split/{k}", data=idx)
        if shard is None:
            copied = _import_shards(f, path, expected)
            if copied:
                print(f"{scene}: {copied} samples taken from shard files")
            todo = np.flatnonzero(f["done"][:] == 0)
            total = n
        else:
            mine = np.arange(n) % int(shard[1]) == int(shard[0]) - 1
            todo = np.flatnonzero((f["done"][:] == 0) & mine)
            total = int(mine.sum())
        label = f"{scene} dataset" + ("" if shard is None else f" shard {shard[0]}/{shard[1]}")
        before = float(f.attrs.get("wall_time_s", 0.0))      # earlier runs' time, killed ones included

        def store(i, sample):
            _store(f, i, sample)
            f.attrs["wall_time_s"] = before + time.perf_counter() - t0

        if scheduler is None and workers is None:
            for i in tqdm(todo, desc=label, disable=not progress, initial=total - len(todo), total=total):
                store(int(i), make_sample(camera, cfg, scene, int(i), slopes))
        else:   # rendered on Dask workers, written here as each arrives (any order; same bytes)
            from ..parallel import dask_client, map_unordered
            # task keys carry the settings: on a shared scheduler, a concurrent run with other
            # settings must not be handed this run's samples (Dask reuses a task by its key)
            tag = hashlib.sha256(json.dumps(expected, sort_keys=True).encode()).hexdigest()[:8]
            with dask_client(scheduler, workers or 1) as client:
                for i, sample in map_unordered(client, _sample_at, [int(i) for i in todo], camera, cfg, scene,
                                               list(slopes), name=f"{label.replace(' ', '-')}-{tag}",
                                               progress=progress, total=len(todo)):
                    store(i, sample)
        f.attrs["provenance"] = json.dumps(provenance())
        f.attrs["digest"] = content_digest(f)
        f.attrs["wall_time_s_last_run"] = time.perf_counter() - t0
        f.attrs["wall_time_s"] = before + time.perf_counter() - t0
    os.replace(tmp, final)
    return final


def check_dataset(path, camera: PlenopticCamera | None = None) -> dict:
    """Open a dataset and check it is complete and consistent; return its attributes.

    Raises
    ------
    ValueError
        Missing, truncated or corrupt file, missing arrays or attributes (:data:`IDENTITY_ATTRS`), unfinished
        samples, content that no longer has the digest the file records (:func:`content_digest`: edited or
        damaged since it was written), or a camera different from ``camera``.
    """
    path = Path(path)
    if not path.is_file():
        raise ValueError(f"dataset file not found: {path}")
    try:
        with h5py.File(path, "r") as f:
            missing = [k for k in ("raw", "gt", "done", "params", "split/train", "split/val", "split/test")
                       if k not in f]
            if missing:
                raise ValueError(f"dataset {path} lacks {missing}")
            if not np.all(f["done"][:] == 1):
                raise ValueError(f"dataset {path} has unfinished samples")
            attrs = {k: f.attrs[k] for k in f.attrs}
            lacking = [k for k in IDENTITY_ATTRS if k not in attrs]
            if lacking:
                raise ValueError(f"dataset {path} lacks its attributes {lacking}: written by something other than "
                                 "'lf-flame dataset', or edited since")
            n = f["raw"].shape[0]
            if f["gt"].shape[0] != n:
                raise ValueError(f"dataset {path}: {n} raw images but {f['gt'].shape[0]} ground truths")
            if "digest" in attrs and content_digest(f) != str(attrs["digest"]):   # about 1 s per 400 MB of truth
                raise ValueError(f"dataset {path} was changed since it was written: its content (settings, splits, "
                                 "scenes, ground truth) no longer has the digest the file records (an edited or "
                                 "damaged file): generate it again")
    except OSError as e:
        raise ValueError(f"dataset {path} is truncated or corrupt: {e}") from None
    if camera is not None and attrs.get("camera") != camera.to_json():
        raise ValueError(f"dataset {path} was rendered with another camera: {attrs.get('camera')} "
                         f"!= {camera.to_json()}")
    return attrs


class LightFieldDataset:
    """Read access to a finished dataset file (opened lazily, safe to pickle).

    Parameters
    ----------
    path : path-like

    Attributes
    ----------
    camera : PlenopticCamera
    slopes : list of float
    n : int
    """

    def __init__(self, path):
        self.path = Path(path)
        attrs = check_dataset(self.path)
        self.camera = PlenopticCamera.from_dict(json.loads(attrs["camera"]))
        self.slopes = json.loads(attrs["slopes"])
        self.scene = attrs["scene"]
        self.attrs = attrs
        with h5py.File(self.path, "r") as f:
            self.n = f["raw"].shape[0]
            self.splits = {k: f[f"split/{k}"][:] for k in ("train", "val", "test")}
        self._f = None

    def _file(self):
        if self._f is None:
            self._f = h5py.File(self.path, "r")
        return self._f

    def raw(self, index) -> np.ndarray:
        """Raw image(s) as float32 in [0, 1]: (R·N, C·N) or (k, R·N, C·N) for a sorted index list."""
        return self._file()["raw"][index].astype(np.float32) / RAW_SCALE

    def gt(self, index) -> np.ndarray:
        """Ground truth (4, R, C) or (k, 4, R, C), float32 in [0, 1]."""
        return self._file()["gt"][index]

    @property
    def digest(self) -> str:
        """The dataset's :func:`content_digest`: written at generation, computed here for a
        file made before digests were written (not stored: the file is opened read-only)."""
        d = self.attrs.get("digest")
        if d is None:
            with h5py.File(self.path, "r") as f:
                d = content_digest(f)
            self.attrs["digest"] = d
        return str(d)

    @property
    def config(self) -> DatasetConfig:
        """The dataset settings it was rendered with (regime included)."""
        d = json.loads(self.attrs["dataset_config"])
        return DatasetConfig(**{k: tuple(v) if isinstance(v, list) else v for k, v in d.items()})

    def heldout_sample(self, j: int, seed: int):
        """Sample ``j`` of a second held-out set: drawn and rendered as the dataset's own
        samples (same camera, regime, rays per pixel and slopes) but from the stream of
        ``seed`` instead of the dataset's, so neither training nor any choice made on the
        validation split has seen it.

        Parameters
        ----------
        j : int
            Index in the held-out stream (0, 1, ...).
        seed : int
            Seed of the held-out stream; must differ from the dataset's own seed.

        Returns
        -------
        (raw (R·N, C·N) float32 in [0, 1], gt (4, R, C) float32)

        Raises
        ------
        ValueError
            ``seed`` is the dataset's own seed (its samples would be the stored ones).
        """
        if int(seed) == self.config.seed:
            raise ValueError(f"the held-out seed must differ from the dataset's seed {self.config.seed}. "
                             f"Received: seed={seed}")
        counts, gt, _ = make_sample(self.camera, self.config, self.scene, int(j), self.slopes, seed=int(seed))
        return counts.astype(np.float32) / RAW_SCALE, gt

    def params(self, index) -> list:
        return json.loads(self._file()["params"][index])

    def close(self):
        if self._f is not None:
            self._f.close()
            self._f = None

    def __getstate__(self):
        d = dict(self.__dict__)
        d["_f"] = None
        return d


def calibrate_slopes(camera: PlenopticCamera, rays_per_pixel: int = 64, metric: str = "tenengrad"):
    """Search the sharpest slope of each shape in the nominal multi-shape scene (paper Sec. III-A).

    The slopes searched span -3 .. 3 lenslets per view, widened to a lenslet per view beyond the shapes' analytic
    slopes (a camera of few pixels per lenslet puts the +20 mm shape at 3.8).

    Returns
    -------
    (slopes, searches, objects) : list of 4 floats in the order of :data:`PAPER_DEPTHS_MM`, the
        :class:`~lf_flame.refocus.slope_search.SlopeSearch` of each object (metric curves), and the objects.

    Raises
    ------
    ValueError
        A shape whose sharpest slope lies at the search's end (no focus peak within it).
    """
    from ..refocus.shift_and_sum import raw_to_views
    from ..refocus.slope_search import find_sharpest_slope
    from ..simulate.scenes import shapes_scene
    sc = shapes_scene(camera, np.random.default_rng(0), vary=False)
    views = raw_to_views(render(camera, sc, rays_per_pixel, seed=0), camera.pixels_per_lenslet)
    mask = aperture_mask(camera.pixels_per_lenslet, GT_MASK)
    analytic = [camera.slope_for_depth(float(o["depth_offset_mm"])) for o in sc.objects]
    lo, hi = min(-3.0, min(analytic) - 1.0), max(3.0, max(analytic) + 1.0)
    searches = [find_sharpest_slope(views, o["roi"], metric=metric, mask=mask, lo=lo, hi=hi) for o in sc.objects]
    for o, s in zip(sc.objects, searches):
        if min(s.slope - lo, hi - s.slope) < 0.05:                  # a coarse step: the curve rises to the end
            raise ValueError(f"the {o.get('name', 'shape')}'s sharpest slope lies at the search's end ({s.slope:+.3f}"
                             f" of {lo:+.2f} .. {hi:+.2f} lenslets per view): no focus peak to calibrate")
    return [s.slope for s in searches], searches, sc.objects
