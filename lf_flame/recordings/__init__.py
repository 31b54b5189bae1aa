"""Recordings: flame diagnostics over time and per-plane flicker, serially or on Dask.

:mod:`.sources` reads frames (HDF5, a folder of images, a simulation) and their rate;
:mod:`.job` holds a run's settings; :mod:`.chunk` processes a chunk of frames; :mod:`.flicker`
gives each plane's Welch spectrum and dominant frequency; :mod:`.plot` the figure;
:mod:`.runner` runs the chunks serially or on Dask (:mod:`lf_flame.parallel`),
resumably.

Its public names are importable from here (loaded on first use, as scikit-image does).
"""
import lazy_loader as lazy

__getattr__, __dir__, __all__ = lazy.attach(
    __name__,
    submodules=["chunk", "flicker", "job", "plot", "runner", "sources"],
    submod_attrs={
        "flicker": ["SIGNALS", "spectra", "peaks"],
        "job": ["CHUNK", "SequenceJob", "simulated_job"],
        "chunk": ["process_chunk", "truncated_rows"],
        "plot": ["plot_sequence"],
        "runner": ["run"],
        "sources": ["FRAME_SUFFIXES", "SimulatedSource", "H5Source", "TiffStackSource", "FolderSource",
                    "open_source", "write_frames", "frame_rate"],
    },
)
