"""Every option of `osmap synth`, validated before any work starts.

A session object in the spirit of Embark's texture-synthesis: `SynthOptions(...).validated()`
either returns the resolved options or raises OsmapError naming the bad value and the allowed
range. Presets are plain mappings of the tunable fields below.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field

import numpy as np

from osmap_cli.errors import OsmapError

METHODS = ("osmap", "paper")
QUALITIES = ("fast", "default", "high")


def _spec(default, lo=None, hi=None, doc=""):
    return field(default=default, metadata={"lo": lo, "hi": hi, "doc": doc})


def check_number(option: str, value, f: dataclasses.Field, where: str = "") -> None:
    """Raise OsmapError unless value is a finite number of f's kind inside f's [lo, hi]."""
    kind = int if isinstance(f.default, int) else float
    if isinstance(value, bool) or not isinstance(value, (int, float, np.number)):
        raise OsmapError(f"{where}{option}: expected a number, got {value!r}")
    if kind is int and float(value) != int(value):
        raise OsmapError(f"{where}{option}: expected a whole number, got {value!r}")
    if not math.isfinite(float(value)):
        raise OsmapError(f"{where}{option}: expected a finite number, got {value!r}")
    lo, hi = f.metadata["lo"], f.metadata["hi"]
    if not lo <= value <= hi:
        raise OsmapError(f"{where}{option}: {value!r} is out of range (allowed {lo} to {hi})")


@dataclass(frozen=True)
class SynthOptions:
    """What to synthesize and how. Units: pixels of the output unless stated."""

    width: int = _spec(256, 8, 16384, "output width")
    height: int = _spec(256, 8, 16384, "output height")
    seed: int = _spec(0, 0, 2**63 - 1, "random seed")
    scale: float = _spec(1.0, 0.25, 8.0, "feature size relative to the exemplar")
    orientation: float = _spec(0.0, -360.0, 360.0, "rotation of the texture, degrees")
    anisotropy: float = _spec(1.0, 0.25, 4.0, "stretch along the orientation direction")
    tileable: bool = _spec(False, doc="output wraps around seamlessly")
    method: str = _spec("osmap", doc="osmap (default pipeline) or paper (the published OS-Map)")
    quality: str = _spec("default", doc="fast, default or high")
    # --- tunables (presets) ---
    levels: int = _spec(0, 0, 8, "pyramid levels (0: from the exemplar size, coarsest ~16 px)")
    patch_radius: int = _spec(2, 1, 4, "matching window half-size, in feature vectors")
    sweeps: int = _spec(6, 0, 20, "coherence sweeps per level")
    coarse_sweeps: int = _spec(8, 0, 40, "coherence sweeps at the coarsest level")
    occupancy: float = _spec(0.5, 0.0, 10.0, "penalty on over-used exemplar regions")
    seam: float = _spec(1.0, 0.0, 10.0, "penalty on positions that break their neighbours' copy")
    max_copy: float = _spec(56.0, 0.0, 4096.0, "copy regions wider than this, in output pixels, "
                            "are broken up (0: off)")
    align: int = _spec(4, 0, 8, "copies move whole by up to this many pixels to match at their "
                       "borders (coarsest level; halved per finer level; 0: off)")
    blend: int = _spec(2, 0, 8, "seam blending radius when rendering, pixels (0: hard copies)")
    knn: int = _spec(4, 0, 16, "similar-position candidates (k-coherence)")
    random_candidates: int = _spec(4, 0, 16, "PatchMatch random-search candidates")
    feature_dims: int = _spec(16, 1, 32, "appearance-space dimensions")
    window_scale: float = _spec(1.0, 0.1, 4.0, "winner-search window / exemplar extent")
    som_steps_per_node: float = _spec(20.0, 0.0, 1000.0, "OS-Map steps per map node")
    som_sigma_max: float = _spec(1.5, 0.1, 256.0, "OS-Map initial radius, nodes")
    som_sigma_min: float = _spec(0.3, 0.05, 64.0, "OS-Map final radius, nodes")
    som_alpha_max: float = _spec(0.5, 0.0, 1.0, "OS-Map initial learning rate")
    som_alpha_min: float = _spec(0.05, 0.0, 1.0, "OS-Map final learning rate")
    som_anisotropy: float = _spec(0.25, 0.0, 1.0, "kernel weight across / along each component")
    som_range: float = _spec(2.0, 0.0, 100.0, "range kernel tau = som_range * sigma + 1 (0: off)")

    @classmethod
    def tunables(cls) -> dict[str, dataclasses.Field]:
        """The fields a preset may set."""
        names = [f.name for f in dataclasses.fields(cls)]
        start = names.index("levels")
        return {f.name: f for f in dataclasses.fields(cls)[start:]}

    def replace(self, **changes) -> SynthOptions:
        """A copy with some fields changed (not yet validated)."""
        return dataclasses.replace(self, **changes)

    def validated(self) -> SynthOptions:
        """These options checked field by field; raises OsmapError on the first bad value."""
        for f in dataclasses.fields(self):
            value = getattr(self, f.name)
            option = "--" + f.name.replace("_", "-")
            if isinstance(f.default, bool):
                if not isinstance(value, (bool, np.bool_)):
                    raise OsmapError(f"{option}: expected true or false, got {value!r}")
                continue
            if isinstance(f.default, str):
                continue
            check_number(option, value, f)
        if self.method not in METHODS:
            raise OsmapError(f"--method: {self.method!r} is not one of {', '.join(METHODS)}")
        if self.quality not in QUALITIES:
            raise OsmapError(f"--quality: {self.quality!r} is not one of {', '.join(QUALITIES)}")
        if self.som_sigma_min > self.som_sigma_max:
            raise OsmapError(f"som_sigma_min {self.som_sigma_min} exceeds som_sigma_max "
                             f"{self.som_sigma_max}")
        if self.som_alpha_min > self.som_alpha_max:
            raise OsmapError(f"som_alpha_min {self.som_alpha_min} exceeds som_alpha_max "
                             f"{self.som_alpha_max}")
        return self

    def with_quality(self) -> SynthOptions:
        """The tunables adjusted for --quality (fast halves the work, high adds sweeps)."""
        if self.quality == "fast":
            return self.replace(sweeps=max(1, self.sweeps // 2), knn=min(self.knn, 2),
                                coarse_sweeps=max(1, self.coarse_sweeps // 2),
                                random_candidates=min(self.random_candidates, 2))
        if self.quality == "high":
            return self.replace(sweeps=self.sweeps + 2, coarse_sweeps=self.coarse_sweeps + 2,
                                knn=self.knn + 2)
        return self

    def jacobian(self) -> np.ndarray:
        """J (2x2, row/col order): exemplar offset per output pixel offset.

        The output shows the exemplar rotated counter-clockwise by `orientation` degrees,
        magnified by `scale`, and stretched by `anisotropy` along the rotated exemplar x axis.
        """
        theta = math.radians(self.orientation)
        c, s = math.cos(theta), math.sin(theta)
        # output (x, y-down) = scale * rot * diag(anisotropy, 1) * exemplar (x, y-down);
        # counter-clockwise on screen (y down) is [[c, s], [-s, c]] in (x, y).
        forward_xy = self.scale * np.array([[c, s], [-s, c]]) @ np.diag([self.anisotropy, 1.0])
        inverse_xy = np.linalg.inv(forward_xy)
        swap = np.array([[0.0, 1.0], [1.0, 0.0]])
        return swap @ inverse_xy @ swap
