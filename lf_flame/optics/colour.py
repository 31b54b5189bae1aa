"""A colour sensor: Bayer CFA, channel sensitivities, Planck and soot spectra.

The camera's optics are achromatic ray transfer matrices, so the light of one colour channel
follows the same rays as any other; this module holds what is colour: the colour filter
array (:func:`cfa_channels`), each channel's spectral sensitivity and gain
(:class:`ColourSensor`) and the band integrals of a blackbody or of soot
(:func:`band_integrals`). The simulator renders with it
(:func:`lf_flame.simulate.colour.render_colour`), the pyrometer inverts it
(:mod:`lf_flame.temperature.pyrometry`).

Spectra
-------
Soot emits as a grey-ish body with emissivity ``eps(lambda) ∝ lambda^-alpha``; the value
``alpha = 1.39`` in the visible is Hottel & Broughton's (H. C. Hottel, F. P. Broughton,
"Determination of true temperature and total radiation from luminous gas flames",
Ind. Eng. Chem. Anal. Ed. 4 (1932) 166-175), the value two-colour pyrometry of soot uses
since. A texel's signal in channel ``c`` is

    s_c = g_c · soot · ∫ S_c(λ) (λ / λ0)^-alpha B(λ, T) dλ,

with ``S_c`` the channel's spectral sensitivity (colour-science's measured camera
sensitivities, kept in a cache file once read: :func:`library_sensor`), ``B`` Planck's law with the CIE's
constants (:func:`planck_radiance`, colour-science's ``planck_law``),
``g_c`` the camera's channel gain (unknown to the pyrometer: a calibration finds its
ratio) and ``λ0 = 550 nm``. A blackbody has ``alpha = 0`` and unit emissivity.
"""
from __future__ import annotations

import os
import zipfile
from dataclasses import dataclass
from pathlib import Path

import numpy as np


#: Hottel & Broughton (1932): soot emissivity ∝ λ^-1.39 in the visible.
ALPHA_SOOT = 1.39
#: reference wavelength (nm) of the emissivity's power law (it only scales the signal)
LAMBDA0_NM = 550.0
CHANNELS = ("R", "G", "B")
#: 2 x 2 tiles of the supported colour filter arrays, as channel letters, row-major
CFA_PATTERNS = {"RGGB": ("RG", "GB"), "BGGR": ("BG", "GR"), "GRBG": ("GR", "BG"), "GBRG": ("GB", "RG")}
#: the camera sensitivities colour-science ships (a Bayer camera first)
DEFAULT_SENSITIVITIES = "Nikon 5100 (NPL)"
#: wavelength step (nm) of the band integrals (sensitivities interpolated linearly onto it)
STEP_NM = 1.0


@dataclass(frozen=True)
class ColourSensor:
    """A colour sensor: its CFA and each channel's spectral sensitivity and gain.

    Attributes
    ----------
    name : str
        The sensitivities' name (colour-science's ``MSDS_CAMERA_SENSITIVITIES`` key, or any label).
    pattern : str
        A key of :data:`CFA_PATTERNS`, e.g. ``"RGGB"``: the channels of the 2 x 2 tile at
        ``phase``, row-major.
    phase : (int, int)
        Row and column (0 or 1) of the tile at which the sensor's pixel (0, 0) lies: pixel
        ``(i, j)`` has channel ``pattern[(i + phase[0]) % 2][(j + phase[1]) % 2]``.
    wavelengths_nm : ndarray of shape (L,)
        Increasing sample wavelengths, nm.
    sensitivities : ndarray of shape (L, 3)
        Relative sensitivity of channels R, G, B (columns) at each wavelength, >= 0.
    gains : (float, float, float)
        The camera's absolute gain of each channel (signal per band-integrated radiance).
    """

    name: str
    pattern: str
    phase: tuple
    wavelengths_nm: np.ndarray
    sensitivities: np.ndarray
    gains: tuple = (1.0, 1.0, 1.0)

    def __post_init__(self):
        if self.pattern not in CFA_PATTERNS:
            raise ValueError(f"unknown CFA pattern {self.pattern!r}; one of {sorted(CFA_PATTERNS)}")
        if tuple(self.phase) not in ((0, 0), (0, 1), (1, 0), (1, 1)):
            raise ValueError(f"CFA phase must be (row, col) with each 0 or 1. Received: {self.phase!r}")
        wl, s = np.asarray(self.wavelengths_nm, float), np.asarray(self.sensitivities, float)
        if wl.ndim != 1 or s.shape != (len(wl), 3) or np.any(np.diff(wl) <= 0):
            raise ValueError(f"wavelengths (L,) increasing and sensitivities (L, 3) are needed. Received: "
                             f"{wl.shape} and {s.shape}")
        if not np.all(np.isfinite(s)) or np.any(s < 0) or np.any(s.max(axis=0) <= 0):
            raise ValueError("sensitivities must be finite, >= 0, and each channel somewhere > 0")
        if len(self.gains) != 3 or not all(np.isfinite(g) and g > 0 for g in self.gains):
            raise ValueError(f"gains must be three positive numbers. Received: {self.gains!r}")

    def channel_map(self, shape) -> np.ndarray:
        """Channel index (0 R, 1 G, 2 B) of each pixel of a sensor of ``shape`` (rows, cols), int8."""
        return cfa_channels(shape, self.pattern, self.phase)

    def record(self) -> dict:
        """What a capture records of its sensor (``name``, ``pattern``, ``phase`` as a list; JSON-ready): the
        record that :func:`library_sensor` rebuilds it from."""
        return dict(name=self.name, pattern=self.pattern, phase=list(self.phase))


