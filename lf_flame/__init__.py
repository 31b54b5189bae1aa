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
__version__ = "0.1.0"
