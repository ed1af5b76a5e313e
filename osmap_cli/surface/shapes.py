"""Built-in analytic surfaces: sampling uniformly by area, and their own parameterisations.

Each shape knows how to
- draw n points uniformly by area (`sample`),
- project any point (e.g. a map node) to its parameter space (`params`; columns may be periodic,
  see `periods`),
- measure the surface (geodesic) distance between two projected points (`surface_distance`: exact
  for the developable roll and cylinder and for the sphere, the length of the parameter-space
  straight segment for the torus, an upper bound that is tight for short edges),
- measure the distance from a point to the surface (`distance`).
These are what the quality metrics use (see metrics.py), and the recommended OS-Map settings that
make each shape learn a clean grid (`recommended`).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

TWO_PI = 2.0 * np.pi


def _wrap(a: np.ndarray, period: float) -> np.ndarray:
    """a reduced to [-period/2, period/2)."""
    return a - period * np.floor(a / period + 0.5)


@dataclass
class Recommended:
    """Settings that learn a fold-free grid on the shape (used when the user gives none)."""

    wrap: str = "none"
    frame: str = "cartesian"
    axis: str = "z"
    vary: str = ""
    anisotropy: float = 0.0


@dataclass
class Shape:
    """Base class: subclasses fill in the geometry."""

    name: str = "shape"
    recommended: Recommended = field(default_factory=Recommended)

    #: period of each parameter column (0 = not periodic)
    periods: tuple[float, float] = (0.0, 0.0)
    param_names: tuple[str, str] = ("a", "b")

    @property
    def area(self) -> float:
        raise NotImplementedError

    def sample(self, n: int, rng: np.random.Generator) -> np.ndarray:
        raise NotImplementedError

    def params(self, p: np.ndarray) -> np.ndarray:
        raise NotImplementedError

    def surface_distance(self, a: np.ndarray, b: np.ndarray) -> np.ndarray:
        raise NotImplementedError

    def distance(self, p: np.ndarray) -> np.ndarray:
        raise NotImplementedError

    def describe(self) -> str:
        return self.name


# ----------------------------------------------------------------------------------------- roll
def _spiral_arclength(t: np.ndarray) -> np.ndarray:
    """Arc length of (t cos t, t sin t) from 0 to t."""
    t = np.asarray(t, np.float64)
    return 0.5 * (t * np.sqrt(1.0 + t * t) + np.arcsinh(t))


@dataclass
class Roll(Shape):
    """Archimedean roll x = t cos t, y = t sin t, t in [t0, t0 + 2 pi turns], z in [0, height]."""

    turns: float = 1.0
    height: float = 14.0
    t0: float = 1.5 * np.pi
    name: str = "roll"
    param_names: tuple[str, str] = ("s", "h")
    recommended: Recommended = field(default_factory=lambda: Recommended(
        wrap="none", frame="cartesian", vary="x=u,y=u,z=v", anisotropy=0.0))

    @property
    def t1(self) -> float:
        return self.t0 + TWO_PI * self.turns

    @property
    def area(self) -> float:
        return float((_spiral_arclength(self.t1) - _spiral_arclength(self.t0)) * self.height)

    def describe(self) -> str:
        return f"roll ({self.turns:g} turns, height {self.height:g})"

    def _t_of_s(self, s: np.ndarray) -> np.ndarray:
        """Invert the arc length by Newton's method (ds/dt = sqrt(1 + t^2))."""
        t = np.sqrt(np.maximum(2.0 * s, 0.0))  # s ~ t^2 / 2
        t = np.clip(t, self.t0, self.t1)
        for _ in range(30):
            t = t - (_spiral_arclength(t) - s) / np.sqrt(1.0 + t * t)
        return t

    def sample(self, n, rng):
        s0, s1 = _spiral_arclength(self.t0), _spiral_arclength(self.t1)
        t = self._t_of_s(rng.uniform(s0, s1, n))
        z = rng.uniform(0.0, self.height, n)
        return np.stack([t * np.cos(t), t * np.sin(t), z], 1)

    def _nearest_t(self, p: np.ndarray) -> np.ndarray:
        """Parameter t in [t0, t1] of the spiral point nearest to each (x, y)."""
        x, y = p[:, 0], p[:, 1]
        alpha = np.arctan2(y, x)
        kmin = int(np.floor((self.t0 - np.pi) / TWO_PI)) - 1
        kmax = int(np.ceil((self.t1 + np.pi) / TWO_PI)) + 1
        best_t = np.full(len(p), self.t0)
        best_d = np.full(len(p), np.inf)
        for k in range(kmin, kmax + 1):
            t = np.clip(alpha + TWO_PI * k, self.t0, self.t1)
            for _ in range(8):  # Newton on f(t) = (c(t) - p) . c'(t)
                c, s = np.cos(t), np.sin(t)
                cx, cy = t * c - x, t * s - y
                dx, dy = c - t * s, s + t * c
                ddx, ddy = -2 * s - t * c, 2 * c - t * s
                f = cx * dx + cy * dy
                fp = dx * dx + dy * dy + cx * ddx + cy * ddy
                step = np.where(fp > 1e-9, f / np.where(fp > 1e-9, fp, 1.0), 0.0)
                t = np.clip(t - np.clip(step, -0.5, 0.5), self.t0, self.t1)
            d = np.hypot(t * np.cos(t) - x, t * np.sin(t) - y)
            better = d < best_d
            best_d = np.where(better, d, best_d)
            best_t = np.where(better, t, best_t)
        return best_t

    def params(self, p):
        p = np.asarray(p, np.float64)
        t = self._nearest_t(p)
        return np.stack([_spiral_arclength(t), np.clip(p[:, 2], 0.0, self.height)], 1)

    def surface_distance(self, a, b):
        # developable: the unrolled surface is a rectangle in (s, h), where geodesics are straight
        return np.hypot(a[:, 0] - b[:, 0], a[:, 1] - b[:, 1])

    def distance(self, p):
        p = np.asarray(p, np.float64)
        t = self._nearest_t(p)
        z = np.clip(p[:, 2], 0.0, self.height)
        q = np.stack([t * np.cos(t), t * np.sin(t), z], 1)
        return np.linalg.norm(p - q, axis=1)


