"""Every option of `osmap solid`, declared once and validated before any work starts (the
pattern of osmap_cli.synth.options: `SolidOptions(...).validated()` returns the options or raises
OsmapError naming the bad value and its range).

Solid presets are separate from the `[synth]` presets: TOML files with `name`, `description` and
a `[solid]` table of the tunables below (the built-in ones in presets/solid/).

>>> SolidOptions(width=32, height=32, depth=16).validated().shape
(16, 32, 32)
"""

from __future__ import annotations

from dataclasses import dataclass

from osmap_cli.errors import OsmapError
from osmap_cli.options import Options, option
from osmap_cli.solid.methods import METHODS, method_help
from osmap_cli.solid.structure import STRUCTURES

QUALITIES = ("fast", "default", "high")
MAX_SIDE = 1024


@dataclass(frozen=True)
class SolidOptions(Options):
    """What to synthesize and how. Sizes in voxels."""

    width: int = option(128, 8, MAX_SIDE, "volume size along x")
    height: int = option(128, 8, MAX_SIDE, "volume size along y")
    depth: int = option(128, 8, MAX_SIDE, "volume size along z")
    seed: int = option(0, 0, 2**63 - 1, "random seed")
    tileable: bool = option(False, help="the volume wraps around in all three axes")
    quality: str = option("default", help="fast, default or high", choices=QUALITIES)
    rotate_x: float = option(0.0, -360.0, 360.0, "the material turned about x, degrees "
                             "(--orientation RX,RY,RZ: about x, then y, then z)")
    rotate_y: float = option(0.0, -360.0, 360.0, "the material turned about y, degrees")
    rotate_z: float = option(0.0, -360.0, 360.0, "the material turned about z, degrees")
    # --- tunables (solid preset keys and tuning flags) ---
    method: str = option("structure", help=method_help(), choices=tuple(METHODS), tunable=True)
    levels: int = option(4, 1, 8, "pyramid levels (a volume side is halved while it keeps >= "
                         "16 voxels, the exemplar while its sides do)", tunable=True)
    patch_radius: int = option(2, 1, 4, "in-plane matching window half-size", tunable=True)
    iterations: int = option(3, 1, 20, "search + colour iterations per finer level",
                             tunable=True)
    coarse_iterations: int = option(8, 1, 40, "iterations at the coarsest level", tunable=True)
    knn: int = option(2, 0, 16, "similar-position candidates per propagated candidate",
                      tunable=True)
    random_candidates: int = option(2, 0, 16, "random-search candidates per voxel and axis",
                                    tunable=True)
    feature_dims: int = option(8, 1, 32, "appearance-space (PCA) dimensions", tunable=True)
    feature_radius: int = option(0, 0, 3, "appearance neighbourhood half-size (0: colour only)",
                                 tunable=True)
    mode_bandwidth: float = option(0.25, 0.001, 10.0, "mode kernel support, relative to the "
                                   "feature variance", tunable=True)
    mode_radius: int = option(1, 0, 4, "proposals from the in-plane (2r+1)^2 neighbours",
                              tunable=True)
    mode_power: float = option(0.6, 0.0, 4.0, "proposal weight = match cost ** -mode_power",
                               tunable=True)
    occupancy: float = option(0.5, 0.0, 10.0, "penalty on over-used exemplar pixels in the mode",
                              tunable=True)
    across: float = option(0.0, 0.0, 100.0, "mode discount on proposals unlike the volume's two "
                           "voxels across their slice plane (against 1-voxel stripes)",
                           tunable=True)
    search_occupancy: float = option(0.0, 0.0, 10.0, "penalty on over-used exemplar pixels in "
                                     "the search", tunable=True)
    seam: float = option(0.5, 0.0, 10.0, "finest level: search penalty on positions that break "
                         "their in-plane neighbours' copy", tunable=True)
    coarse_seam: float = option(0.6, 0.0, 10.0, "the same penalty at every coarser level (the "
                                "copy layout the finer levels refine)", tunable=True)
    histogram: float = option(0.0, 0.0, 1.0, "how far the volume searched against is moved to "
                              "the exemplar's colour distribution", tunable=True)
    smooth_upsample: float = option(1.0, 0.0, 1.0, "weight of the coarser volume's interpolated "
                                    "colours (against its duplicated sources) at each new level",
                                    tunable=True)
    blend: float = option(1.0, 0.0, 100.0, "render: mean of the proposals within this bandwidth "
                          "(relative to the feature variance) of each voxel's source; 0: exact "
                          "copies", tunable=True)
    som_steps_per_node: float = option(10.0, 0.0, 1000.0, "OS-Map steps per coarsest voxel",
                                       tunable=True)
    som_sigma_max: float = option(1.5, 0.1, 64.0, "OS-Map initial radius, voxels", tunable=True)
    som_anisotropy: float = option(0.25, 0.0, 1.0, "kernel weight across / along each component",
                                   tunable=True)

    # --- method structure (osmap_cli/solid/method_structure.py; its fill also reads the
    #     kopf_* window settings, knn, histogram_weight, position_weight and sharpen_* below) ---
    structure: str = option("auto", help="method structure: the 3D structure built: auto (what "
                            "the analysis finds), particles, layers, veins (swirled bands and "
                            "veins as continuous sheets), field (mottled phase regions), or "
                            "none (the osmap method's slice optimisation alone)",
                            choices=STRUCTURES, tunable=True)
    phases: int = option(0, 0, 4, "method structure: colour phases of the exemplar's "
                         "segmentation (0: chosen from the exemplar, 2 to 4)", tunable=True)
    guide_weight: float = option(1.0, 0.0, 10.0, "method structure: weight of the structure's "
                                 "guide channels against the colours in the window search",
                                 tunable=True)
    guide_clip: float = option(4.0, 1.0, 32.0, "method structure: pixels from a phase "
                               "boundary at which the distance guide saturates", tunable=True)
    phase_match: float = option(1.0, 0.0, 1.0, "method structure: how far each phase's colours "
                                "(and each particle's mean colour) move to the exemplar's",
                                tunable=True)
    fill_sharpen: int = option(3, 0, 20, "method structure: the last `fill_sharpen` "
                               "iterations of a level give each voxel the densest colour "
                               "cluster of its proposals of its own label, as method osmap's "
                               "sharpen (its sharpen_* settings apply; 0: the fill only "
                               "averages)", tunable=True)
    fill_detail: float = option(1.0, 0.0, 2.0, "method structure: the exemplar's residual "
                                "detail (its high-pass) added to each voxel from its source "
                                "pixel, each phase up to this share of the exemplar's detail "
                                "variance in that phase (0: none)", tunable=True)
    # --- methods osmap and kopf (texture optimisation, osmap_cli/solid/optimise.py) ---
    kopf_window: int = option(8, 4, 16, "window side n of the slice neighbourhoods (n x n)",
    tunable=True)
    kopf_iterations: int = option(4, 1, 20, "search + optimisation iterations per level",
    tunable=True)
    kopf_r: float = option(0.8, 0.1, 2.0, "robust norm exponent r: IRLS weight = distance ** "
                          "(r - 2)", tunable=True)
    kopf_dims: int = option(24, 2, 64, "PCA dimensions of the window vectors (search space)",
    tunable=True)
    kopf_stride: int = option(2, 1, 4, "window centres every kopf_stride voxels in each plane",
    tunable=True)
    window_falloff: float = option(0.0, 0.0, 10.0, "method osmap: centre weighting of each "
                                  "window's colours, exp(-falloff * d^2 / (n/2)^2) (kopf: flat "
                                  "windows, as published)", tunable=True)
    kopf_histogram: float = option(1.0, 0.0, 10.0, "method kopf: strength of the colour and "
                                  "exemplar-position histogram weights (0: plain IRLS)",
                                  tunable=True)
    histogram_weight: float = option(3.0, 0.0, 10.0, "methods osmap and structure: strength "
                                    "of the colour histogram weight (stronger than kopf's: the "
                                    "sharpening favours the majority colour)", tunable=True)
    position_weight: float = option(9.0, 0.0, 30.0, "methods osmap and structure: strength "
                                   "of the exemplar-position histogram weight (higher: more of "
                                   "the exemplar used, truer colours and feature sizes, more "
                                   "1-voxel stripes)", tunable=True)
    sharpen: int = option(3, 0, 20, "method osmap: the last `sharpen` iterations of every level "
                         "give each voxel one exemplar colour (the best-agreeing window's)",
                         tunable=True)
    sharpen_levels: int = option(8, 0, 8, "methods osmap and structure: sharpen at the finest "
                                "this many levels (the coarser ones average, as in Kopf et al.)",
                                tunable=True)
    sharpen_cross: int = option(1, 0, 1, "1: a proposal's density counts only the other two "
                               "slice families' proposals (against 1-voxel stripes)", tunable=True)
    sharpen_finest: int = option(0, 0, 1, "methods osmap and structure: 0: the finest level "
                                "only averages (faster; the sharpened coarser levels set the "
                                "structure)", tunable=True)
    sharpen_final: int = option(0, 0, 1, "1: the finest level's last iteration is sharpened "
                               "too; 0: the volume is its average (soft antialiased boundaries "
                               "instead of pixel staircases)", tunable=True)
    upsample_render: int = option(1, 0, 1, "method osmap: 1: each finer level starts from the "
                                 "exemplar colours at the upsampled positions; 0: from the "
                                 "coarser volume interpolated (Kopf)", tunable=True)
    pick_support: int = option(1, 0, 4, "half-size of the in-plane area over which a window "
                              "must agree with the averaged volume to be picked", tunable=True)
    sharpen_bandwidth: float = option(0.25, 0.0, 10.0, "sharpening by mean shift: proposals "
                                     "within this squared colour distance (relative to the "
                                     "exemplar's colour variance) of the densest one are "
                                     "averaged; 0: pick the best-agreeing window instead",
                                     tunable=True)
    sharpen_steps: int = option(0, 0, 20, "with sharpen_bandwidth: mean-shift steps from the "
                               "weighted mean (Gaussian kernel) instead of the densest "
                               "proposal's cluster; 0: densest", tunable=True)
    final_histogram: float = option(0.75, 0.0, 1.0, "methods osmap and structure: how far the "
                                   "final colours are moved to the exemplar's per-channel "
                                   "distribution", tunable=True)
    # --- polish (method structure: iterations at the finest level once the structure is set,
    #     osmap_cli/solid/optimise.py's Polish) ---
    polish: int = option(0, 0, 8, "method structure: search + average iterations after the "
                         "fill's finest level, from its volume (0: none; the front they "
                         "measure: docs/solid.md)", tunable=True)
    polish_guides: int = option(0, 0, 1, "method structure: 1: the polish's windows keep the "
                                "structure's guide channels; 0: colours only", tunable=True)
    polish_labels: float = option(1.0, 0.0, 1.0, "method structure: the label constraint's "
                                  "weight in the polish's averaging (1: none)", tunable=True)
    polish_discrete: int = option(0, 0, 1, "method structure: 1: the polish's last iteration "
                                  "gives each voxel its heaviest proposal's exemplar colour "
                                  "instead of the mean", tunable=True)
    # --- veins (method structure's residual detail on veins) ---
    vein_detail: str = option("noise", help="method structure, veins: how the residual detail "
                              "(fill_detail) reaches veins: noise (Gaussian noise with the "
                              "exemplar's detail spectrum and colours, its grain along the "
                              "sheets), copy (from each voxel's source pixel, as particles and "
                              "layers: prints the fill's window lattice as a grid on wide "
                              "regions) or none", choices=("noise", "copy", "none"),
                              tunable=True)
    vein_grain: float = option(0.0, 0.0, 8.0, "method structure, veins: how far (voxels) the "
                               "fine band, the fill's and the noise detail's, is blurred within "
                               "the sheets' local planes, drawing it out into streaks that "
                               "follow every fold (0: fitted, running along the flow as "
                               "strongly as the exemplar's detail)", tunable=True)

    @property
    def shape(self) -> tuple[int, int, int]:
        """(Z, Y, X) of the volume."""
        return (self.depth, self.height, self.width)

    @property
    def angles(self) -> tuple[float, float, float]:
        """(rotate_x, rotate_y, rotate_z), degrees."""
        return (self.rotate_x, self.rotate_y, self.rotate_z)

    def synthesis_shape(self) -> tuple[int, int, int]:
        """(Z, Y, X) of the volume synthesized: the output's, or with --orientation the
        axis-aligned box that holds the turned output (osmap_cli.solid.orient)."""
        from osmap_cli.solid.orient import enclosing_shape

        return enclosing_shape(self.shape, self.angles)

    def check_relations(self) -> None:
        from osmap_cli.solid.orient import is_turned

        if not is_turned(self.angles):
            return
        if self.tileable:
            raise OsmapError("--orientation: a turned volume cannot wrap around; drop "
                             "--tileable or the orientation")
        big = max(self.synthesis_shape())
        if big > MAX_SIDE:
            raise OsmapError(f"--orientation: this turn needs a {big}-voxel side of axis-aligned "
                             f"material (at most {MAX_SIDE}); make the volume smaller")
