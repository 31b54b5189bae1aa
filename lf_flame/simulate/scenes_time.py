"""Scenes that change in time: flickering flames filmed at a frame rate.

Each frame is a :class:`lf_flame.simulate.layers.Scene` built by the flame layers of
:mod:`lf_flame.simulate.scenes`; this module adds the time: flicker frequencies, amplitudes and
per-frame jitter, and the recordings' truth. Static scenes stay in :mod:`lf_flame.simulate.scenes`.
"""
from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import numpy as np

from ..optics.camera import PlenopticCamera
from .scenes import FLAME_EFFECTS, FLAME_HEIGHT_MEAN_MM, PAPER_DEPTHS_MM, _flame_layer, camera_template_scale
from .layers import Effects, Scene


@dataclass(frozen=True)
class FlickerFlame:
    """One flickering flame of a :class:`FlameSequence`.

    Its height at time ``t`` (s) is ``height_mm * (1 + amp sin(2 pi f t + phase)
    + harmonic_amp sin(4 pi f t + 2 phase) + jitter e_t)`` with ``e_t`` standard normal
    (drawn per frame and flame from the sequence's seed), and its centreline sways as a
    wave travelling up the flame at the same frequency: the puffing of a buoyant
    diffusion flame (Hamins et al. 1992, f ~ 1.5 / sqrt(D), D the burner diameter in m).

    Attributes
    ----------
    depth_offset_mm : float
        Depth (mm beyond the focal plane).
    height_mm, centre_x_mm, base_y_mm : float
        Mean object-space height, centre and base (mm).
    radiance : float
        Peak radiance (1 saturates the sensor).
    freq_hz : float
        Flicker frequency (Hz).
    amp, harmonic_amp, jitter : float
        Height oscillation at ``f`` and ``2 f`` and per-frame noise (sd), fractions of the height.
    sway : float
        Sway amplitude of the centreline, fraction of the height.
    phase : float
        Phase at t = 0 (radians).
    """

    depth_offset_mm: float
    height_mm: float
    centre_x_mm: float
    base_y_mm: float
    radiance: float
    freq_hz: float
    amp: float = 0.10
    harmonic_amp: float = 0.03
    jitter: float = 0.01
    sway: float = 0.03
    phase: float = 0.0


@dataclass(frozen=True)
class FlameSequence:
    """A recording of flickering flames: ``n_frames`` frames at ``fps`` frames per second.

    Frame ``i`` (time ``i / fps`` s) is a pure function of the sequence and ``i``
    (:meth:`scene`), so frames render in any order, on any machine, identically.

    Attributes
    ----------
    name : str
    flames : tuple of FlickerFlame
    fps : float
        Frame rate (frames/s).
    n_frames : int
    seed : int
        Seeds the per-frame jitter (and the ray samples and noise of the renders).
    effects : Effects
        Optically thin flames; sensor noise when asked (:func:`flicker_sequence`).
    texels_per_lenslet : float
    """

    name: str
    flames: tuple
    fps: float
    n_frames: int
    seed: int
    effects: Effects = None
    texels_per_lenslet: float = 3.0

    def __post_init__(self):
        if not (math.isfinite(self.fps) and self.fps > 0) or int(self.n_frames) < 1:
            raise ValueError(f"need fps > 0 and n_frames >= 1. Received: fps={self.fps}, n_frames={self.n_frames}")
        if self.effects is None:
            object.__setattr__(self, "effects", FLAME_EFFECTS)

    def times_s(self) -> np.ndarray:
        """Time of each frame (s), shape (n_frames,)."""
        return np.arange(int(self.n_frames)) / float(self.fps)

    def heights_mm(self, frame: int) -> np.ndarray:
        """True height (mm) of each flame at frame ``frame``, shape (n_flames,)."""
        t = int(frame) / float(self.fps)
        e = np.random.default_rng([int(self.seed), 0xF11C, int(frame)]).standard_normal(len(self.flames))
        return np.array([f.height_mm * (1 + f.amp * math.sin(2 * math.pi * f.freq_hz * t + f.phase)
                                        + f.harmonic_amp * math.sin(4 * math.pi * f.freq_hz * t + 2 * f.phase)
                                        + f.jitter * e[k]) for k, f in enumerate(self.flames)])

    def scene(self, camera: PlenopticCamera, frame: int) -> Scene:
        """The scene of frame ``frame``: one layer and one flame object per flame (keys as
        :func:`flame_scene`'s, with ``freq_hz`` and ``time_s``).

        Raises
        ------
        ValueError
            A frame outside ``[0, n_frames)``.
        """
        if not 0 <= int(frame) < int(self.n_frames):
            raise ValueError(f"frame must lie in [0, {self.n_frames}). Received: {frame}")
        t = int(frame) / float(self.fps)
        layers, objects = [], []
        for f, H in zip(self.flames, self.heights_mm(frame)):
            # the sway's phase runs with time: a wave travelling up the flame
            layer, obj = _flame_layer(camera, f.depth_offset_mm, max(float(H), 1e-3), f.centre_x_mm, f.base_y_mm,
                                      f.radiance, f.sway, f.phase - 2 * math.pi * f.freq_hz * t,
                                      self.texels_per_lenslet)
            layers.append(layer)
            objects.append(dict(obj, freq_hz=f.freq_hz, time_s=t))
        return Scene(self.name, tuple(layers), self.effects, tuple(objects))

    def to_dict(self) -> dict:
        """Plain data (JSON-ready); :meth:`from_dict` inverts it."""
        d = dataclasses.asdict(self)
        d["flames"] = [dataclasses.asdict(f) for f in self.flames]
        return d

    @classmethod
    def from_dict(cls, d: dict) -> "FlameSequence":
        d = dict(d)
        d["flames"] = tuple(FlickerFlame(**f) for f in d["flames"])
        d["effects"] = Effects(**d["effects"]) if d.get("effects") else None
        return cls(**d)