# ---------------------------------------------------------------------------------------- torus
@dataclass
class Torus(Shape):
    """Torus about the z axis: major radius R (centre of the tube), minor radius r (tube)."""

    major_radius: float = 2.0
    minor_radius: float = 0.7
    name: str = "torus"
    periods: tuple[float, float] = (TWO_PI, TWO_PI)
    param_names: tuple[str, str] = ("phi", "theta")
    recommended: Recommended = field(default_factory=lambda: Recommended(
        wrap="uv", frame="cylindrical", axis="z", vary="rho=v,z=v,phi=u", anisotropy=0.0))

    @property
    def area(self) -> float:
        return float(4.0 * np.pi ** 2 * self.major_radius * self.minor_radius)

    def describe(self) -> str:
        return f"torus (R {self.major_radius:g}, r {self.minor_radius:g})"

    def sample(self, n, rng):
        big, small = self.major_radius, self.minor_radius
        theta = np.empty(0)
        while len(theta) < n:  # density of theta is proportional to R + r cos(theta)
            cand = rng.uniform(0.0, TWO_PI, 2 * n)
            keep = rng.uniform(0.0, big + small, 2 * n) < big + small * np.cos(cand)
            theta = np.concatenate([theta, cand[keep]])
        theta = theta[:n]
        phi = rng.uniform(0.0, TWO_PI, n)
        rho = big + small * np.cos(theta)
        return np.stack([rho * np.cos(phi), rho * np.sin(phi), small * np.sin(theta)], 1)

    def params(self, p):
        p = np.asarray(p, np.float64)
        rho = np.hypot(p[:, 0], p[:, 1])
        phi = np.mod(np.arctan2(p[:, 1], p[:, 0]), TWO_PI)
        theta = np.mod(np.arctan2(p[:, 2], rho - self.major_radius), TWO_PI)
        return np.stack([phi, theta], 1)

    def surface_distance(self, a, b, samples: int = 9):
        """Length of the straight parameter-space segment (wrapped), by Simpson's rule."""
        dphi = _wrap(b[:, 0] - a[:, 0], TWO_PI)
        dtheta = _wrap(b[:, 1] - a[:, 1], TWO_PI)
        s = np.linspace(0.0, 1.0, samples)
        w = np.ones(samples)
        w[1:-1:2], w[2:-1:2] = 4.0, 2.0
        w /= w.sum()
        theta = a[:, 1:2] + s[None] * dtheta[:, None]
        speed = np.sqrt(((self.major_radius + self.minor_radius * np.cos(theta))
                         * dphi[:, None]) ** 2 + (self.minor_radius * dtheta[:, None]) ** 2)
        return speed @ w

    def distance(self, p):
        p = np.asarray(p, np.float64)
        rho = np.hypot(p[:, 0], p[:, 1])
        return np.abs(np.hypot(rho - self.major_radius, p[:, 2]) - self.minor_radius)


