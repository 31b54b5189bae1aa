"""Each plane's flicker spectrum (Welch, :func:`scipy.signal.welch`) and its dominant frequency."""
from __future__ import annotations

import math

import numpy as np
import pandas as pd

#: Per-plane signals whose spectra are computed (columns of the frames table).
SIGNALS = ("height_mm", "integrated_intensity")
#: A dominant frequency is resolved when at least this many of its periods fit the spectrum's segment (the record,
#: or Welch's segment): below, it lies in the spectrum's first bin, where any slower change of the signal lands too
#: (a record of 20 frames at 500 frames/s read flames flickering at 5-20 Hz as 25 Hz, its first bin).
MIN_PERIODS = 2


# ---------------------------------------------------------------------------------
def spectra(frames: pd.DataFrame, fps: float, nperseg: int | None = None, signals=SIGNALS) -> pd.DataFrame:
    """Each plane's power spectrum of each signal (Welch, Hann window, mean removed).

    Parameters
    ----------
    frames : DataFrame
        The frames table (columns frame, plane, depth_mm and the ``signals``); a frame
        whose plane could not be measured (NaN) takes the plane's mean.
    fps : float
        Frame rate (frames/s).
    nperseg : int or None
        Welch segment length (frames); None: the whole record, so the bin is 1/T.

    Returns
    -------
    DataFrame with columns plane, depth_mm, signal, freq_hz, power (the signal's unit
    squared: ``scaling="spectrum"``, a sinusoid of amplitude a on a bin has power a²/2).

    Raises
    ------
    ValueError
        A plane with fewer than 2 frames, or ``nperseg`` below 2: no spectrum beyond 0 Hz; ``fps`` not finite
        and > 0.
    """
    from scipy.signal import welch
    if not (math.isfinite(fps) and fps > 0):
        raise ValueError(f"fps (the recording's frames per second) must be finite and > 0. Received: {fps!r}")
    if nperseg is not None and (int(nperseg) != nperseg or nperseg < 2):
        raise ValueError(f"nperseg (Welch segment, frames) must be a whole number >= 2. Received: {nperseg!r}")
    out = []
    for (k, d), g in frames.groupby(["plane", "depth_mm"], sort=True):
        g = g.sort_values("frame")
        if len(g) < 2:
            raise ValueError(f"plane {k} has {len(g)} frame: a spectrum needs at least 2 frames")
        for s in signals:
            x = g[s].to_numpy(float)
            x = np.where(np.isfinite(x), x, np.nanmean(x) if np.isfinite(x).any() else 0.0)
            f, p = welch(x, fs=fps, nperseg=min(nperseg or len(x), len(x)), detrend="constant", scaling="spectrum")
            out.append(pd.DataFrame(dict(plane=k, depth_mm=d, signal=s, freq_hz=f, power=p)))
    return pd.concat(out, ignore_index=True)


def unresolved_note(pk: pd.DataFrame) -> str | None:
    """A line for the user where a dominant frequency is not resolved (:func:`peaks`' ``resolved``), else None: the
    planes and signals, their frequency, and the record's length that would resolve it."""
    bad = pk[~pk.resolved.astype(bool)]
    if bad.empty:
        return None
    seg = 1.0 / float(bad.bin_hz.iloc[0])
    planes = ", ".join(str(int(k)) for k in sorted(set(bad.plane)))
    hz = ", ".join(f"{v:.3g}" for v in sorted(set(bad.dominant_hz)))
    return (f"warning: {len(bad)} of {len(pk)} dominant frequencies are not resolved (planes {planes}, at {hz} Hz): "
            f"fewer than {MIN_PERIODS} of their periods fit the spectrum's {seg:.3g} s segment, where any slower "
            f"change lands too; a flicker of f Hz needs {MIN_PERIODS}/f s of recording or more (peaks.csv: resolved)")


def peaks(spec: pd.DataFrame, truth_freqs_hz=None) -> pd.DataFrame:
    """Dominant frequency of each plane and signal (the largest power above 0 Hz), its
    amplitude ``sqrt(2 P)``, its periods in the spectrum's segment (``periods``: the frequency over
    the bin) and whether it is resolved (``resolved``: at least :data:`MIN_PERIODS` of them), and
    where the true frequencies are known (one per plane, plane ``k`` holding flame ``k``): the true
    frequency, the error in bins, whether a resolved peak lies within one bin of it, and how far (dB)
    the other flames' frequencies lie below the plane's own on its spectrum (the worst of them).

    Raises
    ------
    ValueError
        A spectrum of a single bin (fewer than 2 frames); a true frequency more than one
        bin outside the spectrum (0 to half the frame rate); not one true frequency per plane.
    """
    n_planes = spec.plane.nunique()
    if truth_freqs_hz is not None and len(truth_freqs_hz) != n_planes:
        raise ValueError(f"truth_freqs_hz holds {len(truth_freqs_hz)} frequencies for {n_planes} planes: one per plane "
                         "(plane k holding flame k)")
    rows = []
    for (k, d, s), g in spec.groupby(["plane", "depth_mm", "signal"], sort=False):
        f, p = g.freq_hz.to_numpy(), g.power.to_numpy()
        if len(f) < 2:
            raise ValueError(f"plane {k}'s spectrum has {len(f)} bin: it needs at least 2 frames")
        j = 1 + int(np.argmax(p[1:]))
        df = f[1] - f[0]
        row = dict(plane=k, depth_mm=d, signal=s, bin_hz=df, dominant_hz=f[j], amplitude=math.sqrt(2 * p[j]),
                   periods=f[j] / df, resolved=bool(f[j] / df >= MIN_PERIODS))
        if truth_freqs_hz is not None:
            for hz in truth_freqs_hz:
                if not (-df <= hz <= f[-1] + df):
                    raise ValueError(f"true frequency {hz:g} Hz lies outside the spectrum (0 to {f[-1]:g} Hz, "
                                     f"bins of {df:g} Hz)")

            def power_at(hz):   # the largest power within one bin of hz (a tone off the bin grid splits)
                return float(p[np.abs(f - hz) <= df].max())
            own = truth_freqs_hz[k]
            others = [v for i, v in enumerate(truth_freqs_hz) if i != k]
            row.update(true_hz=own, error_bins=abs(f[j] - own) / df,
                       within_one_bin=row["resolved"] and abs(f[j] - own) <= df)
            if others:
                below = [10 * math.log10(max(power_at(own), 1e-300) / max(power_at(v), 1e-300)) for v in others]
                row.update(others_below_db=min(below), worst_other_hz=others[int(np.argmin(below))])
        rows.append(row)
    return pd.DataFrame(rows)
