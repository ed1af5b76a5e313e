"""Every option of `osmap synth`, declared once and validated before any work starts.

A session object in the spirit of Embark's texture-synthesis: `SynthOptions(...).validated()`
either returns the resolved options or raises OsmapError naming the bad value and the allowed
range. The tunable fields are the preset keys and the tuning flags (osmap_cli.options).

>>> SynthOptions(width=128, height=64, seed=7).validated().width
128
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from osmap_cli.errors import OsmapError
from osmap_cli.options import Options, option

METHODS = ("osmap", "paper")
QUALITIES = ("fast", "default", "high")


@dataclass(frozen=True)
class SynthOptions(Options):
    """What to synthesize and how. Units: pixels of the output unless stated."""

    width: int = option(256, 8, 16384, "output width")
    height: int = option(256, 8, 16384, "output height")
    seed: int = option(0, 0, 2**63 - 1, "random seed")
    scale: float = option(1.0, 0.25, 8.0, "feature size relative to the exemplar")
    orientation: float = option(0.0, -360.0, 360.0, "rotation of the texture, degrees")
    anisotropy: float = option(1.0, 0.25, 4.0, "stretch along the orientation direction")
    tileable: bool = option(False, help="output wraps around seamlessly")
    method: str = option("osmap", help="osmap (default pipeline) or paper (the published "
                         "OS-Map)", choices=METHODS)
    quality: str = option("default", help="fast, default or high", choices=QUALITIES)
    # --- tunables (preset keys and tuning flags) ---
    levels: int = option(0, 0, 8, "pyramid levels (0: from the exemplar size)", tunable=True)
    patch_radius: int = option(2, 1, 4, "matching window half-size, in feature vectors",
                               tunable=True)
    sweeps: int = option(6, 0, 20, "coherence sweeps per pyramid level", tunable=True)
    coarse_sweeps: int = option(8, 0, 40, "coherence sweeps at the coarsest level", tunable=True)
    occupancy: float = option(0.5, 0.0, 10.0, "penalty on over-used exemplar regions",
                              tunable=True)
    seam: float = option(1.0, 0.0, 10.0, "penalty on positions that break their neighbours' "
                         "copy", tunable=True)
    max_copy: float = option(56.0, 0.0, 4096.0, "copy regions wider than this, in output "
                             "pixels, are broken up (0: off)", tunable=True)
    align: int = option(4, 0, 8, "copies move whole by up to this many pixels to match at their "
                        "borders (coarsest level; halved per finer level; 0: off)", tunable=True)
    lattice: str = option("auto", help="regular textures keep their lattice: auto (read from "
                          "the exemplar), off, or the period vectors DX,DY[:DX,DY] in exemplar "
                          "pixels", tunable=True)
    blend: int = option(2, 0, 8, "seam blending radius when rendering, pixels (0: hard copies)",
                        tunable=True)
    guide_weight: float = option(1.0, 0.0, 100.0, "how strongly the output follows "
                                 "--target-guide (guided synthesis only)", tunable=True)
    knn: int = option(4, 0, 16, "similar-position candidates per pixel (k-coherence)",
                      tunable=True)
    random_candidates: int = option(4, 0, 16, "PatchMatch random-search candidates per pixel",
                                    tunable=True)
    feature_dims: int = option(16, 1, 32, "appearance-space (PCA) dimensions", tunable=True)
    window_scale: float = option(1.0, 0.1, 4.0, "OS-Map winner-search window / exemplar extent",
                                 tunable=True)
    som_steps_per_node: float = option(20.0, 0.0, 1000.0, "OS-Map training steps per map node",
                                       tunable=True)
    som_sigma_max: float = option(1.5, 0.1, 256.0, "OS-Map initial neighbourhood radius, in "
                                  "nodes", tunable=True)
    som_sigma_min: float = option(0.3, 0.05, 64.0, "OS-Map final neighbourhood radius, in nodes",
                                  tunable=True)
    som_alpha_max: float = option(0.5, 0.0, 1.0, "OS-Map initial learning rate", tunable=True)
    som_alpha_min: float = option(0.05, 0.0, 1.0, "OS-Map final learning rate", tunable=True)
    som_anisotropy: float = option(0.25, 0.0, 1.0, "OS-Map kernel weight across / along each "
                                   "component", tunable=True)
    som_range: float = option(2.0, 0.0, 100.0, "OS-Map range kernel: tau = som_range * sigma + 1 "
                              "(0: off)", tunable=True)

    def check_relations(self) -> None:
        """The schedules run from max to min; --lattice is auto, off or vectors."""
        if self.lattice not in ("auto", "off"):
            from osmap_cli.synth.lattice import parse_lattice

            try:
                parse_lattice(self.lattice)
            except ValueError as exc:
                raise OsmapError(f"--lattice {self.lattice}: {exc} (expected auto, off, DX,DY "
                                 "or DX,DY:DX,DY)") from None
        if self.som_sigma_min > self.som_sigma_max:
            raise OsmapError(f"som_sigma_min {self.som_sigma_min} exceeds som_sigma_max "
                             f"{self.som_sigma_max}")
        if self.som_alpha_min > self.som_alpha_max:
            raise OsmapError(f"som_alpha_min {self.som_alpha_min} exceeds som_alpha_max "
                             f"{self.som_alpha_max}")

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

    def jacobian(self):
        """J (2x2, row/col order): exemplar offset per output pixel offset.

        The output shows the exemplar rotated counter-clockwise by `orientation` degrees,
        magnified by `scale`, and stretched by `anisotropy` along the rotated exemplar x axis.
        """
        import numpy as np

        theta = math.radians(self.orientation)
        c, s = math.cos(theta), math.sin(theta)
        # output (x, y-down) = scale * rot * diag(anisotropy, 1) * exemplar (x, y-down);
        # counter-clockwise on screen (y down) is [[c, s], [-s, c]] in (x, y).
        forward_xy = self.scale * np.array([[c, s], [-s, c]]) @ np.diag([self.anisotropy, 1.0])
        inverse_xy = np.linalg.inv(forward_xy)
        swap = np.array([[0.0, 1.0], [1.0, 0.0]])
        return swap @ inverse_xy @ swap


@dataclass(frozen=True)
class FillOptions(Options):
    """What `osmap inpaint` and `osmap tileable` add to the synthesis options."""

    border: int = option(0, 0, 4096, "width of the re-synthesized bands along the edges, pixels "
                         "(0: an eighth of the shorter side, at least 8)")

    def band(self, shape) -> int:
        """The band width for an image of `shape` (h, w); OsmapError when it leaves no centre."""
        widest = (min(shape) - 1) // 2
        border = self.border or max(8, min(shape) // 8)
        if widest < 1 or border > widest:
            raise OsmapError(f"--border {border}: too wide for a {shape[1]}x{shape[0]} image "
                             f"(allowed 1 to {max(widest, 1)})")
        return border