def cfa_channels(shape, pattern: str = "RGGB", phase=(0, 0)) -> np.ndarray:
    """Channel index (0 R, 1 G, 2 B) of each pixel under a 2 x 2 colour filter array.

    Parameters
    ----------
    shape : (int, int)
        Sensor rows and columns.
    pattern : str
        A key of :data:`CFA_PATTERNS` (row-major letters of the tile).
    phase : (int, int)
        Tile row and column of pixel (0, 0) (see :class:`ColourSensor`).

    Returns
    -------
    ndarray of shape ``shape``, int8.

    Raises
    ------
    ValueError
        Unknown pattern or a phase outside {0, 1}².
    """
    if pattern not in CFA_PATTERNS:
        raise ValueError(f"unknown CFA pattern {pattern!r}; one of {sorted(CFA_PATTERNS)}")
    if tuple(phase) not in ((0, 0), (0, 1), (1, 0), (1, 1)):
        raise ValueError(f"CFA phase must be (row, col) with each 0 or 1. Received: {phase!r}")
    tile = np.array([[CHANNELS.index(ch) for ch in row] for row in CFA_PATTERNS[pattern]], np.int8)
    i = (np.arange(shape[0]) + phase[0]) % 2
    j = (np.arange(shape[1]) + phase[1]) % 2
    return tile[i[:, None], j[None, :]]


def same_cfa_layout(pattern_a: str, phase_a, pattern_b: str, phase_b) -> bool:
    """Whether two colour filter arrays put the same channels on a sensor's pixels, however spelt (RGGB at
    phase (0, 1) is GRBG at (0, 0)): their channels on the first 2 x 2 pixels (:func:`cfa_channels`) agree."""
    return bool(np.array_equal(cfa_channels((2, 2), pattern_a, phase_a), cfa_channels((2, 2), pattern_b, phase_b)))


def library_sensor(name: str = DEFAULT_SENSITIVITIES, pattern: str = "RGGB", phase=(0, 0),
                   gains=(1.0, 1.0, 1.0)) -> ColourSensor:
    """A :class:`ColourSensor` with measured camera sensitivities from colour-science.

    ``name`` is a key of ``colour.MSDS_CAMERA_SENSITIVITIES`` (e.g. ``"Nikon 5100 (NPL)"``,
    ``"Sigma SDMerill (NPL)"``; 380-780 nm every 5 nm), its curves clipped at 0. Read once per
    colour-science version and kept in :func:`cache_dir` (:func:`library_curves`): a later process reads
    the small file instead of importing colour-science (over a second). Raises ValueError for another name.
    """
    wl, values = library_curves(name)
    return ColourSensor(name, pattern, tuple(phase), wl, values, tuple(float(g) for g in gains))


