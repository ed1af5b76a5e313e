"""One `osmap inpaint` or `osmap tileable` job: an image -> the same image with a hole filled or
its edge bands re-synthesized, plus its --with maps and --uv-out positions.

    read (image, mask, --with maps) -> check (mask, border, formats) -> compute (fill)
    -> stage (every output in one transaction) -> commit

The outputs, formats and transaction are osmap_cli.synth.job.SynthJob's; what differs is the
input (a mask or a border), the size (the image's), the engine (osmap_cli.synth.fill), how the
--with maps are rendered and the provenance: the hooks of SynthJob's staging this job overrides.
"""

from __future__ import annotations

import dataclasses
import os
from dataclasses import dataclass

import numpy as np

from osmap_cli.errors import OsmapError
from osmap_cli.synth.job import SynthJob, map_renderer, synth_args

__all__ = ["MODES", "FillJob", "fill_args", "read_mask"]

MODES = ("inpaint", "tileable")


def fill_args(options, preset: str, preset_values: dict | None, bit_depth: int,
              more: list[str]) -> list[str]:
    """Canonical `osmap inpaint` / `osmap tileable` flags: synth_args' without --size and
    --tileable (the image sets them), then MORE (--mask NAME, --border N)."""
    args = synth_args(options, preset, preset_values, bit_depth)[2:]
    return [a for a in args if a != "--tileable"] + list(more)


@dataclass(frozen=True)
class _FillInputs:
    image: object  # osmap_cli.imageio.Image
    maps: list  # [(WithMap, output path, Image)]
    free: np.ndarray  # bool (H, W): the pixels to synthesize
    fields: object = None
    exemplars: tuple = ()  # float32 pixels of --exemplar, with the image's channels


def read_mask(mask: str, image) -> np.ndarray:
    """bool (H, W), True = fill: MASK's white pixels (any colour channel >= 0.5), or with
    mask "alpha" the image's transparent pixels (alpha < 0.5)."""
    from osmap_cli.imageio import read_image

    pixels = image.pixels
    if mask == "alpha":
        if image.alpha_channel is None:
            raise OsmapError(f"{image.path}: has no alpha channel (--mask alpha takes the fill "
                             "region from it; give a mask image instead)")
        free = pixels[..., image.alpha_channel] < 0.5
        what = f"{image.path}: its alpha channel has no transparent pixel"
    else:
        read = read_image(mask)
        if read.pixels.shape[:2] != pixels.shape[:2]:
            raise OsmapError(f"{mask}: the mask is {read.pixels.shape[1]}x{read.pixels.shape[0]} "
                             f"but {image.path} is {pixels.shape[1]}x{pixels.shape[0]} (they "
                             "must be the same size)")
        colour = [c for c in range(read.pixels.shape[2]) if c != read.alpha_channel] or [0]
        free = read.pixels[..., colour].max(axis=2) >= 0.5
        what = f"{mask}: the mask is empty (white = fill; it has no pixel >= 0.5)"
    if not free.any():
        raise OsmapError(what)
    if free.all():
        raise OsmapError(f"{mask if mask != 'alpha' else image.path}: the mask covers the "
                         "whole image (nothing is left to fill from)")
    return free


def read_exemplars(paths, image) -> tuple:
    """The --exemplar images' pixels, with IMAGE's channel count: the same, or one fewer when
    IMAGE's last channel is its alpha (the exemplar is then taken as opaque)."""
    from osmap_cli.imageio import read_image

    channels = image.pixels.shape[2]
    out = []
    for path in paths:
        pixels = read_image(path).pixels
        if pixels.shape[2] == channels - 1 and image.alpha_channel == channels - 1:
            pixels = np.concatenate([pixels, np.ones((*pixels.shape[:2], 1), np.float32)], 2)
        if pixels.shape[2] != channels:
            raise OsmapError(f"{path}: {pixels.shape[2]} channels, but {image.path} has "
                             f"{channels} (--exemplar needs the same, or the same without "
                             "alpha)")
        out.append(np.ascontiguousarray(pixels, np.float32))
    return tuple(out)