# --------------------------------------------------------------------------------------- sphere
@dataclass
class Sphere(Shape):
    """Sphere of the given radius about the origin; parameters (phi azimuth, theta polar)."""

    radius: float = 1.0
    name: str = "sphere"
    periods: tuple[float, float] = (TWO_PI, 0.0)
    param_names: tuple[str, str] = ("phi", "theta")
    recommended: Recommended = field(default_factory=lambda: Recommended(
        wrap="u", frame="spherical", axis="z", vary="r=uv,theta=v,phi=u", anisotropy=0.0))

    @property
    def area(self) -> float:
        return float(4.0 * np.pi * self.radius ** 2)

    def describe(self) -> str:
        return f"sphere (radius {self.radius:g})"

    def sample(self, n, rng):
        v = rng.normal(size=(n, 3))
        v /= np.linalg.norm(v, axis=1, keepdims=True)
        return v * self.radius

    def params(self, p):
        p = np.asarray(p, np.float64)
        phi = np.mod(np.arctan2(p[:, 1], p[:, 0]), TWO_PI)
        theta = np.arctan2(np.hypot(p[:, 0], p[:, 1]), p[:, 2])
        return np.stack([phi, theta], 1)

    def _unit(self, q):
        phi, theta = q[:, 0], q[:, 1]
        return np.stack([np.sin(theta) * np.cos(phi), np.sin(theta) * np.sin(phi),
                         np.cos(theta)], 1)

    def surface_distance(self, a, b):
        dot = np.clip(np.sum(self._unit(a) * self._unit(b), axis=1), -1.0, 1.0)
        return self.radius * np.arccos(dot)

    def distance(self, p):
        return np.abs(np.linalg.norm(np.asarray(p, np.float64), axis=1) - self.radius)


# ------------------------------------------------------------------------------------- cylinder
@dataclass
class Cylinder(Shape):
    """Open cylinder about the z axis: radius, z in [0, height]; parameters (phi, h)."""

    radius: float = 1.0
    height: float = 4.0
    name: str = "cylinder"
    periods: tuple[float, float] = (TWO_PI, 0.0)
    param_names: tuple[str, str] = ("phi", "h")
    recommended: Recommended = field(default_factory=lambda: Recommended(
        wrap="u", frame="cylindrical", axis="z", vary="rho=uv,phi=u,z=v", anisotropy=0.0))

    @property
    def area(self) -> float:
        return float(TWO_PI * self.radius * self.height)

    def describe(self) -> str:
        return f"cylinder (radius {self.radius:g}, height {self.height:g})"

    def sample(self, n, rng):
        phi = rng.uniform(0.0, TWO_PI, n)
        z = rng.uniform(0.0, self.height, n)
        return np.stack([self.radius * np.cos(phi), self.radius * np.sin(phi), z], 1)

    def params(self, p):
        p = np.asarray(p, np.float64)
        phi = np.mod(np.arctan2(p[:, 1], p[:, 0]), TWO_PI)
        return np.stack([phi, np.clip(p[:, 2], 0.0, self.height)], 1)

    def surface_distance(self, a, b):
        dphi = _wrap(b[:, 0] - a[:, 0], TWO_PI)
        return np.hypot(self.radius * dphi, b[:, 1] - a[:, 1])

    def distance(self, p):
        p = np.asarray(p, np.float64)
        radial = np.hypot(p[:, 0], p[:, 1]) - self.radius
        over = np.maximum(np.maximum(-p[:, 2], p[:, 2] - self.height), 0.0)
        return np.hypot(radial, over)


SHAPES = {"roll": Roll, "torus": Torus, "sphere": Sphere, "cylinder": Cylinder}


def make_shape(name: str, *, turns=None, height=None, major_radius=None, minor_radius=None,
               radius=None) -> Shape:
    """A built-in shape by name with the size options that apply to it (None = default)."""
    from osmap_cli.errors import OsmapError

    given = {"turns": turns, "height": height, "major_radius": major_radius,
             "minor_radius": minor_radius, "radius": radius}
    accepted = {"roll": ("turns", "height"), "torus": ("major_radius", "minor_radius"),
                "sphere": ("radius",), "cylinder": ("radius", "height")}
    if name not in SHAPES:
        raise OsmapError(f"--shape: unknown shape {name!r} (choose from {', '.join(SHAPES)})")
    kwargs = {}
    for key, value in given.items():
        if value is None:
            continue
        option = "--" + key.replace("_", "-")
        if key not in accepted[name]:
            raise OsmapError(f"{option}: does not apply to --shape {name} (it takes "
                             + ", ".join("--" + a.replace("_", "-") for a in accepted[name])
                             + ")")
        if not np.isfinite(value) or value <= 0:
            raise OsmapError(f"{option}: must be a positive number, got {value}")
        kwargs[key] = float(value)
    shape = SHAPES[name](**kwargs)
    if isinstance(shape, Torus) and shape.minor_radius >= shape.major_radius:
        raise OsmapError(f"--minor-radius: must be smaller than --major-radius "
                         f"({shape.minor_radius:g} >= {shape.major_radius:g})")
    return shape
