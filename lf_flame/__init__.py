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


def _keep_freed_memory() -> bool:
    """glibc's malloc: arrays up to 32 MiB (the largest the setting takes) from the heap, and freed heap memory kept
    for the next arrays instead of returned to the system (``mallopt``: ``M_MMAP_THRESHOLD`` 32 MiB,
    ``M_TRIM_THRESHOLD`` 1 GiB). admm allocates the FFTs' outputs afresh at every fill; each first touch of fresh
    memory costs a page fault, dear in a virtual machine, and the default returns freed memory once 2-64 MiB of it
    sit at the heap's top (``experiments/floor.py``; docs/decisions.md). Not where the user has tuned malloc
    (``MALLOC_MMAP_THRESHOLD_``, ``MALLOC_TRIM_THRESHOLD_``, ``GLIBC_TUNABLES``) or off glibc. Returns whether it
    was set. The cost: the process keeps the heap's peak until it exits (arrays over 32 MiB, the operators'
    spectra among them, are still given back when freed). Dask's nannies start their workers with
    ``MALLOC_TRIM_THRESHOLD_`` set (Dask's own advice, to give memory back), which is kept there."""
    import ctypes
    import sys
    user_set = ("MALLOC_MMAP_THRESHOLD_", "MALLOC_TRIM_THRESHOLD_", "GLIBC_TUNABLES")
    if not sys.platform.startswith("linux") or any(k in os.environ for k in user_set):
        return False
    try:
        libc = ctypes.CDLL("libc.so.6")
        m_trim_threshold, m_mmap_threshold = -1, -3                   # malloc.h
        return bool(libc.mallopt(m_mmap_threshold, 32 << 20)) and bool(libc.mallopt(m_trim_threshold, 1 << 30))
    except (OSError, AttributeError):                                 # not glibc (musl has no mallopt)
        return False


#: Whether importing lf_flame tuned glibc's malloc (:func:`_keep_freed_memory`).
MALLOC_TUNED = _keep_freed_memory()
