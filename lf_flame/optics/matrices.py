"""Ray transfer matrices (ABCD) of paraxial optics.

A ray in one transverse axis is the column vector ``(y, theta)``: height ``y`` in mm
and angle ``theta`` in radians to the optical axis. An element maps it by
``(y2, theta2) = M @ (y1, theta1)`` with ``M = [[A, B], [C, D]]`` (the paper's Eq. 3).
The x and y axes of a rotationally symmetric system are separable, so one 2×2
matrix serves both.

Source: the paper's Eqs. 3–5; E. Hecht, *Optics*, 5th ed., §6.2; Kogelnik & Li,
"Laser beams and resonators", Appl. Opt. 5, 1550 (1966).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

DET_TOL = 1e-12


def _finite(name: str, value: float) -> float:
    value = float(value)
    if not math.isfinite(value):
        raise ValueError(f"{name} must be finite. Received: {name}={value!r}")
    return value


@dataclass(frozen=True)
class RayTransferMatrix:
    """An immutable 2×2 ray transfer matrix ``[[A, B], [C, D]]``.

    Units: B in mm, C in 1/mm, A and D dimensionless. Elements compose with ``@``
    in the order light meets them from right to left: ``lens @ space`` first
    propagates through ``space``, then through ``lens``.

    Raises
    ------
    ValueError
        If an entry is not finite, or if ``check_det`` is true and the determinant
        differs from 1 by more than 1e-12 (an element between two equal media
        preserves étendue, so ``AD - BC = 1``).
    """

    A: float
    B: float
    C: float
    D: float
    check_det: bool = True

    def __post_init__(self):
        for name in "ABCD":
            _finite(name, getattr(self, name))
        if self.check_det and abs(self.det - 1.0) > DET_TOL * max(1.0, abs(self.A * self.D)):
            raise ValueError(
                f"ray transfer matrix in one medium must have determinant 1. "
                f"Received: det={self.det!r} for {self}"
            )

    @property
    def det(self) -> float:
        """Determinant ``AD - BC`` (1 for any element in one medium)."""
        return self.A * self.D - self.B * self.C

    @property
    def matrix(self) -> np.ndarray:
        """The matrix as a float64 array of shape (2, 2)."""
        return np.array([[self.A, self.B], [self.C, self.D]], dtype=np.float64)

    def __matmul__(self, other: "RayTransferMatrix") -> "RayTransferMatrix":
        if not isinstance(other, RayTransferMatrix):
            return NotImplemented
        return RayTransferMatrix(
            self.A * other.A + self.B * other.C,
            self.A * other.B + self.B * other.D,
            self.C * other.A + self.D * other.C,
            self.C * other.B + self.D * other.D,
            check_det=self.check_det and other.check_det,
        )

    def inverse(self) -> "RayTransferMatrix":
        """The matrix that traces rays backwards through the same element."""
        det = self.det
        return RayTransferMatrix(self.D / det, -self.B / det, -self.C / det, self.A / det,
                                 check_det=self.check_det)

    def apply(self, y, theta):
        """Trace rays: ``y`` (mm) and ``theta`` (rad), arrays of any equal shape.

        Returns
        -------
        (y2, theta2) : tuple of ndarray
            Heights (mm) and angles (rad) after the element, same shape as input.
        """
        y = np.asarray(y, dtype=np.float64)
        theta = np.asarray(theta, dtype=np.float64)
        return self.A * y + self.B * theta, self.C * y + self.D * theta


def free_space(distance_mm: float) -> RayTransferMatrix:
    """Propagation over ``distance_mm`` in one medium: ``[[1, d], [0, 1]]`` (paper Eq. 4).

    A negative distance traces backwards.

    Raises
    ------
    ValueError
        If the distance is not finite.
    """
    return RayTransferMatrix(1.0, _finite("distance_mm", distance_mm), 0.0, 1.0)


def thin_lens(focal_length_mm: float) -> RayTransferMatrix:
    """Thin lens of focal length ``f``: ``[[1, 0], [-1/f, 1]]`` (paper Eq. 5).

    Raises
    ------
    ValueError
        If the focal length is zero or not finite.
    """
    f = _finite("focal_length_mm", focal_length_mm)
    if f == 0.0:
        raise ValueError("thin lens focal length must be non-zero. Received: focal_length_mm=0")
    return RayTransferMatrix(1.0, 0.0, -1.0 / f, 1.0)


@dataclass(frozen=True)
class ApertureStop:
    """A circular aperture stop (clear diameter ``diameter_mm``), centred on the axis.

    It passes rays unchanged (its ray transfer matrix is the identity) and blocks
    those outside the clear aperture: the aperture function A(u, v) of the paper's
    Eq. 1. A ray exactly on the rim passes (``y² + x² <= r²``).

    Raises
    ------
    ValueError
        If the diameter is not finite and positive.
    """

    diameter_mm: float

    def __post_init__(self):
        v = _finite("diameter_mm", self.diameter_mm)
        if v <= 0:
            raise ValueError(f"aperture stop diameter must be > 0 (mm). Received: diameter_mm={v!r}")

    @property
    def matrix(self) -> RayTransferMatrix:
        """Identity: a stop changes no ray, it only removes some."""
        return RayTransferMatrix(1.0, 0.0, 0.0, 1.0)

    def passes(self, y_mm, x_mm) -> np.ndarray:
        """True where rays at ``(y, x)`` mm on the stop's plane pass (arrays, any equal shape)."""
        r = self.diameter_mm / 2
        return np.asarray(y_mm) ** 2 + np.asarray(x_mm) ** 2 <= r * r


