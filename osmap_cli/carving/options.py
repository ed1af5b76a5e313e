"""Every option of `osmap carve` (placement, baking, outputs), declared once with
osmap_cli.options.option and validated before any work.

>>> CarveOptions(texture_width=512, texture_height=512).validated().texture_size
(512, 512)
"""

from __future__ import annotations

from dataclasses import dataclass

from osmap_cli.errors import OsmapError
from osmap_cli.options import Options, option

__all__ = ["INTERPOLATIONS", "MAX_TEXTURE", "SCALE_MODES", "CarveOptions", "parse_scale"]

MAX_TEXTURE = 16384
INTERPOLATIONS = ("trilinear", "tricubic")
# fit: the object (turned) fills the volume; voxels: `scale` voxels per object unit;
# repeats: the volume repeats `scale` times across the object's longest side
SCALE_MODES = ("fit", "voxels", "repeats")


@dataclass(frozen=True)
class CarveOptions(Options):
    """How a volume is placed on an object and baked. Sizes in texels, offsets in voxels."""

    texture_width: int = option(1024, 8, MAX_TEXTURE, "texture map width, texels")
    texture_height: int = option(1024, 8, MAX_TEXTURE, "texture map height, texels")
    padding: int = option(4, 0, 64, "texels each UV island is grown by (no seams in mip-maps)")
    scale_mode: str = option("fit", help="fit, voxels or repeats", choices=SCALE_MODES)
    scale: float = option(1.0, 1e-6, 1e6, "voxels per object unit (voxels) or repeats across "
                          "the object's longest side (repeats)")
    offset_x: float = option(0.0, -1e6, 1e6, "material moved along the volume's x, voxels")
    offset_y: float = option(0.0, -1e6, 1e6, "material moved along the volume's y, voxels")
    offset_z: float = option(0.0, -1e6, 1e6, "material moved along the volume's z, voxels")
    rotate_x: float = option(0.0, -360.0, 360.0, "material turned about x, degrees (then y, "
                             "then z)")
    rotate_y: float = option(0.0, -360.0, 360.0, "material turned about y, degrees")
    rotate_z: float = option(0.0, -360.0, 360.0, "material turned about z, degrees")
    interpolation: str = option("trilinear", help="trilinear or tricubic (Catmull-Rom)",
                                choices=INTERPOLATIONS)
    atlas: bool = option(False, help="make a new UV atlas even when the mesh has UVs")
    vertex_colors: bool = option(False, help="colours at the vertices instead of a texture")
    wrap: bool = option(False, help="the volume tiles: points outside it wrap around")

    @property
    def texture_size(self) -> tuple[int, int]:
        return (self.texture_width, self.texture_height)

    @property
    def offset(self) -> tuple[float, float, float]:
        return (self.offset_x, self.offset_y, self.offset_z)

    @property
    def angles(self) -> tuple[float, float, float]:
        return (self.rotate_x, self.rotate_y, self.rotate_z)

    @property
    def cubic(self) -> bool:
        return self.interpolation == "tricubic"

    def scale_text(self) -> str:
        """--scale as typed: fit, N (voxels per unit) or Nx (repeats)."""
        from osmap_cli.options import number_text

        if self.scale_mode == "fit":
            return "fit"
        return number_text(self.scale) + ("x" if self.scale_mode == "repeats" else "")


def parse_scale(text: str) -> tuple[str, float]:
    """(scale_mode, scale) of a --scale value: fit, N or Nx; raises OsmapError."""
    value = str(text).strip().lower()
    if value == "fit":
        return "fit", 1.0
    mode = "repeats" if value.endswith("x") else "voxels"
    try:
        number = float(value[:-1] if mode == "repeats" else value)
    except ValueError:
        number = float("nan")
    if not number > 0 or number == float("inf"):
        raise OsmapError(f"--scale: {text!r} is not fit, a positive number (voxels per object "
                         "unit) or a positive number followed by x (repeats across the object)")
    return mode, number
