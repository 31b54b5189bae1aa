"""lf_flame: deep-learning light-field refocusing of burner flames, reproduced.

The package's folders are its stages (``docs/architecture.md`` draws them):

- :mod:`lf_flame.optics`: ray transfer matrices and the plenoptic camera;
- :mod:`lf_flame.simulate`: scenes and the ray tracer that renders raw light fields;
- :mod:`lf_flame.refocus`: sub-aperture views, shift-and-sum and the slope search;
- :mod:`lf_flame.real`: white-image calibration and decoding of real captures;
- :mod:`lf_flame.learn`: datasets, the paper's Keras model, its yardsticks, Tables I and II;
- :mod:`lf_flame.measure`: flame diagnostics per plane, SSIM and PSNR;
- :mod:`lf_flame.tomo`: each plane's emission by inverting the camera as a linear operator;
- :mod:`lf_flame.temperature`: two-colour pyrometry, each colour channel's emission and their ratio to temperature;
- :mod:`lf_flame.recordings`: flames over time, per-plane flicker, serially or on Dask;
- :mod:`lf_flame.cli`: the ``lf-flame`` command line.

Shared by every stage: :mod:`lf_flame.config` (configs, provenance, atomic writes) and
:mod:`lf_flame.parallel` (Dask clients and an unordered map).
"""
import os

__version__ = "0.1.0"

# Numba's OpenMP threads busy-wait after each parallel kernel (libgomp's default: 300,000 spins), holding the cores
# that SciPy's FFT threads and the next kernel want at once; waiting passively made admm's solve faster on 2 cores
# (``experiments/thread_wait.py``, results/thread_wait.md). Set before any OpenMP runtime starts; a user's own
# setting is kept (libgomp manual, OMP_WAIT_POLICY and GOMP_SPINCOUNT).
os.environ.setdefault("OMP_WAIT_POLICY", "PASSIVE")
# PyLops imports JAX at its own import where JAX is installed (0.35-0.46 s of every command's start); lf_flame hands
# it NumPy arrays only. A user's own setting is kept.
os.environ.setdefault("JAX_PYLOPS", "0")
