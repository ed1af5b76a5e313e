"""Coordinate frames of the data space in which the OS-Map update is done.

Orientation in data space (paper, section 2.1): points are converted to the frame before training,
the map learns model vectors in frame coordinates (angles are periodic components of the engine),
and the model vectors are converted back to xyz for output and metrics.

- cartesian:   (x, y, z)
- cylindrical: (rho, phi, z) about an axis through a centre: rho the distance from the axis,
  z the height along it, phi the angle around it;
- spherical:   (r, theta, phi) about a centre: r the distance, theta the polar angle from the
  axis, phi the angle around the axis.
Angles are stored as arc lengths: multiplied by the mean radius (rho or r) of the data, so that a
step in every component is measured in length units and the winner search (Euclidean in frame
coordinates) stays close to the Euclidean distance in xyz. phi is periodic with period
2 pi * scale.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from osmap_cli.errors import OsmapError

FRAMES = ("cartesian", "cylindrical", "spherical")
COMPONENTS = {
    "cartesian": ("x", "y", "z"),
    "cylindrical": ("rho", "phi", "z"),
    "spherical": ("r", "theta", "phi"),
}
# accepted alternative spellings of component names
ALIASES = {"cylindrical": {"h": "z", "r": "rho"}, "spherical": {"rho": "r"}}


def parse_axis(text: str) -> np.ndarray:
    """'x', 'y', 'z' (optionally signed, '-z') or a vector 'a,b,c': a unit vector."""
    t = text.strip().lower()
    named = {"x": (1.0, 0.0, 0.0), "y": (0.0, 1.0, 0.0), "z": (0.0, 0.0, 1.0)}
    sign = 1.0
    if t[:1] in "+-" and t[1:] in named:
        sign, t = (-1.0 if t[0] == "-" else 1.0), t[1:]
    if t in named:
        return sign * np.array(named[t])
    try:
        v = np.array([float(s) for s in t.split(",")])
    except ValueError:
        v = np.zeros(0)
    if v.shape != (3,) or not np.all(np.isfinite(v)):
        raise OsmapError(f"--axis: expected x, y, z or a vector like 0,0,1, got {text!r}")
    n = np.linalg.norm(v)
    if n < 1e-12:
        raise OsmapError(f"--axis: the vector {text!r} has zero length")
    return v / n


def parse_center(text: str | None):
    """'x,y,z'; 'centroid' (the data centroid) or None / 'fit' (the fitted circle or sphere
    centre, see `fitted_center`), both decided at fit time."""
    if text is None or text.strip().lower() == "fit":
        return None
    if text.strip().lower() == "centroid":
        return "centroid"
    try:
        v = np.array([float(s) for s in text.split(",")])
    except ValueError:
        v = np.zeros(0)
    if v.shape != (3,) or not np.all(np.isfinite(v)):
        raise OsmapError(f"--center: expected 'fit', 'centroid' or x,y,z, got {text!r}")
    return v


def fitted_center(kind: str, points: np.ndarray, basis: np.ndarray, iterations: int = 200):
    """The centre of the circle (cylindrical: in the plane normal to the axis, through the
    centroid) or sphere (spherical) that best fits the points geometrically: argmin over c and R
    of sum (|p - c| - R)^2, by Spath's fixed point c = mean(p) - R mean(unit(p - c)). Unlike
    the centroid it does not move toward where the samples are denser: on a torus whose density
    varies 4x around the axis the centroid is 0.6 off the axis (30 % of the major radius), which
    makes rho vary around the big circle and the grid fail. Falls back to the centroid when the
    fit runs off (points on a nearly straight arc)."""
    c0 = points.mean(0)
    q = (points - c0) @ basis.T
    if kind == "cylindrical":
        q = q[:, :2]
    c = np.zeros(q.shape[1])
    mean_q = q.mean(0)
    for _ in range(iterations):
        d = q - c
        r = np.maximum(np.linalg.norm(d, axis=1), 1e-300)
        new = mean_q - r.mean() * (d / r[:, None]).mean(0)
        done = np.linalg.norm(new - c) <= 1e-12 * (1.0 + r.mean())
        c = new
        if done:
            break
    extent = float(np.max(np.ptp(q, axis=0)))
    if not np.all(np.isfinite(c)) or np.linalg.norm(c) > 0.5 * extent:
        return c0
    full = np.zeros(3)
    full[:len(c)] = c
    return c0 + full @ basis


def _basis(axis: np.ndarray) -> np.ndarray:
    """Rows e1, e2, axis: an orthonormal right-handed basis with the given third vector."""
    a = axis / np.linalg.norm(axis)
    helper = np.array([1.0, 0.0, 0.0]) if abs(a[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    e1 = helper - a * (helper @ a)
    e1 /= np.linalg.norm(e1)
    e2 = np.cross(a, e1)
    return np.stack([e1, e2, a])


@dataclass
class Frame:
    """A fitted coordinate frame: kind, centre, basis (rows e1, e2, axis) and angle scale."""

    kind: str = "cartesian"
    center: np.ndarray | None = None
    basis: np.ndarray | None = None
    scale: float = 1.0

    @classmethod
    def fit(cls, kind: str, points: np.ndarray, axis=None, center=None) -> Frame:
        """The frame for these points: centre defaults to the fitted circle or sphere centre
        (`fitted_center`; center="centroid" for their centroid), the angle scale is their mean
        distance from the axis (cylindrical) or the centre (spherical)."""
        if kind not in FRAMES:
            raise OsmapError(f"--frame: unknown frame {kind!r} (choose from {', '.join(FRAMES)})")
        if kind == "cartesian":
            return cls("cartesian")
        axis = np.array([0.0, 0.0, 1.0]) if axis is None else np.asarray(axis, np.float64)
        basis = _basis(axis)
        if center is None:
            c = fitted_center(kind, points, basis)
        elif isinstance(center, str):  # "centroid"
            c = points.mean(0)
        else:
            c = np.asarray(center, np.float64)
        frame = cls(kind, c, basis, 1.0)
        local = (points - c) @ frame.basis.T
        if kind == "cylindrical":
            radius = np.hypot(local[:, 0], local[:, 1])
        else:
            radius = np.linalg.norm(local, axis=1)
        scale = float(np.mean(radius))
        if not np.isfinite(scale) or scale <= 1e-9 * (1.0 + float(np.abs(points).max())):
            raise OsmapError(f"--frame {kind}: the points lie on the axis / at the centre, "
                             "so their angles are undefined")
        frame.scale = scale
        return frame

    @property
    def names(self) -> tuple[str, str, str]:
        return COMPONENTS[self.kind]

    @property
    def periods(self) -> np.ndarray:
        """Period per frame component (0 = none): phi wraps at 2 pi * scale."""
        out = np.zeros(3)
        if self.kind != "cartesian":
            out[self.names.index("phi")] = 2.0 * np.pi * self.scale
        return out

    def to_frame(self, p: np.ndarray) -> np.ndarray:
        p = np.asarray(p, np.float64)
        if self.kind == "cartesian":
            return p.copy()
        local = (p - self.center) @ self.basis.T
        phi = np.mod(np.arctan2(local[:, 1], local[:, 0]), 2.0 * np.pi) * self.scale
        rho = np.hypot(local[:, 0], local[:, 1])
        if self.kind == "cylindrical":
            return np.stack([rho, phi, local[:, 2]], 1)
        r = np.linalg.norm(local, axis=1)
        theta = np.arctan2(rho, local[:, 2]) * self.scale
        return np.stack([r, theta, phi], 1)

    def from_frame(self, q: np.ndarray) -> np.ndarray:
        q = np.asarray(q, np.float64)
        if self.kind == "cartesian":
            return q.copy()
        if self.kind == "cylindrical":
            rho, phi, z = q[:, 0], q[:, 1] / self.scale, q[:, 2]
            local = np.stack([rho * np.cos(phi), rho * np.sin(phi), z], 1)
        else:
            r, theta, phi = q[:, 0], q[:, 1] / self.scale, q[:, 2] / self.scale
            local = np.stack([r * np.sin(theta) * np.cos(phi), r * np.sin(theta) * np.sin(phi),
                              r * np.cos(theta)], 1)
        return local @ self.basis + self.center

    def component_index(self, name: str) -> int:
        """Index of a component by name (aliases accepted), or an OsmapError for --vary."""
        key = name.strip().lower()
        key = ALIASES.get(self.kind, {}).get(key, key)
        if key not in self.names:
            raise OsmapError(f"--vary: {name!r} is not a component of the {self.kind} frame "
                             f"(its components are {', '.join(self.names)})")
        return self.names.index(key)

    def describe(self) -> str:
        if self.kind == "cartesian":
            return "cartesian"
        c = ",".join(f"{v:.4g}" for v in self.center)
        a = ",".join(f"{v:.4g}" for v in self.basis[2])
        return f"{self.kind} (centre {c}, axis {a}, angle scale {self.scale:.4g})"
