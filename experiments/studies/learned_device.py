"""The learned reconstructor trained on a GPU machine: more training data than 2 cores afford (a study).

Training samples (:func:`lf_flame.learn.reconstructor.training_samples`, the seeds of ``experiments/learned.py``)
made on 15 processes of one thread each (``NUMBA_NUM_THREADS=1``: a process's Numba threads times 15 processes
oversubscribe the cores), then trained with Keras on JAX for each base width given; each model saved under
``$OUT/gpu<width>``, to be scored on the CPU by ``experiments/learned.py --stage score --models DIR``.

Run on the device machine (its image has JAX; keras, optree, namex, pylops and pyproximal carried as wheels):
``KERAS_BACKEND=jax NUMBA_NUM_THREADS=1 PYTHONPATH=. python3 experiments/studies/learned_device.py SCENES WIDTHS EPOCHS``,
e.g. ``500 16 25`` (results/learned_h100_two_families.md: 500 scenes, 4 min 17 s in all on an H100).
"""
import os, sys, time
from concurrent.futures import ProcessPoolExecutor
import numpy as np
N, CHUNK, PROCS = int(sys.argv[1]), 10, 15
TRAIN_SEED, VAL_SEED = 1_100_000, 1_200_000

def chunk(args):
    first, n, seed = args
    from lf_flame.learn import reconstructor as L
    from lf_flame.optics.camera import PAPER_CAMERA
    return L.training_samples(PAPER_CAMERA, n, seed, progress=False, first=first, workers=1)

if __name__ == "__main__":
    t0 = time.time()
    jobs = [(f, min(CHUNK, N - f), TRAIN_SEED) for f in range(0, N, CHUNK)] + [(0, 13, VAL_SEED), (13, 12, VAL_SEED)]
    with ProcessPoolExecutor(PROCS) as pool:
        parts = list(pool.map(chunk, jobs))
    tr, va = parts[:-2], parts[-2:]
    x, y = np.concatenate([p[0] for p in tr]), np.concatenate([p[1] for p in tr])
    xv, yv = np.concatenate([p[0] for p in va]), np.concatenate([p[1] for p in va])
    gen_s = time.time() - t0
    print("data", x.shape, xv.shape, round(gen_s), "s", flush=True)
    from lf_flame.learn import reconstructor as L
    from lf_flame.optics.camera import PAPER_CAMERA
    import jax
    print(jax.devices(), flush=True)
    for base in [int(b) for b in sys.argv[2].split(",")]:
        cfg = L.ReconstructorConfig(epochs=int(sys.argv[3]), base_channels=base, patience=8)
        m = L.train(PAPER_CAMERA, (x, y), (xv, yv), cfg, verbose=2)
        m.record.update(train_seed=TRAIN_SEED, train_scenes=N, val_seed=VAL_SEED, val_scenes=25,
                        families=list(L.TRAIN_FAMILIES), device="nvidia-h100 (Keras on JAX)", data_s=gen_s,
                        keras_backend="jax")
        out = os.path.join(os.environ["OUT"], f"gpu{base}")
        m.save(out)
        print("saved", base, m.record["best_epoch"], m.record["epochs_run"], round(m.record["train_s"]), flush=True)