def cache_dir() -> Path:
    """Where lf_flame keeps what it derives from its libraries' data: ``$LF_FLAME_CACHE``, else
    ``$XDG_CACHE_HOME/lf_flame``, else ``~/.cache/lf_flame``."""
    if os.environ.get("LF_FLAME_CACHE"):
        return Path(os.environ["LF_FLAME_CACHE"])
    return Path(os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache") / "lf_flame"


def library_curves(name: str) -> tuple[np.ndarray, np.ndarray]:
    """colour-science's camera sensitivities ``name``: wavelengths ``(L,)`` (nm) and sensitivities ``(L, 3)``
    (R, G, B; clipped at 0).

    Read from the cache file of this name and colour-science version in :func:`cache_dir` where a process wrote it,
    else from colour-science and written there (a temporary file, then renamed; where it cannot be written, as
    read). A cache file that cannot be read is read again from colour-science and replaced.

    Raises
    ------
    ValueError
        ``name`` is not one of colour-science's camera sensitivities.
    """
    import hashlib
    from importlib.metadata import version
    key = hashlib.sha256(name.encode()).hexdigest()[:16]
    path = cache_dir() / f"camera_sensitivities_colour-{version('colour-science')}_{key}.npz"
    try:
        with np.load(path) as f:
            if str(f["name"]) == name:
                return f["wavelengths_nm"], f["sensitivities"]
    except (OSError, KeyError, ValueError, EOFError, zipfile.BadZipFile):
        pass
    import colour

    lib = colour.MSDS_CAMERA_SENSITIVITIES
    if name not in lib:
        raise ValueError(f"no camera sensitivities named {name!r}; colour-science has {sorted(lib.keys())}")
    m = lib[name]
    wl, values = np.asarray(m.wavelengths, float), np.clip(np.asarray(m.values, float), 0, None)
    tmp = path.with_name(f"{path.name}.{os.getpid()}.partial")
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        with open(tmp, "wb") as f:
            np.savez(f, name=name, wavelengths_nm=wl, sensitivities=values)
        os.replace(tmp, path)
    except OSError:
        tmp.unlink(missing_ok=True)
    return wl, values


#: The radiation constants of Planck's law as CIE 15:2004 rounds them (the values colour-science's ``planck_law``
#: uses): ``c1 = 2 pi h c^2`` (W m^2) and ``c2 = h c / k`` (m K).
PLANCK_C1, PLANCK_C2 = 3.741771e-16, 1.4388e-2


def planck_radiance(wavelengths_nm, temperature_k) -> np.ndarray:
    """Planck's spectral radiance of a blackbody in vacuum, ``B(λ, T) = (c1 / π) λ⁻⁵ / (exp(c2 / (λ T)) - 1)``,
    W sr⁻¹ m⁻² m⁻¹, with the CIE's constants (:data:`PLANCK_C1`, :data:`PLANCK_C2`; CIE 15:2004). colour-science's
    ``planck_law`` to rounding (``tests/test_temperature.py``), without importing colour-science (over a second).

    Parameters
    ----------
    wavelengths_nm : ndarray of shape (L,), nm
    temperature_k : float or ndarray of shape (...), K

    Returns
    -------
    ndarray of shape (..., L): every temperature at every wavelength.
    """
    wl = np.atleast_1d(np.asarray(wavelengths_nm, float)) * 1e-9
    t = np.asarray(temperature_k, float)[..., None]
    return PLANCK_C1 / np.pi * wl ** -5 / np.expm1(PLANCK_C2 / (wl * t))


def band_integrals(sensor: ColourSensor, temperature_k, alpha: float = ALPHA_SOOT, gains: bool = False,
                   chunk: int = 16384) -> np.ndarray:
    """Band-integrated emission ``∫ S_c(λ) (λ/λ0)^-alpha B(λ, T) dλ`` of each channel.

    The sensitivities are interpolated linearly onto a :data:`STEP_NM` grid over their
    range and integrated by the trapezoidal rule (its error against the closed form:
    ``tests/test_temperature.py``).

    Parameters
    ----------
    sensor : ColourSensor
    temperature_k : float or ndarray of shape (...), K
    alpha : float
        Emissivity exponent: :data:`ALPHA_SOOT` for soot, 0 for a blackbody.
    gains : bool
        Multiply by the sensor's channel gains (what its pixels record) or not (the model).
    chunk : int
        Temperatures evaluated at a time (memory: chunk x L floats).

    Returns
    -------
    ndarray of shape (..., 3): channels R, G, B; wavelength in m inside the integral, so
    W sr⁻¹ m⁻² times the sensitivities' units.

    Raises
    ------
    ValueError
        Non-finite or non-positive temperatures.
    """
    t = np.asarray(temperature_k, float)
    if not np.all(np.isfinite(t)) or np.any(t <= 0):
        raise ValueError("temperatures must be finite and > 0 K")
    wl0, wl1 = sensor.wavelengths_nm[0], sensor.wavelengths_nm[-1]
    wl = np.linspace(wl0, wl1, int(round((wl1 - wl0) / STEP_NM)) + 1)
    s = np.stack([np.interp(wl, sensor.wavelengths_nm, sensor.sensitivities[:, c]) for c in range(3)], axis=-1)
    dx = np.diff(wl) * 1e-9
    w = np.zeros(len(wl))
    w[:-1] += dx / 2
    w[1:] += dx / 2                                   # trapezoidal weights, m
    kernel = (w * (wl / LAMBDA0_NM) ** (-alpha))[:, None] * s            # (L, 3)
    flat = t.ravel()
    out = np.empty((flat.size, 3))
    for k in range(0, flat.size, chunk):
        out[k:k + chunk] = planck_radiance(wl, flat[k:k + chunk]) @ kernel
    out = out.reshape(t.shape + (3,))
    return out * np.asarray(sensor.gains) if gains else out


def mosaic(channel_images: np.ndarray, sensor: ColourSensor) -> np.ndarray:
    """One raw image from three full-resolution channel images (3, rows, cols): each pixel keeps
    its own channel's value (the CFA). Returns (rows, cols), the dtype of the input."""
    chan = sensor.channel_map(channel_images.shape[1:])
    return np.take_along_axis(channel_images, chan[None].astype(np.intp), axis=0)[0]


