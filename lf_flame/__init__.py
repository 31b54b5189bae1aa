"""lf_flame: deep-learning light-field refocusing of burner flames, reproduced.

Modules: :mod:`~lf_flame.optics` (ray transfer matrices), :mod:`~lf_flame.camera`
(the plenoptic camera), :mod:`~lf_flame.scenes` (layered scenes),
:mod:`~lf_flame.simulate` (ray tracer), :mod:`~lf_flame.refocus` (shift-and-sum,
slope search), :mod:`~lf_flame.dataset` (HDF5 datasets), :mod:`~lf_flame.model`
(the Keras model), :mod:`~lf_flame.train`, :mod:`~lf_flame.evaluate`.
"""
__version__ = "0.1.0"
