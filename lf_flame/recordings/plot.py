"""The recording's figure: heights over time and each plane's spectrum."""
from __future__ import annotations

import numpy as np
import pandas as pd


def plot_sequence(path, frames: pd.DataFrame, spec: pd.DataFrame, pk: pd.DataFrame, title: str = "") -> None:
    """Figure: each plane's height against time (truth dashed when known) and its spectrum
    (true frequency marked)."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    planes = sorted(frames.plane.unique())
    fig, axes = plt.subplots(len(planes), 2, figsize=(11, 2.0 * len(planes) + 0.6), squeeze=False)
    for ax, k in zip(axes, planes):
        g = frames[frames.plane == k].sort_values("frame")
        d = g.depth_mm.iloc[0]
        ax[0].plot(g.time_s, g.height_mm, lw=0.8, label="measured")
        if "height_mm_true" in g:
            ax[0].plot(g.time_s, g.height_mm_true, "k--", lw=0.6, label="true")
        ax[0].set_ylabel(f"{d:+g} mm\nheight (mm)")
        s = spec[(spec.plane == k) & (spec.signal == "height_mm")]
        ax[1].semilogy(s.freq_hz, s.power + 1e-12, lw=0.8)
        p = pk[(pk.plane == k) & (pk.signal == "height_mm")].iloc[0]
        ax[1].axvline(p.dominant_hz, color="C1", lw=0.8, label=f"peak {p.dominant_hz:.1f} Hz")
        if "true_hz" in p and np.isfinite(p.get("true_hz", np.nan)):
            ax[1].axvline(p.true_hz, color="k", ls="--", lw=0.6, label=f"true {p.true_hz:.2f} Hz")
        ax[1].set_xlim(0, min(s.freq_hz.max(), 60))
        ax[1].set_ylabel("power (mm²)")
        ax[1].legend(fontsize=7, loc="upper right")
    axes[0][0].legend(fontsize=7, loc="upper right")
    axes[-1][0].set_xlabel("time (s)")
    axes[-1][1].set_xlabel("frequency (Hz)")
    fig.suptitle(title, fontsize=9)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
