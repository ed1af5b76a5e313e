"""Every option of `osmap solid`, validated before any work starts (the pattern of
osmap_cli.synth.options: `SolidOptions(...).validated()` returns the options or raises OsmapError
naming the bad value and its range).

Solid presets are separate from the `[synth]` presets: a built-in name from SOLID_PRESETS, or a
TOML file with `name`, `description` and a `[solid]` table of the tunables below.
"""

from __future__ import annotations

import dataclasses
import os
import sys
from dataclasses import dataclass, field

from osmap_cli.errors import OsmapError
from osmap_cli.synth.options import check_number

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover
    import tomli as tomllib

QUALITIES = ("fast", "default", "high")
MAX_SIDE = 1024


def _spec(default, lo=None, hi=None, doc=""):
    return field(default=default, metadata={"lo": lo, "hi": hi, "doc": doc})


@dataclass(frozen=True)
class SolidOptions:
    """What to synthesize and how. Sizes in voxels."""

    width: int = _spec(128, 8, MAX_SIDE, "volume size along x")
    height: int = _spec(128, 8, MAX_SIDE, "volume size along y")
    depth: int = _spec(128, 8, MAX_SIDE, "volume size along z")
    seed: int = _spec(0, 0, 2**63 - 1, "random seed")
    tileable: bool = _spec(False, doc="the volume wraps around in all three axes")
    quality: str = _spec("default", doc="fast, default or high")
    method: str = _spec("osmap", doc="osmap (OS-Map layout + sharpened Kopf optimisation), "
                        "kopf (Kopf et al. 2007 as published) or legacy (the pre-issue-13 "
                        "search + mode pipeline)")
    # --- tunables (solid presets) ---
    levels: int = _spec(4, 1, 8, "pyramid levels (the coarsest volume keeps >= 16 voxels a side)")
    patch_radius: int = _spec(2, 1, 4, "in-plane matching window half-size")
    iterations: int = _spec(3, 1, 20, "search + colour iterations per finer level")
    coarse_iterations: int = _spec(8, 1, 40, "iterations at the coarsest level")
    knn: int = _spec(2, 0, 16, "similar-position candidates per propagated candidate")
    random_candidates: int = _spec(2, 0, 16, "random-search candidates per voxel and axis")
    feature_dims: int = _spec(8, 1, 32, "appearance-space (PCA) dimensions")
    feature_radius: int = _spec(0, 0, 3, "appearance neighbourhood half-size (0: colour only)")
    mode_bandwidth: float = _spec(0.25, 0.001, 10.0,
                                  "mode kernel support, relative to the feature variance")
    mode_radius: int = _spec(1, 0, 4, "proposals from the in-plane (2r+1)^2 neighbours")
    mode_power: float = _spec(0.6, 0.0, 4.0, "proposal weight = match cost ** -mode_power")
    occupancy: float = _spec(0.5, 0.0, 10.0, "penalty on over-used exemplar pixels in the mode")
    across: float = _spec(0.0, 0.0, 100.0, "mode discount on proposals unlike the volume's "
                          "two voxels across their slice plane (against 1-voxel stripes)")
    search_occupancy: float = _spec(0.0, 0.0, 10.0,
                                    "penalty on over-used exemplar pixels in the search")
    seam: float = _spec(0.5, 0.0, 10.0, "finest level: search penalty on positions that break "
                        "their in-plane neighbours' copy")
    coarse_seam: float = _spec(0.6, 0.0, 10.0, "the same penalty at every coarser level (the "
                               "copy layout the finer levels refine)")
    histogram: float = _spec(0.0, 0.0, 1.0, "how far the volume searched against is moved to "
                             "the exemplar's colour distribution")
    smooth_upsample: float = _spec(1.0, 0.0, 1.0, "weight of the coarser volume's interpolated "
                                   "colours (against its duplicated sources) at each new level")
    blend: float = _spec(1.0, 0.0, 100.0, "render: mean of the proposals within this "
                         "bandwidth (relative to the feature variance) of each voxel's source; "
                         "0: exact copies")
    som_steps_per_node: float = _spec(10.0, 0.0, 1000.0, "OS-Map steps per coarsest voxel")
    som_sigma_max: float = _spec(1.5, 0.1, 64.0, "OS-Map initial radius, voxels")
    som_anisotropy: float = _spec(0.25, 0.0, 1.0, "kernel weight across / along each component")
    # --- methods osmap and kopf (texture optimisation, osmap_cli/solid/kopf.py) ---
    kopf_window: int = _spec(8, 4, 16, "window side n of the slice neighbourhoods (n x n)")
    kopf_iterations: int = _spec(4, 1, 20, "search + optimisation iterations per level")
    kopf_r: float = _spec(0.8, 0.1, 2.0, "robust norm exponent r: IRLS weight = distance ** "
                          "(r - 2)")
    kopf_dims: int = _spec(24, 2, 64, "PCA dimensions of the window vectors (search space)")
    kopf_stride: int = _spec(2, 1, 4, "window centres every kopf_stride voxels in each plane")
    window_falloff: float = _spec(0.0, 0.0, 10.0, "method osmap: centre weighting of each "
                                  "window's colours, exp(-falloff * d^2 / (n/2)^2) (kopf: flat "
                                  "windows, as published)")
    kopf_histogram: float = _spec(1.0, 0.0, 10.0, "method kopf: strength of the colour and "
                                  "exemplar-position histogram weights (0: plain IRLS)")
    histogram_weight: float = _spec(3.0, 0.0, 10.0, "method osmap: the same strength (stronger "
                                    "than kopf's: the sharpening favours the majority colour)")
    sharpen: int = _spec(3, 0, 20, "method osmap: the last `sharpen` iterations of every level "
                         "give each voxel one exemplar colour (the best-agreeing window's)")
    sharpen_levels: int = _spec(8, 0, 8, "method osmap: sharpen at the finest this many levels "
                                "(the coarser ones average, as in Kopf et al.)")
    sharpen_cross: int = _spec(1, 0, 1, "1: a proposal's density counts only the other two "
                               "slice families' proposals (against 1-voxel stripes)")
    sharpen_finest: int = _spec(0, 0, 1, "0: the finest level only averages (faster; the "
                                "sharpened coarser levels set the structure)")
    sharpen_final: int = _spec(0, 0, 1, "1: the finest level's last iteration is sharpened "
                               "too; 0: the volume is its average (soft antialiased boundaries "
                               "instead of pixel staircases)")
    upsample_render: int = _spec(1, 0, 1, "method osmap: 1: each finer level starts from the "
                                 "exemplar colours at the upsampled positions; 0: from the "
                                 "coarser volume interpolated (Kopf)")
    pick_support: int = _spec(1, 0, 4, "half-size of the in-plane area over which a window "
                              "must agree with the averaged volume to be picked")
    sharpen_bandwidth: float = _spec(0.25, 0.0, 10.0, "sharpening by mean shift: proposals "
                                     "within this squared colour distance (relative to the "
                                     "exemplar's colour variance) of the densest one are "
                                     "averaged; 0: pick the best-agreeing window instead")
    sharpen_steps: int = _spec(0, 0, 20, "with sharpen_bandwidth: mean-shift steps from the "
                               "weighted mean (Gaussian kernel) instead of the densest "
                               "proposal's cluster; 0: densest")
    final_histogram: float = _spec(0.5, 0.0, 1.0, "method osmap: how far the final colours are "
                                   "moved to the exemplar's per-channel distribution")

    @classmethod
    def tunables(cls) -> dict[str, dataclasses.Field]:
        """The fields a solid preset may set."""
        fields = dataclasses.fields(cls)
        start = [f.name for f in fields].index("levels")
        return {f.name: f for f in fields[start:]}

    def replace(self, **changes) -> SolidOptions:
        """A copy with some fields changed (not yet validated)."""
        return dataclasses.replace(self, **changes)

    @property
    def shape(self) -> tuple[int, int, int]:
        """(Z, Y, X) of the volume."""
        return (self.depth, self.height, self.width)

    def validated(self) -> SolidOptions:
        """These options checked field by field; raises OsmapError on the first bad value."""
        for f in dataclasses.fields(self):
            value = getattr(self, f.name)
            option = "--" + f.name.replace("_", "-")
            if isinstance(f.default, bool):
                if not isinstance(value, bool):
                    raise OsmapError(f"{option}: expected true or false, got {value!r}")
                continue
            if isinstance(f.default, str):
                continue
            check_number(option, value, f)
        if self.quality not in QUALITIES:
            raise OsmapError(f"--quality: {self.quality!r} is not one of {', '.join(QUALITIES)}")
        return self

    def with_quality(self) -> SolidOptions:
        """The tunables adjusted for --quality (fast: less search; high: more)."""
        if self.quality == "fast":
            return self.replace(iterations=1,
                                coarse_iterations=max(1, self.coarse_iterations // 2),
                                knn=min(self.knn, 1),
                                random_candidates=min(self.random_candidates, 1))
        if self.quality == "high":
            return self.replace(iterations=self.iterations + 1,
                                coarse_iterations=self.coarse_iterations + 2,
                                knn=self.knn + 2, random_candidates=self.random_candidates + 2)
        return self


# ---------------------------------------------------------------------------------------------
# presets

SOLID_PRESETS: dict[str, tuple[str, dict]] = {
    "default": ("the built-in defaults: stone, marble, terrazzo, gravel", {}),
    "structured": ("legacy method, larger windows and more search: veins, grains, planks",
                   {"method": "legacy", "patch_radius": 3, "iterations": 3, "knn": 3}),
    "fast": ("previews: less search", {"iterations": 1, "coarse_iterations": 3, "knn": 1,
                                       "random_candidates": 1, "som_steps_per_node": 4.0,
                                       "kopf_iterations": 1}),
    "smooth": ("legacy method with far fewer 1-voxel stripes and better coherence, but paler "
               "(the majority colour wins; grains and chips grow and thin out)",
               {"method": "legacy", "across": 4.0}),
    "legacy": ("the default before issue 13: search + mode pipeline (boxy, pale; for "
               "comparison)", {"method": "legacy"}),
}


@dataclass(frozen=True)
class SolidPreset:
    """A loaded solid preset: `values` is the [solid] table (tunable -> value)."""

    name: str
    description: str
    values: dict


def is_preset_path(text: str) -> bool:
    """A preset given as a file rather than a built-in name."""
    return text.lower().endswith(".toml") or os.sep in text or "/" in text


def load_solid_preset(name: str) -> SolidPreset:
    """A built-in solid preset by name, or a TOML file with a [solid] table; validated."""
    if not is_preset_path(name):
        if name not in SOLID_PRESETS:
            raise OsmapError(f"--preset: unknown solid preset {name!r} (built-in: "
                             f"{', '.join(SOLID_PRESETS)}; or give a .toml file with a "
                             "[solid] table)")
        description, values = SOLID_PRESETS[name]
        return SolidPreset(name, description, dict(values))
    try:
        with open(name, "rb") as handle:
            data = tomllib.load(handle)
    except FileNotFoundError:
        raise OsmapError(f"{name}: no such preset file") from None
    except OSError as exc:
        raise OsmapError(f"{name}: cannot read preset file ({exc.strerror or exc})") from None
    except tomllib.TOMLDecodeError as exc:
        raise OsmapError(f"{name}: not valid TOML ({exc})") from None
    unknown = sorted(set(data) - {"name", "description", "solid", "synth"})
    if unknown:
        raise OsmapError(f"{name}: unknown key {unknown[0]!r} (expected name, description, "
                         "[solid])")
    table = data.get("solid")
    if not isinstance(table, dict):
        raise OsmapError(f"{name}: no [solid] table (osmap solid reads its tunables from "
                         "[solid]; [synth] is for osmap synth)")
    tunables = SolidOptions.tunables()
    for key, value in table.items():
        if key not in tunables:
            raise OsmapError(f"{name}: [solid] {key}: unknown key (allowed: "
                             f"{', '.join(tunables)})")
        check_number(key, value, tunables[key], where=f"{name}: [solid] ")
    base = os.path.basename(name)
    return SolidPreset(str(data.get("name", base)), str(data.get("description", "")),
                       dict(table))


def preset_toml(name: str) -> str:
    """A built-in solid preset written out as TOML, every tunable included."""
    description, values = SOLID_PRESETS[name]
    opts = SolidOptions().replace(**values)
    lines = [f'name = "{name}"', f'description = "{description}"', "", "[solid]"]
    for key, f in SolidOptions.tunables().items():
        lines.append(f"{key} = {getattr(opts, key)!r}".ljust(28) + f"# {f.metadata['doc']}")
    return "\n".join(lines) + "\n"