@dataclass(frozen=True)
class FillJob(SynthJob):
    """One image and where its outputs go. mode: inpaint (mask) or tileable (border)."""

    mode: str = "inpaint"
    mask: str | None = None  # a mask image's path, or "alpha" (inpaint)
    border: int = 0  # the requested band width, 0: automatic (tileable)
    exemplars: tuple = ()  # --exemplar paths: the hole is filled from them (inpaint)
    label: str = "osmap inpaint"

    def describe(self) -> dict:
        record = super().describe()
        record["size"] = None  # the image's size, known once it is read
        record["options"] = {**record["options"], "mode": self.mode,
                             **({"mask": self.mask} if self.mode == "inpaint" else
                                {"border": self.border})}
        if self.exemplars:
            record["exemplars"] = list(self.exemplars)
        return record

    def read(self) -> _FillInputs:
        from osmap_cli.imageio import read_image
        from osmap_cli.materials import load_aligned
        from osmap_cli.synth.fill import border_bands
        from osmap_cli.synth.options import FillOptions

        image = read_image(self.exemplar)
        if self.mode == "inpaint":
            free = read_mask(self.mask, image)
        else:
            try:
                band = FillOptions(border=self.border).band(image.pixels.shape[:2])
            except OsmapError as exc:
                raise OsmapError(f"{self.exemplar}: {exc}") from None
            free = border_bands(image.pixels.shape[:2], band)
        maps = [(spec, path, load_aligned(spec.path, image.pixels.shape, self.exemplar))
                for spec, path in self.withs]
        return _FillInputs(image, maps, free, exemplars=read_exemplars(self.exemplars, image))

    def sized(self, inputs) -> SynthJob:
        """This job with the options' size set to the image's."""
        h, w = inputs.image.pixels.shape[:2]
        return dataclasses.replace(self, options=self.options.replace(
            width=w, height=h, tileable=self.mode == "tileable"))

    def compute(self, inputs):
        from osmap_cli.progress import ProgressBar
        from osmap_cli.synth.fill import fill
        from osmap_cli.synth.job import announce
        from osmap_cli.synth.warm import ensure_compiled

        ensure_compiled(None if self.quiet else announce)  # as osmap synth: said, in parallel
        options = self.sized(inputs).options
        with ProgressBar(enabled=self.progress, desc=self.label) as progress:
            try:
                return fill(inputs.image.pixels, inputs.free, options,
                            source_free=self.mode == "tileable", progress=progress,
                            exemplars=inputs.exemplars)
            except OsmapError as exc:
                # name the files the refusal is about (the mask's, or the exemplars')
                named = ", ".join(self.exemplars) or (
                    self.mask if self.mask not in (None, "alpha") else self.exemplar)
                raise OsmapError(f"{named}: {exc}") from None

    def provenance(self, inputs, depth: int) -> tuple[list[str], dict, str]:
        image = inputs.image
        if self.mode == "inpaint":
            given = os.path.basename(self.mask) if self.mask != "alpha" else "alpha"
            more, extra = ["--mask", given], {"mask": given}
            if self.exemplars:
                names = [os.path.basename(e) for e in self.exemplars]
                more += [arg for name in names for arg in ("--exemplar", name)]
                extra["exemplars"] = ",".join(names)
        else:
            from osmap_cli.synth.options import FillOptions

            band = FillOptions(border=self.border).band(image.pixels.shape[:2])
            more = ["--border", str(self.border)] if self.border else []
            extra = {"border": str(band)}
        return fill_args(self.options, self.preset, self.preset_values, depth, more), extra, \
            self.mode

    def render_with(self, spec, mapped, inputs, result):
        """A --with map filled as the image was: kept pixels as they are, the free ones drawn
        through the fill's positions (the edge bands wrapping around for tileable)."""
        from osmap_cli.materials import render_map
        from osmap_cli.synth.fill import render_fill

        source_free = self.mode == "tileable"
        identity = np.eye(2)

        def draw(pixels, blend):
            renderer = map_renderer(result.positions, identity, source_free, blend)
            return render_map(dataclasses.replace(mapped, pixels=pixels), renderer, identity,
                              spec.normal, spec.path)

        return render_fill(draw, mapped.pixels, inputs.free, source_free, self.options.blend)
