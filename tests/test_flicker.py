"""The flicker spectra's frequency axis (lf_flame.recordings.flicker): a tone is found at its
frequency, to far better than the 1 % that a wrong frame rate would shift it by."""
import numpy as np
import pandas as pd
import pytest

from lf_flame.recordings.flicker import peaks, spectra


def _frames(n, fps, tones):
    """A frames table of one plane whose signals are pure tones: ``tones`` maps a signal to (Hz, amplitude)."""
    t = np.arange(n) / fps
    cols = {s: 3.0 + a * np.sin(2 * np.pi * hz * t + 0.3) for s, (hz, a) in tones.items()}
    return pd.DataFrame(dict(frame=np.arange(n), plane=0, depth_mm=10.0, **cols))


@pytest.mark.parametrize("nperseg", [None, 200])
def test_a_tone_on_a_bin_is_found_at_its_frequency_and_amplitude(nperseg):
    """fps 100, 1000 frames: bins of 0.1 Hz on the whole record, 0.5 Hz on segments of 200.
    Tones at 13.5 and 7 Hz lie on a bin of both: the dominant frequency is the tone's within
    0.2 % (a frame rate off by 1 % moves it 0.135 Hz), the frequencies are NumPy's ``rfftfreq``
    of the segment, and the amplitude sqrt(2 P) is the tone's."""
    fps, n = 100.0, 1000
    tones = {"height_mm": (13.5, 0.8), "integrated_intensity": (7.0, 2.0)}
    spec = spectra(_frames(n, fps, tones), fps, nperseg=nperseg)
    seg = nperseg or n
    for s, (hz, amp) in tones.items():
        f = spec[spec.signal == s].freq_hz.to_numpy()
        np.testing.assert_allclose(f, np.fft.rfftfreq(seg, 1.0 / fps), rtol=1e-12, atol=1e-12)
    pk = peaks(spec).set_index("signal")
    for s, (hz, amp) in tones.items():
        assert pk.loc[s, "bin_hz"] == pytest.approx(fps / seg, rel=1e-9)
        assert pk.loc[s, "dominant_hz"] == pytest.approx(hz, rel=0.002)
        assert pk.loc[s, "amplitude"] == pytest.approx(amp, rel=0.01)


def test_a_frame_rate_of_zero_and_a_frequency_per_plane_missing_are_refused():
    """fps 0 had reached SciPy's Welch ('sampling frequency'); true frequencies fewer than the planes an IndexError."""
    frames = pd.concat([_frames(200, 100.0, {"height_mm": (13.5, 0.8), "integrated_intensity": (7.0, 2.0)})
                        .assign(plane=k, depth_mm=10.0 * k)
                        for k in (0, 1)])
    for fps in (0.0, float("nan")):
        with pytest.raises(ValueError, match="fps .* must be finite and > 0"):
            spectra(frames, fps)
    with pytest.raises(ValueError, match="truth_freqs_hz holds 1 frequencies for 2 planes"):
        peaks(spectra(frames, 100.0), truth_freqs_hz=[13.5])
