"""``lf-flame``: the command line that the Make targets call. ``lf-flame --help``."""
from __future__ import annotations

import argparse
import dataclasses
import json
import sys
import time
from pathlib import Path

import numpy as np


def _load_raw(path):
    """A raw image from .npz (key 'raw'), .npy, or a dataset sample 'file.h5:INDEX'."""
    s = str(path)
    if ".h5:" in s:
        from .dataset import LightFieldDataset
        f, i = s.rsplit(":", 1)
        ds = LightFieldDataset(f)
        return ds.raw(int(i)), ds.camera
    p = Path(s)
    if not p.is_file():
        raise SystemExit(f"error: raw image file not found: {p}")
    if p.suffix == ".npz":
        with np.load(p) as z:
            from .camera import PlenopticCamera
            cam = PlenopticCamera.from_dict(json.loads(str(z["camera"]))) if "camera" in z else None
            return z["raw"], cam
    return np.load(p), None


def _load_views(path):
    """Sub-aperture views (N, N, R, C) and the camera (or None) of RAW: a file of views
    decoded by ``lf-flame decode`` (.h5 without ':INDEX'), else a raw image of the
    simulated camera split by :func:`lf_flame.refocus.raw_to_views`."""
    s = str(path)
    if s.endswith(".h5") and ".h5:" not in s:
        from .decode import load_views
        return load_views(s)[0], None
    from .camera import PAPER_CAMERA
    from .refocus import raw_to_views
    raw, cam = _load_raw(path)
    cam = cam or PAPER_CAMERA
    return raw_to_views(raw, cam.pixels_per_lenslet), cam


def _save_image(path, img):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    plt.imsave(path, np.clip(img, 0, 1), cmap="gray", vmin=0, vmax=1)


def _write_stack(path, stack, **extra):
    """Write a focal stack (S, R, C): planes side by side as .png, else .npz with ``extra``."""
    out = Path(path)
    out.parent.mkdir(parents=True, exist_ok=True)
    if out.suffix == ".png":
        _save_image(out, np.concatenate(list(stack), axis=1))
    else:
        np.savez_compressed(out, stack=stack, **extra)
    print(f"-> {out}")