#: Kinds of :func:`flicker_sequence`.
SEQUENCE_KINDS = ("paper", "overlap")


def _distinct_frequencies(rng: np.random.Generator, n: int, lo: float, hi: float, gap: float) -> list[float]:
    """``n`` frequencies in [lo, hi] Hz, each at least ``gap`` from every other and from every other's
    second harmonic (a harmonic must not pass for another flame's flicker)."""
    for _ in range(10_000):
        f = np.sort(rng.uniform(lo, hi, n))
        if all(abs(f[i] - f[j]) >= gap and abs(2 * f[i] - f[j]) >= gap for i in range(n) for j in range(n) if i != j):
            return [round(float(v), 2) for v in f]
    raise ValueError(f"cannot place {n} frequencies {gap} Hz apart in [{lo}, {hi}] Hz")


def flicker_sequence(camera: PlenopticCamera, rng: np.random.Generator, kind: str = "paper", *, fps: float = 500.0,
                     duration_s: float = 1.0, freqs_hz=None, noise: tuple | None = None,
                     template_scale: float | None = None) -> FlameSequence:
    """A recording of flickering flames: each flame its own frequency.

    - ``"paper"``: the paper's four flames (:func:`flame_scene`'s nominal heights and
      positions) at :data:`PAPER_DEPTHS_MM`.
    - ``"overlap"``: two flames one behind the other in the same columns, 20 mm apart in
      depth (+10 and −10 mm): a tall bright one behind (80 % of the field, radiance 1) and
      a shorter dimmer one in front (50 %, radiance 0.6).

    Those are the paper camera's depths; another camera's flames stand at the depths of the same
    parallax (:func:`lf_flame.simulate.scenes_depth.carried_depths`, as ``lf-flame simulate --scene depth``
    carries its depth range), where the paper's millimetres could be far out of focus or all at one
    slope.

    Frequencies default to draws from 5–20 Hz at least 2 Hz apart (and 2 Hz from each
    other's second harmonic); amplitudes 8–12 % of the height with a second harmonic of a
    third of that, 1 % jitter, sway 3 %, random phases.

    Parameters
    ----------
    camera : PlenopticCamera
    rng : numpy.random.Generator
        Source of the frequencies, amplitudes, phases and the sequence's seed.
    kind : {'paper', 'overlap'}
    fps : float
        Frame rate (frames/s).
    duration_s : float
        Length of the recording (s); ``round(fps * duration_s)`` frames.
    freqs_hz : sequence of float or None
        One frequency per flame (Hz, > 0), farthest flame first; None: drawn.
    noise : (full_well_e, read_noise_e, bit_depth) or None
        Sensor noise of every frame (:class:`Effects`); None: noise-free.
    template_scale : float or None
        ``"paper"``: object-space scale of the paper's flame heights (:func:`flame_scene`);
        None: :func:`~lf_flame.simulate.scenes.camera_template_scale`, so the flames fill any
        camera's field as they fill the paper's.

    Returns
    -------
    FlameSequence

    Raises
    ------
    ValueError
        Unknown kind, a wrong number of frequencies or one not positive and finite, a
        frame rate whose Nyquist frequency does not exceed the highest second harmonic,
        fewer than 2 frames.
    """
    if kind not in SEQUENCE_KINDS:
        raise ValueError(f"kind must be one of {SEQUENCE_KINDS}. Received: {kind!r}")
    n = 4 if kind == "paper" else 2
    freqs = _distinct_frequencies(rng, n, 5.0, 20.0, 2.0) if freqs_hz is None else [float(v) for v in freqs_hz]
    if len(freqs) != n or not all(math.isfinite(v) and v > 0 for v in freqs):
        raise ValueError(f"{kind!r} needs {n} positive finite frequencies (Hz). Received: {freqs_hz!r}")
    n_frames = int(round(fps * duration_s))
    if n_frames < 2 or fps / 2 <= 2 * max(freqs):
        raise ValueError(f"need >= 2 frames and fps / 2 above every flame's second harmonic ({2 * max(freqs)} Hz). "
                         f"Received: fps={fps}, duration_s={duration_s}")
    h0, w0 = camera.field_of_view_mm(0.0)
    if template_scale is None:
        template_scale = camera_template_scale(camera)
    from .scenes_depth import carried_depths
    depths = carried_depths(camera, PAPER_DEPTHS_MM if kind == "paper" else (10.0, -10.0))
    flames = []
    for k, dz in enumerate(depths):
        camera.image_distance_mm(camera.object_distance_mm(dz))   # raises for a depth it cannot image
        scale = camera.object_distance_mm(dz) / camera.focus_distance_mm
        if kind == "paper":
            H, cx, level = FLAME_HEIGHT_MEAN_MM[k] * template_scale, ((k + 0.5) / 4 - 0.5) * w0 * 0.9, 1.0
        else:
            H, cx, level = (0.8, 0.5)[k] * h0, 0.0, (1.0, 0.6)[k]
        amp = float(rng.uniform(0.08, 0.12))
        flames.append(FlickerFlame(dz, H * scale, cx * scale, -0.45 * h0 * scale, level, freqs[k], amp, amp / 3,
                                   0.01, 0.03, float(rng.uniform(0, 2 * math.pi))))
    effects = FLAME_EFFECTS if noise is None else dataclasses.replace(
        FLAME_EFFECTS, full_well_e=float(noise[0]), read_noise_e=float(noise[1]),
        bit_depth=None if noise[2] is None else int(noise[2]))
    return FlameSequence(kind, tuple(flames), float(fps), n_frames, int(rng.integers(2**31)), effects)