@dataclass(frozen=True)
class MicrolensArray:
    """A square grid of identical thin lenslets, each acting about its own centre.

    Lenslet ``(r, c)`` has its optical axis at ``y_c = (r + 1/2 - R/2) * pitch``,
    ``x_c = (C/2 - c - 1/2) * pitch``: the sensor is read out rotated by 180°,
    so that the main lens's inverted image of the scene appears upright. A ray at height ``y``
    on lenslet ``r`` leaves with ``theta - (y - y_c) / f``: a thin lens in the
    lenslet's own frame (an affine map of the ray, not a single 2×2 matrix).

    Parameters
    ----------
    pitch_mm : float
        Centre-to-centre spacing (mm), > 0.
    focal_length_mm : float
        Lenslet focal length (mm), > 0.
    n_rows, n_cols : int
        Number of lenslets, >= 1.

    Raises
    ------
    ValueError
        If a pitch, focal length or count is not positive.
    """

    pitch_mm: float
    focal_length_mm: float
    n_rows: int
    n_cols: int

    def __post_init__(self):
        for name in ("pitch_mm", "focal_length_mm"):
            v = _finite(name, getattr(self, name))
            if v <= 0:
                raise ValueError(f"microlens array {name} must be > 0. Received: {name}={v!r}")
        for name in ("n_rows", "n_cols"):
            v = getattr(self, name)
            if int(v) != v or v < 1:
                raise ValueError(f"microlens array {name} must be a positive integer. Received: {name}={v!r}")

    @property
    def lens(self) -> RayTransferMatrix:
        """The thin-lens matrix of one lenslet, in its own frame."""
        return thin_lens(self.focal_length_mm)

    def lenslet_index(self, y_mm, x_mm):
        """Lenslet row and column hit by rays at ``(y, x)`` mm on the array plane.

        A ray exactly on a border between two lenslets belongs to the lenslet of
        higher row (higher ``y``) and lower column (higher ``x``): ``floor`` of the
        grid coordinate, the rule the tracing kernel uses for pixels too.
        Rays outside the array get indices outside ``[0, n)``.

        Returns
        -------
        (row, col) : tuple of int ndarray, shape of the input.
        """
        row = np.floor(np.asarray(y_mm) / self.pitch_mm + self.n_rows / 2).astype(np.int64)
        col = np.floor(self.n_cols / 2 - np.asarray(x_mm) / self.pitch_mm).astype(np.int64)
        return row, col

    def centre(self, row, col):
        """Optical-axis position ``(y_c, x_c)`` in mm of lenslets ``(row, col)``."""
        row = np.asarray(row, dtype=np.float64)
        col = np.asarray(col, dtype=np.float64)
        return (row + 0.5 - self.n_rows / 2) * self.pitch_mm, (self.n_cols / 2 - col - 0.5) * self.pitch_mm

    def apply(self, y_mm, theta_y, x_mm, theta_x):
        """Refract rays at the array plane through the lenslet each one hits.

        Returns
        -------
        (theta_y2, theta_x2) : angles (rad) after the array; heights are unchanged.
        """
        row, col = self.lenslet_index(y_mm, x_mm)
        yc, xc = self.centre(row, col)
        f = self.focal_length_mm
        return np.asarray(theta_y) - (np.asarray(y_mm) - yc) / f, np.asarray(theta_x) - (np.asarray(x_mm) - xc) / f
