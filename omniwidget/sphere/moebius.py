"""Möbius transformations of the sphere as 2 x 2 complex matrices.

A Möbius transformation ``z -> (a z + b) / (c z + d)`` of the extended complex plane
becomes, through the stereographic projection of :mod:`omniwidget.sphere.coords`, a
conformal bijection of the sphere. Here it is the matrix ``[[a, b], [c, d]]`` acting on
homogeneous coordinates ``[u : v]``, normalised to determinant 1: the projection pole,
``z = 0`` and ``z = ∞`` are ordinary points and nothing is ever divided by ``c z + d``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import ArrayLike, NDArray

from . import coords

__all__ = ["Moebius", "frame_rotation"]

#: Two points whose chordal distance is below this are treated as the same point.
COINCIDENT = 1e-9


def _as_matrix(matrix: ArrayLike) -> NDArray[np.complex128]:
    m = np.array(matrix, dtype=np.complex128)
    if m.shape != (2, 2) or not np.all(np.isfinite(m)):
        raise ValueError(f"a Möbius matrix must be a finite 2 x 2 complex array, got {m!r}")
    det = m[0, 0] * m[1, 1] - m[0, 1] * m[1, 0]
    norm = float(np.sum(np.abs(m) ** 2))
    if not abs(det) > 1e-14 * norm:
        raise ValueError("a Möbius matrix must be invertible (ad - bc != 0)")
    m /= np.sqrt(det)
    m.setflags(write=False)
    return m


def frame_rotation(lonlat: ArrayLike) -> NDArray[np.float64]:
    """The rotation taking ``lonlat`` to the south pole (``z = 0``), east to ``+x``, north to ``-y``.

    In the stereographic chart at ``z = 0`` the image's east is then the real axis and
    north the negative imaginary axis (the chart is seen from inside the sphere).
    """
    p = coords.lonlat_to_xyz(lonlat)
    east, north = coords.local_frame(lonlat)
    return np.stack([east, -north, -p])


def _chordal_separation(p: NDArray[np.float64]) -> float:
    return float(min(np.linalg.norm(p[i] - p[j]) for i, j in ((0, 1), (0, 2), (1, 2))))


def _to_zero_one_infinity(p: NDArray[np.float64]) -> NDArray[np.complex128]:
    """The matrix sending homogeneous points ``p[0], p[1], p[2]`` to ``0, 1, ∞`` (cross-ratio)."""
    u, v = coords.xyz_to_homogeneous(p)
    (u1, u2, u3), (v1, v2, v3) = u, v
    s1 = v3 * u2 - u3 * v2  # row 1 vanishes at p1, row 2 at p3; both equal at p2
    s3 = v1 * u2 - u1 * v2
    return np.array([[s1 * v1, -s1 * u1], [s3 * v3, -s3 * u3]], dtype=np.complex128)


@dataclass(frozen=True, eq=False)
class Moebius:
    """A Möbius transformation of the sphere.

    Parameters
    ----------
    matrix : array_like, shape (2, 2), complex
        ``[[a, b], [c, d]]`` with ``ad - bc != 0``; stored normalised to determinant 1.

    Notes
    -----
    ``M(p)`` takes and returns ``[lon, lat]`` in degrees; :meth:`apply_xyz` works on unit
    vectors. Composition follows function composition: ``(A @ B)(p) == A(B(p))``.

    Examples
    --------
    >>> m = Moebius.from_points([[0, 0], [10, 0], [20, 0]], [[0, 0], [10, 5], [20, 0]])
    >>> np.round(m([[10, 0]]), 9)
    array([[10.,  5.]])
    """

    matrix: NDArray[np.complex128] = field(repr=False)

    def __post_init__(self) -> None:
        object.__setattr__(self, "matrix", _as_matrix(self.matrix))

    def __repr__(self) -> str:
        (a, b), (c, d) = np.round(self.matrix, 6)
        return f"Moebius(a={a}, b={b}, c={c}, d={d})"

    # --- constructors -------------------------------------------------------------
    @classmethod
    def identity(cls) -> Moebius:
        """The identity map."""
        return cls(np.eye(2, dtype=np.complex128))

    @classmethod
    def from_points(cls, src: ArrayLike, dst: ArrayLike) -> Moebius:
        """The unique map sending three points to three points (Theorem 1).

        Parameters
        ----------
        src, dst : array_like, shape (3, 2)
            ``[lon, lat]`` in degrees; the three points of each must be distinct.

        Raises
        ------
        ValueError
            If two of the points in ``src`` or in ``dst`` coincide.
        """
        return cls.from_points_xyz(coords.lonlat_to_xyz(src), coords.lonlat_to_xyz(dst))

    @classmethod
    def from_points_xyz(cls, src: ArrayLike, dst: ArrayLike) -> Moebius:
        """:meth:`from_points` for unit vectors, shape (3, 3)."""
        src = np.asarray(src, dtype=np.float64)
        dst = np.asarray(dst, dtype=np.float64)
        if src.shape != (3, 3) or dst.shape != (3, 3):
            raise ValueError(f"need three points and three targets, got shapes {src.shape} and {dst.shape}")
        for name, pts in (("source", src), ("target", dst)):
            if not np.all(np.isfinite(pts)):
                raise ValueError(f"the {name} points must be finite")
            if _chordal_separation(pts) < COINCIDENT:
                raise ValueError(f"two of the three {name} points coincide")
        h_src = _to_zero_one_infinity(src)
        h_dst = _to_zero_one_infinity(dst)
        adj_dst = np.array([[h_dst[1, 1], -h_dst[0, 1]], [-h_dst[1, 0], h_dst[0, 0]]])
        return cls(adj_dst @ h_src)

    @classmethod
    def from_rotation(cls, rotation: ArrayLike) -> Moebius:
        """The Möbius map of a rotation of the sphere.

        Parameters
        ----------
        rotation : array_like, shape (3, 3)
            A proper rotation matrix acting on unit vectors (``R @ xyz``).
        """
        r = np.asarray(rotation, dtype=np.float64)
        if r.shape != (3, 3) or not np.allclose(r @ r.T, np.eye(3), atol=1e-9) or np.linalg.det(r) < 0:
            raise ValueError("expected a proper 3 x 3 rotation matrix")
        basis = np.eye(3)
        return cls.from_points_xyz(basis, (r @ basis).T)

    @classmethod
    def levelling(cls, up: ArrayLike) -> Moebius:
        """The rotation that turns ``up`` to the zenith by the shortest turn (about ``up × z``): the yaw is kept.

        Parameters
        ----------
        up : array_like, shape (2,)
            ``[lon, lat]`` in degrees where a panorama sees the true vertical, north of the equator.

        Raises
        ------
        ValueError
            If ``up`` is not north of the equator (a turn of 90° or more is no levelling).
        """
        u = coords.lonlat_to_xyz(np.asarray(up, dtype=np.float64))
        if u.shape != (3,) or not u[2] > 1e-12:
            raise ValueError(f"up must be a [lon, lat] north of the equator, got {up!r}")
        axis = np.array([u[1], -u[0], 0.0])  # u x z
        s, c = float(np.linalg.norm(axis)), float(u[2])
        if s < 1e-15:
            return cls.identity()
        k = axis / s
        kx = np.array([[0.0, -k[2], k[1]], [k[2], 0.0, -k[0]], [-k[1], k[0], 0.0]])
        return cls.from_rotation(np.eye(3) + s * kx + (1.0 - c) * (kx @ kx))

    @classmethod
    def rotation(cls, axis: ArrayLike, angle: float) -> Moebius:
        """Rotation of the sphere by ``angle`` degrees about the direction ``axis`` ``[lon, lat]``.

        The rotation is counter-clockwise seen from outside the sphere at ``axis``, that is
        counter-clockwise as seen in the image around ``axis``.
        """
        n = coords.lonlat_to_xyz(axis)
        theta = math.radians(angle)
        k = np.array([[0, -n[2], n[1]], [n[2], 0, -n[0]], [-n[1], n[0], 0]])
        r = np.eye(3) + math.sin(theta) * k + (1 - math.cos(theta)) * (k @ k)
        return cls.from_rotation(r)

    @classmethod
    def point_map(cls, position: ArrayLike, target: ArrayLike, scale: float = 1.0, rotation: float = 0.0) -> Moebius:
        """The map of a point handle (Sec. 3.3), built exactly rather than from three points.

        It sends ``position`` to ``target`` and the antipode of ``position`` to the antipode of
        ``target``; at ``target`` it magnifies by ``scale`` and turns by ``rotation`` degrees
        counter-clockwise, both relative to the image's east and north directions at the two
        points. With ``scale=1, rotation=0`` it is a rotation of the sphere that looks like a
        pure shift in the image.

        Parameters
        ----------
        position, target : array_like, shape (2,)
            ``[lon, lat]`` in degrees.
        scale : float
            Magnification at ``target``, ``> 0`` (``> 1`` zooms in).
        rotation : float
            Degrees, counter-clockwise as seen in the image.
        """
        if not (math.isfinite(scale) and scale > 0):
            raise ValueError(f"scale must be a positive finite number, got {scale}")
        if not math.isfinite(rotation):
            raise ValueError(f"rotation must be finite, got {rotation}")
        k = scale * complex(math.cos(math.radians(rotation)), -math.sin(math.radians(rotation)))
        root = np.sqrt(complex(k))
        stretch = cls(np.array([[root, 0], [0, 1 / root]]))
        return cls.from_rotation(frame_rotation(target).T) @ stretch @ cls.from_rotation(frame_rotation(position))

    @classmethod
    def translation(cls, src: ArrayLike, dst: ArrayLike) -> Moebius:
        """The rotation of the sphere that moves ``src`` to ``dst`` and looks like a shift in the image.

        East and north at ``src`` go to east and north at ``dst``
        (``point_map(src, dst)`` with unit scale and no turn).
        """
        return cls.point_map(src, dst)

    @classmethod
    def zoom(cls, center: ArrayLike, scale: float, rotation: float = 0.0) -> Moebius:
        """Spherical zoom (Fig. 11): fixes ``center`` and its antipode, magnifies by ``scale`` at ``center``.

        ``rotation`` additionally turns the neighbourhood of ``center`` counter-clockwise (degrees).
        """
        return cls.point_map(center, center, scale, rotation)

    def as_dict(self) -> dict[str, list[float]]:
        """The matrix normalised to determinant 1 as JSON-ready ``{"a": [re, im], "b": ..., "c": ..., "d": ...}`` (the editor's form)."""
        m = self.matrix / np.sqrt(np.linalg.det(self.matrix))
        return {k: [float(v.real), float(v.imag)] for k, v in zip("abcd", m.ravel(), strict=True)}

    # --- algebra -------------------------------------------------------------------
    def __matmul__(self, other: Moebius) -> Moebius:
        if not isinstance(other, Moebius):
            return NotImplemented
        return Moebius(self.matrix @ other.matrix)

    @property
    def inverse(self) -> Moebius:
        """The inverse map."""
        (a, b), (c, d) = self.matrix
        return Moebius(np.array([[d, -b], [-c, a]]))

    def power(self, t: float) -> Moebius:
        """The map ``t`` of the way from the identity to this one: ``exp(t log M)``, on the one-parameter group through it.

        ``power(0)`` is the identity, ``power(1)`` the map itself, ``power(0.5)`` applied twice is
        the map. The matrix (determinant 1) is taken with a trace of non-negative real part (``M``
        and ``-M`` are the same map) and its eigenvalue ``λ`` of principal logarithm, so that
        the path is the shortest: ``M^t = (λ^t - λ^-t) / (λ - λ^-1) M + (λ^(1-t) - λ^(t-1)) / (λ - λ^-1) I``
        (Sylvester), ``t M + (1 - t) I`` for a parabolic map (``λ = 1``).

        Parameters
        ----------
        t : float
            Any real number (negative goes the other way).

        Returns
        -------
        Moebius
        """
        m = self.matrix if (self.matrix[0, 0] + self.matrix[1, 1]).real >= 0 else -self.matrix
        trace = m[0, 0] + m[1, 1]
        lam = (trace + np.sqrt(trace * trace - 4)) / 2
        if abs(lam) < 1:  # the other eigenvalue, so that |λ| >= 1 (either gives the same path)
            lam = 1 / lam
        gap = lam - 1 / lam
        if abs(gap) < 1e-9:  # parabolic, or the identity
            return Moebius(t * m + (1 - t) * np.eye(2))
        up, down = np.exp(t * np.log(lam)), np.exp(-t * np.log(lam))
        return Moebius((up - down) / gap * m + (lam * down - up / lam) / gap * np.eye(2))

    def is_identity(self, tol: float = 1e-12) -> bool:
        """Whether the map is the identity within ``tol`` (on the normalised matrix)."""
        m = self.matrix
        return bool(min(np.abs(m - np.eye(2)).max(), np.abs(m + np.eye(2)).max()) <= tol)

    def isclose(self, other: Moebius, tol: float = 1e-9) -> bool:
        """Whether two maps are the same map within ``tol`` (matrices up to sign)."""
        diff = min(np.abs(self.matrix - other.matrix).max(), np.abs(self.matrix + other.matrix).max())
        return bool(diff <= tol)

    # --- application --------------------------------------------------------------
    def apply_homogeneous(self, u: ArrayLike, v: ArrayLike) -> tuple[NDArray[np.complex128], NDArray[np.complex128]]:
        """Apply to homogeneous coordinates: ``[u : v] -> [a u + b v : c u + d v]``."""
        (a, b), (c, d) = self.matrix
        u = np.asarray(u)
        v = np.asarray(v)
        return a * u + b * v, c * u + d * v

    def apply_xyz(self, xyz: ArrayLike) -> NDArray[np.float64]:
        """Apply to unit vectors, shape (..., 3); returns unit vectors of the same shape."""
        return coords.homogeneous_to_xyz(*self.apply_homogeneous(*coords.xyz_to_homogeneous(xyz)))

    def __call__(self, lonlat: ArrayLike) -> NDArray[np.float64]:
        """Apply to ``[lon, lat]`` positions in degrees, shape (..., 2)."""
        return coords.xyz_to_lonlat(self.apply_xyz(coords.lonlat_to_xyz(lonlat)))

    def local_scale_rotation(self, lonlat: ArrayLike) -> tuple[float, float]:
        """Magnification and turn of the map at ``lonlat`` (one ``[lon, lat]``).

        Returns
        -------
        scale : float
            Ratio of lengths on the sphere, image of a small step over the step.
        rotation : float
            Degrees, counter-clockwise relative to east/north at ``lonlat`` and at its image.
        """
        image = self(np.asarray(lonlat, dtype=np.float64))
        n = Moebius.from_rotation(frame_rotation(image)) @ self @ Moebius.from_rotation(frame_rotation(lonlat).T)
        (a, _), (_, d) = n.matrix  # n fixes z = 0 (b = 0): its derivative there is a / d
        k = complex(a / d)
        return abs(k), -math.degrees(math.atan2(k.imag, k.real))