def cmd_simulate(a):
    from . import scenes, simulate
    from .camera import PAPER_CAMERA
    from .config import load_data_config
    cam = load_data_config(a.data_config)[0] if a.data_config else PAPER_CAMERA
    if a.scene == "point":
        sc = scenes.point_scene(cam, a.depth, a.y, a.x)
    else:
        sc = scenes.SCENES[a.scene](cam, np.random.default_rng(a.seed), vary=not a.nominal)
    if a.crosstalk or a.bit_depth:
        import dataclasses
        sc = dataclasses.replace(sc, effects=dataclasses.replace(sc.effects, crosstalk=a.crosstalk or
                                                                 sc.effects.crosstalk, bit_depth=a.bit_depth))
    t = time.perf_counter()
    raw = simulate.render(cam, sc, a.rays_per_pixel, a.seed)
    dt = time.perf_counter() - t
    out = Path(a.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    if out.suffix == ".png":
        _save_image(out, raw)
    else:
        extra = {}
        if a.views:
            from .refocus import raw_to_views
            extra["views"] = raw_to_views(raw, cam.pixels_per_lenslet)
        np.savez_compressed(out, raw=raw, camera=cam.to_json(), objects=json.dumps(sc.objects, default=float),
                            **extra)
    print(f"rendered {sc.name} {raw.shape} at {a.rays_per_pixel} rays/pixel in {dt:.2f} s -> {out}")


def cmd_refocus(a):
    from .refocus import aperture_mask, refocus_views
    views, _ = _load_views(a.raw)
    n = views.shape[0]
    t = time.perf_counter()
    stack = refocus_views(views, a.slope, aperture_mask(n, a.aperture), method=a.method,
                          interpolation=a.interpolation)
    print(f"refocused {len(a.slope)} planes ({a.method}) in {1e3 * (time.perf_counter() - t):.2f} ms")
    _write_stack(a.out, stack, slopes=np.asarray(a.slope))


def cmd_slopes(a):
    if a.raw is None:
        return _calibrate_slopes(a)
    import pandas as pd
    from .evaluate import plot_slope_curves
    from .refocus import aperture_mask, find_sharpest_slope
    views, cam = _load_views(a.raw)
    if a.roi:
        objects = [dict(name=f"roi{i}", roi=tuple(r)) for i, r in enumerate(a.roi)]
    else:
        objects = _raw_objects(a.raw) or [dict(name="image", roi=(0, views.shape[2], 0, views.shape[3]))]
    mask = aperture_mask(views.shape[0], a.aperture)
    t = time.perf_counter()
    searches = [find_sharpest_slope(views, o["roi"], metric=a.metric, method=a.method, lo=a.lo, hi=a.hi, mask=mask)
                for o in objects]
    rows = []
    for o, s in zip(objects, searches):
        row = dict(object=o["name"], roi=" ".join(str(int(x)) for x in o["roi"]), slope=round(s.slope, 4))
        if cam is not None:  # decoded views of a real camera: no optics, no depth
            try:
                row["depth_mm"] = round(cam.depth_for_slope(s.slope), 2)
            except ValueError:
                row["depth_mm"] = float("nan")
        if "depth_offset_mm" in o:
            row["true_depth_mm"] = o["depth_offset_mm"]
            row["analytic_slope"] = round(cam.slope_for_depth(o["depth_offset_mm"]), 4)
        rows.append(row)
    df = pd.DataFrame(rows)
    print(df.to_string(index=False))
    print(f"searched {len(objects)} regions ({a.method}, {a.metric}) in {time.perf_counter() - t:.2f} s")
    out = Path(a.out_prefix or Path(a.raw.split(".h5:")[0]).with_suffix(""))
    out.parent.mkdir(parents=True, exist_ok=True)
    df.to_csv(f"{out}.slopes.csv", index=False)
    plot_slope_curves([o["name"] for o in objects], searches, f"{out}.slopes.png", a.metric)
    print(f"-> {out}.slopes.csv, {out}.slopes.png")


def cmd_calibrate(a):
    from .calibrate import calibrate, file_digest, load_image
    white = load_image(a.white)
    dark = load_image(a.dark) if a.dark else None
    t = time.perf_counter()
    cal = calibrate(white, dark, layout=a.layout, camera_id=a.camera_id or "")
    dt = time.perf_counter() - t
    cal = dataclasses.replace(cal, white=file_digest(a.white), dark=file_digest(a.dark) if a.dark else None)
    cal.save(a.out)
    print(f"{cal.layout} grid: pitch {cal.pitch_px:.4f} px, rotation {cal.rotation_deg:+.4f}°, offset "
          f"({cal.offset_px[0]:+.2f}, {cal.offset_px[1]:+.2f}) px, {cal.n_rows} x {cal.n_cols} lenslets decoded; "
          f"fit residual {cal.residual_rms_px:.3f} px rms, {cal.residual_max_px:.3f} px max over "
          f"{len(cal.lenslets)} of {cal.n_found} lenslet images; {dt:.2f} s -> {a.out}")


def _calibration_file(info, kind, override):
    """The white or dark image a calibration names, checked against its SHA-256."""
    from .calibrate import file_digest, load_image
    if override:
        return load_image(override)
    if not info:
        return None
    p = Path(info["path"])
    if not p.is_file():
        raise FileNotFoundError(f"the calibration's {kind} image {p} is gone; give it with --{kind}")
    if file_digest(p)["sha256"] != info["sha256"]:
        raise ValueError(f"the calibration's {kind} image {p} has changed since the calibration")
    return load_image(p)


def cmd_decode(a):
    from .calibrate import GridCalibration, load_image
    from .decode import decode, save_views
    cal = GridCalibration.load(a.calibration)
    raw = load_image(a.raw)
    white = None if a.no_white else _calibration_file(cal.white, "white", a.white)
    dark = _calibration_file(cal.dark, "dark", a.dark)
    t = time.perf_counter()
    views = decode(raw, cal, white, dark, n_views=a.views, camera_id=a.camera_id)
    dt = time.perf_counter() - t
    save_views(a.out, views, cal, raw=str(Path(a.raw).resolve()), white_normalised=white is not None)
    print(f"decoded {Path(a.raw).name} into {views.shape[0]} x {views.shape[1]} views of {views.shape[2]} x "
          f"{views.shape[3]} lenslets in {dt:.2f} s -> {a.out}")


def _raw_objects(path):
    """The objects (with ``roi``) that ``lf-flame simulate`` stored beside the raw image, if any."""
    if not str(path).endswith(".npz"):
        return None
    with np.load(path) as z:
        return json.loads(str(z["objects"])) if "objects" in z else None


def _calibrate_slopes(a):
    from .config import atomic_write_text, load_data_config
    from .dataset import calibrate_slopes
    from .evaluate import write_slopes
    if not (a.data_config and a.out and a.results):
        raise SystemExit("error: give RAW, or --data-config, --out and --results to calibrate the nominal scene")
    cam, cfg = load_data_config(a.data_config)
    t = time.perf_counter()
    slopes, searches, objects = calibrate_slopes(cam, cfg.calibration_rays_per_pixel)
    df = write_slopes(cam, slopes, searches, objects, a.results)
    print(df.to_string(index=False))
    atomic_write_text(a.out, json.dumps({"slopes": slopes, "wall_time_s": time.perf_counter() - t}))


def cmd_dataset(a):
    from .config import load_data_config
    from .dataset import generate
    cam, cfg = load_data_config(a.data_config)
    if a.regime:
        cfg = dataclasses.replace(cfg, regime=a.regime)
    slopes = json.loads(Path(a.slopes).read_text())["slopes"]
    shard = None
    if a.shard:
        try:
            shard = tuple(int(v) for v in a.shard.split("/"))
        except ValueError:
            raise SystemExit(f"--shard must look like i/N (e.g. 2/4). Received: {a.shard!r}") from None
    p = generate(a.out, cam, cfg, a.scene, slopes, progress=not a.quiet, shard=shard)
    print(f"dataset -> {p}")


def cmd_train(a):
    from .config import load_experiment_config
    from .train import train
    mcfg, tcfg = load_experiment_config(a.experiment_config)
    if a.input_size:
        try:
            rows, cols = (int(v) for v in a.input_size.lower().split("x"))
        except ValueError:
            raise SystemExit(f"--input-size must look like ROWSxCOLS (e.g. 224x112). Received: {a.input_size!r}")
        mcfg = dataclasses.replace(mcfg, input_rows=rows, input_cols=cols)
    if a.time_budget_s is not None:
        tcfg = dataclasses.replace(tcfg, time_budget_s={k: a.time_budget_s for k in tcfg.time_budget_s})
    info = train(a.dataset, a.out, mcfg, tcfg, progress=not a.quiet)
    print(f"trained {info['epochs_run']} epochs in {info['training_wall_time_s']:.0f} s "
          f"(best val_loss {info['best_val_loss']:.5f}, backbone {info['backbone_weights']}) -> {a.out}")


#: ``--route`` names of the learned routes -> the names they carry in a model folder.
LEARNED_ROUTES = {"network": "network", "mean-image": "mean image", "linear-gap": "linear decoder (GAP-pooled)",
                  "linear-unpooled": "linear decoder (un-pooled)"}


def _learned_runner(raw, cam, raw_name, model_dir, route):
    """The function ``x (1, rows, cols, 1) -> stack (4, R, C)`` of a learned route, with the
    model's info; checks that the raw image fits the model."""
    from .camera import PlenopticCamera
    from .train import load_full_model
    model, info = load_full_model(model_dir)
    if tuple(raw.shape) != tuple(info["raw_shape"]):
        raise ValueError(f"raw image {raw.shape} does not match the model's sensor {tuple(info['raw_shape'])}")
    if cam is not None and cam != PlenopticCamera.from_dict(json.loads(info["dataset_camera"])):
        raise ValueError(f"{raw_name} was rendered with another camera than the model was trained on")
    if not np.all(np.isfinite(raw)):
        raise ValueError(f"{raw_name} contains NaN or inf")
    if route == "network":
        def run(x):
            return np.transpose(np.asarray(model.predict_on_batch(x))[0], (2, 0, 1))
    else:
        from .train import load_baselines
        base = load_baselines(model_dir)[LEARNED_ROUTES[route]]
        fx = model.get_layer("feature_extractor")

        def run(x):
            return base.predict(np.asarray(fx.predict_on_batch(x)))[0]
    return run, info


def cmd_predict(a):
    raw, cam = _load_raw(a.raw)
    run, info = _learned_runner(raw, cam, a.raw, a.model_dir, a.route)
    x = raw.astype(np.float32)[None, ..., None]
    run(x)  # warm-up: graph tracing
    times = []
    for _ in range(max(1, a.repeat)):
        t = time.perf_counter()
        stack = run(x)
        times.append(time.perf_counter() - t)
    print(f"{a.route}: predicted 4 planes {stack.shape[1:]} in {1e3 * np.median(times):.1f} ms per light field "
          f"(median of {len(times)} after a warm-up; backbone input {info['model_config']['input_rows']}x"
          f"{info['model_config']['input_cols']}, weights {info['backbone_weights']}, "
          f"keras backend {__import__('keras').backend.backend()})")
    _write_stack(a.out, stack, latency_s=np.asarray(times))


def _profiles_input(a):
    """Camera, 4-plane stack, depths, slopes and flame objects (or None) for ``profiles``."""
    from .camera import PAPER_CAMERA
    from .refocus import aperture_mask, refocus
    from .scenes import PAPER_DEPTHS_MM
    s = str(a.raw)
    gt, objects, slopes = None, None, None
    if ".h5:" in s:
        from .dataset import LightFieldDataset
        f, i = s.rsplit(":", 1)
        ds = LightFieldDataset(f)
        raw, cam = ds.raw(int(i)), ds.camera
        gt, objects, slopes = ds.gt(int(i)), ds.params(int(i)), ds.slopes
    else:
        raw, cam = _load_raw(a.raw)
        objects = _raw_objects(a.raw)
    cam = cam or PAPER_CAMERA
    if objects is not None and not all("height_mm" in o for o in objects):
        raise ValueError(f"{a.raw} does not hold a flame scene (its objects have no flame heights)")
    depths = [float(o["depth_offset_mm"]) for o in objects] if objects else list(PAPER_DEPTHS_MM)
    if a.slope:
        slopes = a.slope
    elif slopes is None:
        slopes = [cam.slope_for_depth(d) for d in depths]
    if len(slopes) != len(depths):
        raise ValueError(f"need {len(depths)} slopes, one per plane. Received: {slopes}")
    n = cam.pixels_per_lenslet
    if a.route == "ground-truth":
        if gt is None:
            raise ValueError("--route ground-truth needs a dataset sample DATASET.h5:INDEX")
        stack = gt
    elif a.route in LEARNED_ROUTES:
        if not a.model_dir:
            raise ValueError(f"--route {a.route} needs --model-dir")
        run, _ = _learned_runner(raw, cam, a.raw, a.model_dir, a.route)
        stack = run(raw.astype(np.float32)[None, ..., None])
    else:
        kw = {"shift-sum": {}, "shift-sum-nearest": dict(interpolation="nearest"),
              "fourier": dict(method="fourier")}[a.route]
        stack = refocus(raw, slopes, n, aperture_mask(n, "circular"), **kw)
    return cam, np.asarray(stack), depths, list(slopes), objects


def cmd_profiles(a):
    import pandas as pd
    from .config import atomic_write_text
    from .diagnostics import EmptyPlaneError, flame_truth, measure_flame, score_stacks
    cam, stack, depths, slopes, objects = _profiles_input(a)
    if objects:
        sample = int(str(a.raw).rsplit(":", 1)[1]) if ".h5:" in str(a.raw) else 0
        df = score_stacks(stack[None], cam, [objects], samples=[sample], route=a.route)
        df.insert(0, "plane", range(len(df)))
        ms = []
        for plane, o in zip(stack, objects):
            try:
                ms.append(measure_flame(plane, cam, o["depth_offset_mm"], columns=flame_truth(o)["columns"]))
            except EmptyPlaneError:
                ms.append(None)
    else:
        ms, rows = [], []
        for k, (plane, d) in enumerate(zip(stack, depths)):
            try:
                m = measure_flame(plane, cam, d)
                rows.append(dict(plane=k, route=a.route, depth_mm=d, **m.summary(), failure=""))
            except EmptyPlaneError as e:
                m = None
                rows.append(dict(plane=k, route=a.route, depth_mm=d, failure=str(e)))
            ms.append(m)
        df = pd.DataFrame(rows)
    df.insert(3, "slope", slopes)
    out = Path(a.out)
    atomic_write_text(f"{out}.csv", df.to_csv(index=False, float_format="%.5g"))
    axial = pd.DataFrame([dict(plane=k, depth_mm=d, height_mm=h, intensity=v)
                          for k, (m, d) in enumerate(zip(ms, depths)) if m is not None
                          for h, v in zip(m.axial_height_mm, m.axial_intensity)])
    atomic_write_text(f"{out}.axial.csv", axial.to_csv(index=False, float_format="%.5g"))
    _plot_profiles(f"{out}.png", cam, stack, depths, ms, objects, a.route)
    cols = [c for c in ("depth_mm", "height_mm", "height_mm_true", "height_err_mm", "max_width_mm",
                        "centroid_x_mm", "integrated_intensity", "failure") if c in df]
    print(df[cols].to_string(index=False, float_format=lambda v: f"{v:.3f}"))
    print(f"-> {out}.csv, {out}.axial.csv, {out}.png")


def _plot_profiles(path, cam, stack, depths, ms, objects, route):
    """Each plane in object-space mm with the measured outline and edges (and the true ones),
    then the axial and radial profiles of the planes."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from .diagnostics import flame_truth, lenslet_to_object_mm
    P = len(stack)
    fig = plt.figure(figsize=(2.6 * P, 9.0))
    grid = fig.add_gridspec(2, P, height_ratios=(2.2, 1.0))
    vmax = max(float(np.max(stack)), 1e-9)
    for k, (plane, d, m) in enumerate(zip(stack, depths, ms)):
        ax = fig.add_subplot(grid[0, k])
        (top, bottom), (left, right) = lenslet_to_object_mm(cam, [-0.5, plane.shape[0] - 0.5],
                                                            [-0.5, plane.shape[1] - 0.5], d)
        ax.imshow(plane, cmap="inferno", vmin=0, vmax=vmax, extent=(left, right, bottom, top))
        title = f"{d:+.0f} mm"
        if m is not None:
            rows, cols = np.arange(plane.shape[0]), np.arange(plane.shape[1])
            y, x = lenslet_to_object_mm(cam, rows[:, None], cols[None, :], d)
            ax.contour(np.broadcast_to(x, plane.shape), np.broadcast_to(y, plane.shape), m.mask, [0.5],
                       colors="w", linewidths=0.7)
            for yy in (m.base_y_mm, m.tip_y_mm):
                ax.axhline(yy, color="w", ls="--", lw=0.8)
            title += f"\nH {m.height_mm:.2f} mm"
        else:
            title += "\nno flame found"
        if objects:
            t = flame_truth(objects[k])
            for yy in (t["base_y_mm"], t["tip_y_mm"]):
                ax.axhline(yy, color="c", lw=0.8)
            title += f" (true {t['height_mm']:.2f})"
        ax.set_title(title, fontsize=9)
        ax.set_xlabel("x (mm)", fontsize=8)
        if k == 0:
            ax.set_ylabel("y (mm)", fontsize=8)
        ax.tick_params(labelsize=7)
    axa = fig.add_subplot(grid[1, : max(1, P // 2)])
    axr = fig.add_subplot(grid[1, max(1, P // 2):]) if P > 1 else None
    for k, (d, m) in enumerate(zip(depths, ms)):
        if m is None:
            continue
        axa.plot(m.axial_height_mm, m.axial_intensity, color=f"C{k}", label=f"{d:+.0f} mm")
        if axr is not None:
            for j, r in enumerate(m.radial):
                axr.plot(r.x_mm, r.intensity, color=f"C{k}", ls=("-", "--", ":")[j % 3], lw=0.9,
                         label=f"{d:+.0f} mm, {r.height_mm:.1f} mm" if k == 0 or j == 0 else None)
    axa.set(xlabel="height above the measured base (mm)", ylabel="intensity on the centreline",
            title=f"axial profiles ({route})")
    axa.legend(fontsize=7)
    if axr is not None:
        axr.set(xlabel="offset from the centreline (mm)", ylabel="intensity",
                title="radial profiles at 25 / 50 / 75 % of the height")
        axr.legend(fontsize=6, ncol=2)
    fig.tight_layout()
    Path(path).parent.mkdir(parents=True, exist_ok=True)
    tmp = Path(f"{path}.partial.png")
    fig.savefig(tmp, dpi=100)
    plt.close(fig)
    tmp.replace(path)


def cmd_evaluate(a):
    from .evaluate import evaluate
    table = evaluate(a.dataset, a.model_dir, a.results, n_fresh=a.fresh)
    print(table.to_string(index=False))


def cmd_tables(a):
    import h5py
    from .evaluate import read_gnu_time, write_tables
    from .scenes import REGIMES
    times, targets = {}, {}
    sl = Path(a.data_dir) / "slopes.json"
    if sl.exists():
        times["slope search"] = json.loads(sl.read_text())["wall_time_s"]
    for regime in REGIMES:
        for scene in ("shapes", "flame"):
            d = Path(a.data_dir) / regime / f"{scene}.h5"
            if d.exists():
                with h5py.File(d, "r") as f:
                    times[f"dataset {regime} {scene}"] = float(f.attrs.get("wall_time_s_last_run", float("nan")))
            info = Path(a.model_dir) / regime / scene / "train_info.json"
            if info.exists():
                i = json.loads(info.read_text())
                with h5py.File(i["feature_cache"], "r") as f:  # when they were computed, maybe by an earlier run
                    times[f"backbone features {regime} {scene}"] = float(f.attrs["wall_time_s"])
                times[f"training {regime} {scene} (start + {i['epochs_run']} epochs)"] = i["training_wall_time_s"]
            tv = Path(a.model_dir) / regime / scene / "time_v.txt"
            if tv.exists():
                targets[f"train {regime} {scene}"] = read_gnu_time(tv)
    print(write_tables(a.results, times, targets))


def main(argv=None):
    p = argparse.ArgumentParser(prog="lf-flame", description="Light-field refocusing of burner flames: "
                                "simulate, refocus, build datasets, train and evaluate the paper's model.")
    sub = p.add_subparsers(dest="command", required=True)

    s = sub.add_parser("simulate", help="render a raw light-field image of a scene")
    s.add_argument("--scene", choices=["shapes", "flame", "point"], required=True)
    s.add_argument("--out", required=True, help=".npz (raw, camera, objects[, views]) or .png")
    s.add_argument("--seed", type=int, default=0)
    s.add_argument("--rays-per-pixel", type=int, default=16)
    s.add_argument("--data-config", help="TOML with a [camera] table (default: the paper's camera)")
    s.add_argument("--nominal", action="store_true", help="the nominal scene (no random variation)")
    s.add_argument("--views", action="store_true", help="also store sub-aperture views (N, N, R, C)")
    s.add_argument("--crosstalk", action="store_true", help="add crosstalk through neighbouring lenslets")
    s.add_argument("--bit-depth", type=int, help="quantise the raw image to this many bits")
    s.add_argument("--depth", type=float, default=0.0, help="point scene: depth offset (mm)")
    s.add_argument("--y", type=float, default=0.0, help="point scene: height (mm)")
    s.add_argument("--x", type=float, default=0.0, help="point scene: lateral position (mm)")
    s.set_defaults(func=cmd_simulate)

    s = sub.add_parser("calibrate", help="calibrate a real camera's lenslet grid from a white image")
    s.add_argument("white", help="white (flat-field) image: PNG, TIFF, .npy or .npz")
    s.add_argument("--dark", help="dark frame, subtracted first")
    s.add_argument("--layout", choices=["auto", "square", "hex"], default="auto")
    s.add_argument("--camera-id", help="name of the camera, stored and checked by decode")
    s.add_argument("--out", required=True, help="calibration JSON")
    s.set_defaults(func=cmd_calibrate)

    s = sub.add_parser("decode", help="decode a real raw image into sub-aperture views with a calibration")
    s.add_argument("raw", help="raw light-field image: PNG, TIFF, .npy or .npz")
    s.add_argument("--calibration", required=True, help="JSON written by 'lf-flame calibrate'")
    s.add_argument("--white", help="white image (default: the calibration's, checked by its SHA-256)")
    s.add_argument("--dark", help="dark frame (default: the calibration's, if any)")
    s.add_argument("--no-white", action="store_true", help="no white-image normalisation")
    s.add_argument("--views", type=int, help="views per axis (default: the pitch rounded down)")
    s.add_argument("--camera-id", help="refuse a calibration of another camera")
    s.add_argument("--out", required=True, help="HDF5 of the views (N, N, R, C)")
    s.set_defaults(func=cmd_decode)

    s = sub.add_parser("refocus", help="refocus a raw image (or decoded views) at one or more slopes")
    s.add_argument("raw", help=".npz from simulate, .npy, DATASET.h5:INDEX, or VIEWS.h5 from decode")
    s.add_argument("--slope", type=float, action="append", required=True, help="lenslets per view (repeatable)")
    s.add_argument("--method", choices=["shift-sum", "fourier"], default="shift-sum")
    s.add_argument("--interpolation", choices=["bilinear", "nearest"], default="bilinear",
                   help="shift-sum only: bilinear, or whole-lenslet shifts")
    s.add_argument("--aperture", choices=["square", "circular"], default="circular")
    s.add_argument("--out", required=True, help=".npz (stack) or .png (planes side by side)")
    s.set_defaults(func=cmd_refocus)

    s = sub.add_parser("slopes", help="sharpest slope of each object of a raw image (table and plot of the "
                       "sharpness curves); without RAW, calibrate the nominal scene of a data config")
    s.add_argument("raw", nargs="?", help=".npz from simulate (its objects' ROIs are used), .npy, DATASET.h5:INDEX, "
                   "or VIEWS.h5 from decode")
    s.add_argument("--roi", type=int, nargs=4, action="append", metavar=("ROW0", "ROW1", "COL0", "COL1"),
                   help="region in lenslets (repeatable; default: the stored objects, else the whole image)")
    s.add_argument("--metric", choices=["tenengrad", "laplacian", "normvar"], default="tenengrad")
    s.add_argument("--method", choices=["fourier", "shift-sum"], default="fourier")
    s.add_argument("--lo", type=float, default=-3.0)
    s.add_argument("--hi", type=float, default=3.0)
    s.add_argument("--aperture", choices=["square", "circular"], default="circular")
    s.add_argument("--out-prefix", help="write PREFIX.slopes.csv and PREFIX.slopes.png (default: beside RAW)")
    s.add_argument("--data-config", help="calibration mode: data config TOML")
    s.add_argument("--out", help="calibration mode: JSON of the slopes used for ground truth")
    s.add_argument("--results", help="calibration mode: folder for slopes.csv and slopes.png")
    s.set_defaults(func=cmd_slopes)

    s = sub.add_parser("dataset", help="generate (or resume) a dataset in HDF5")
    s.add_argument("--data-config", required=True)
    s.add_argument("--scene", choices=["shapes", "flame"], required=True)
    s.add_argument("--slopes", required=True, help="JSON written by 'lf-flame slopes'")
    s.add_argument("--regime", choices=["paper", "varied"],
                   help="scene variation (docs/scenes.md) instead of the data config's")
    s.add_argument("--out", required=True)
    s.add_argument("--shard", help="i/N: render only shard i of N (1 <= i <= N) beside --out; an unsharded "
                                   "run imports finished shards and renders the rest")
    s.add_argument("--quiet", action="store_true")
    s.set_defaults(func=cmd_dataset)

    s = sub.add_parser("train", help="train the decoder on cached backbone features (resumable)")
    s.add_argument("--dataset", required=True)
    s.add_argument("--experiment-config", required=True)
    s.add_argument("--out", required=True, help="model folder")
    s.add_argument("--input-size", help="ROWSxCOLS: backbone input size instead of the config's")
    s.add_argument("--time-budget-s", type=float, help="training time budget (s) instead of the config's")
    s.add_argument("--quiet", action="store_true")
    s.set_defaults(func=cmd_train)

    s = sub.add_parser("predict", help="the trained model's 4 refocused planes of a raw image, with its latency")
    s.add_argument("raw", help=".npz from simulate, .npy, or DATASET.h5:INDEX")
    s.add_argument("--model-dir", required=True, help="folder written by 'lf-flame train'")
    s.add_argument("--out", required=True, help=".npz (stack (4, R, C), latency_s) or .png (planes side by side)")
    s.add_argument("--repeat", type=int, default=5, help="timed calls after the warm-up")
    s.add_argument("--route", choices=list(LEARNED_ROUTES), default="network",
                   help="the trained network, or one of its yardsticks saved beside it")
    s.set_defaults(func=cmd_predict)

    s = sub.add_parser("profiles", help="flame diagnostics per plane: height, widths, centroid, intensity, "
                       "axial and radial profiles in object-space mm (CSV and figure)")
    s.add_argument("raw", help=".npz from 'simulate --scene flame', .npy, or DATASET.h5:INDEX (the truth is "
                               "marked when the flames' objects are known)")
    s.add_argument("--route", choices=["ground-truth", "shift-sum", "shift-sum-nearest", "fourier",
                                       *LEARNED_ROUTES], default="shift-sum",
                   help="refocusing route; ground-truth: a dataset's stored planes; learned routes need --model-dir")
    s.add_argument("--model-dir", help="folder written by 'lf-flame train' (learned routes)")
    s.add_argument("--slope", type=float, action="append",
                   help="one per plane (repeatable); default: the dataset's, else the analytic slopes of the depths")
    s.add_argument("--out", required=True, help="PREFIX: writes PREFIX.csv (one row per plane), PREFIX.axial.csv "
                                               "and PREFIX.png")
    s.set_defaults(func=cmd_profiles)

    s = sub.add_parser("evaluate", help="SSIM/PSNR per plane on the test split, table and figure")
    s.add_argument("--dataset", required=True)
    s.add_argument("--model-dir", required=True)
    s.add_argument("--results", required=True)
    s.add_argument("--fresh", type=int, default=0, help="also score this many freshly drawn samples")
    s.set_defaults(func=cmd_evaluate)

    s = sub.add_parser("tables", help="collect Tables I and II, slopes and stage times into tables.md")
    s.add_argument("--results", required=True)
    s.add_argument("--data-dir", required=True)
    s.add_argument("--model-dir", required=True)
    s.set_defaults(func=cmd_tables)

    a = p.parse_args(argv)
    try:
        a.func(a)
    except (ValueError, FileNotFoundError) as e:
        print(f"error: {e}", file=sys.stderr)
        return 2
    return 0


if __name__ == "__main__":
    sys.exit(main())
