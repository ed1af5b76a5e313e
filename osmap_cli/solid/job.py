"""One `osmap solid` job: an exemplar (or one --x/--y/--z set) -> its volume and extras.

    read (the exemplars) -> check (formats, channels, memory) -> compute (synthesize_solid)
    -> stage (volume, --uv-out, --preview in one transaction) -> commit
"""

from __future__ import annotations

import dataclasses
import json
from dataclasses import dataclass

from osmap_cli.batch import Job
from osmap_cli.errors import OsmapError

__all__ = ["ExemplarSetJob", "SolidJob", "solid_args"]


def solid_args(options, preset: str) -> list[str]:
    """Canonical `osmap solid` flags (no exemplar, no -o) that resolve to `options` again: the
    tunables that differ from the built-in preset's table (all of them for another preset)."""
    from osmap_cli.options import flag_args, number_text
    from osmap_cli.presets import builtin_names, load_preset
    from osmap_cli.solid.options import SolidOptions

    defaults = SolidOptions()
    args = ["--size", f"{options.width}x{options.height}x{options.depth}", "--seed",
            str(options.seed), "--preset", preset]
    if options.tileable:
        args.append("--tileable")
    if options.quality != defaults.quality:
        args += ["--quality", options.quality]
    if options.angles != defaults.angles:
        args += ["--orientation", ",".join(number_text(a) for a in options.angles)]
    baseline = (defaults.replace(**load_preset(preset, "solid"))
                if preset in builtin_names("solid") else None)
    return args + flag_args(options, baseline)


class ExemplarSetJob(Job):
    """A job on one exemplar or one --x/--y/--z set (its fields `exemplar` and `files`): reads
    and checks the set, and its record names every file of it."""

    def read(self) -> list:
        return read_exemplars(self.files)

    def check(self, images) -> None:
        check_exemplars(self.files, images)

    def exemplar_record(self, **fields) -> dict:
        """The job's record: input, outputs, FIELDS, and the per-axis inputs of a set."""
        record = {"input": self.exemplar, "outputs": self.outputs, **fields}
        if len(self.files) == 3:
            record["axis_inputs"] = list(self.files)
        return record


@dataclass(frozen=True)
class SolidJob(ExemplarSetJob):
    """One solid synthesis and where its outputs go."""

    index: int
    exemplar: str  # EXEMPLAR, or the --x file when EXEMPLAR was omitted (names the job)
    files: tuple  # the exemplar of each slice family (x, y, z); one entry: the same for all
    output: str
    kind: str  # volumeio format
    options: object  # SolidOptions (validated)
    preset: str
    nrrd_encoding: str = "raw"
    preview: str | None = None
    uv_out: str | None = None
    replace: bool = True  # False: an existing output makes the job "skipped"
    refused: str | None = None
    progress: bool = False
    verbose: bool = False  # the summary line starts with what the method found and did

    @property
    def outputs(self) -> list[str]:
        return [self.output] + [p for p in (self.uv_out, self.preview) if p is not None]

    def describe(self) -> dict:
        opts = self.options
        return self.exemplar_record(size=[opts.width, opts.height, opts.depth], seed=opts.seed,
                                    options={"preset": self.preset, **dataclasses.asdict(opts)})

    def check(self, images) -> None:
        from osmap_cli.memory import check_memory, structure_bytes, volume_bytes
        from osmap_cli.solid import volumeio

        super().check(images)
        volumeio.check_target(self.output, self.kind)
        count = images[0].pixels.shape[2]
        if self.kind in ("png", "atlas") and count > 4:
            raise OsmapError(f"{self.output}: PNG stores at most 4 channels, the exemplar has "
                             f"{count}; use --format exr, npy or nrrd")
        if self.kind == "atlas":
            volumeio.atlas_grid(self.output, self.options.depth)
        for path in (self.preview, self.uv_out):
            if path is not None:
                volumeio.check_target(path, "npy")
        z, y, x = self.options.shape
        what = f"a {x}x{y}x{z} volume"
        made = self.options.synthesis_shape()
        if made != self.options.shape:
            what += f" (turned: {made[2]}x{made[1]}x{made[0]} voxels of material)"
        need = volume_bytes(made, count, self.options.feature_dims)
        if self.options.method == "structure":
            need += structure_bytes(made)
        check_memory(need, what)

    def compute(self, images):
        from osmap_cli.progress import ProgressBar
        from osmap_cli.solid.pipeline import synthesize_solid

        with ProgressBar(enabled=self.progress, desc="osmap solid") as progress:
            return synthesize_solid([im.pixels for im in images], self.options,
                                    progress=progress)

    def stage(self, outputs, images, result) -> tuple[str, list[str]]:
        from osmap_cli.imageio import encode_image
        from osmap_cli.provenance import volume_metadata
        from osmap_cli.solid import volumeio
        from osmap_cli.solid.preview import render_preview

        options = self.options
        names = list(self.files) if len(self.files) == 3 else [self.files[0]]
        metadata = volume_metadata(options, self.preset, names, solid_args(options, self.preset))
        if result.provenance is not None:
            metadata["structure"] = json.dumps(result.provenance, sort_keys=True)
        depth = 16 if max(im.bit_depth for im in images) >= 16 else 8
        write, folder = volumeio.volume_writer(
            self.output, result.voxels, self.kind, depth=depth,
            channel_names=images[0].channel_names, metadata=metadata,
            encoding=self.nrrd_encoding)
        outputs.stage(self.output, write, folder=folder)
        if self.uv_out is not None:
            outputs.stage(self.uv_out, lambda temp: volumeio.write_npy(temp, result.uv()))
        if self.preview is not None:
            outputs.stage(self.preview, lambda temp: encode_image(
                temp, render_preview(result.voxels), 8, metadata=metadata, name=self.preview))

        channels = images[0].pixels.shape[2]
        line = (f"wrote {self.output}: {options.width}x{options.height}x{options.depth} voxels, "
                f"{channels} channel{'s' * (channels != 1)}, {self.kind}")
        if self.kind == "atlas":
            cols, rows = volumeio.atlas_grid(self.output, options.depth)
            line += f" {cols}x{rows}"
        extras = [p for p in (self.uv_out, self.preview) if p is not None]
        if extras:
            line += "; also " + ", ".join(extras)
        if self.verbose and result.report:
            line = "\n".join([*result.report, line])
        return line, []


def read_exemplars(files) -> list:
    """The images of FILES in order, each distinct file read once."""
    from osmap_cli.imageio import read_image

    cache = {}
    for f in files:
        if f not in cache:
            cache[f] = read_image(f)
    return [cache[f] for f in files]


def check_exemplars(files, images) -> None:
    """OsmapError unless the exemplars share a channel count, are 8x8 or larger and finite."""
    import numpy as np

    if len({im.pixels.shape[2] for im in images}) != 1:
        counts = ", ".join(f"{n}: {im.pixels.shape[2]}" for n, im in zip(files, images))
        raise OsmapError(f"per-axis exemplars need the same number of channels ({counts})")
    for name, im in zip(files, images):
        if min(im.pixels.shape[:2]) < 8:
            raise OsmapError(f"{name}: exemplar is smaller than 8x8 pixels")
        if not np.all(np.isfinite(im.pixels)):
            raise OsmapError(f"{name}: the exemplar has NaN or infinite pixel values")
