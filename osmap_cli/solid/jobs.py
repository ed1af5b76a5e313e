"""`osmap solid` jobs: one exemplar (or one --x/--y/--z set) -> its volume and extras.

A :class:`SolidJob` runs under osmap_cli.batch.run_jobs like a synth job (one at a time or in
worker processes, reported as a line or a JSON object); :meth:`SolidJob.run` does what a single
`osmap solid X -o OUT` does: read, check, synthesize, write every output or none.
"""

from __future__ import annotations

import dataclasses
import time

from osmap_cli.errors import OsmapError


@dataclasses.dataclass(frozen=True)
class SolidJob:
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

    @property
    def outputs(self) -> list[str]:
        return [self.output] + [p for p in (self.uv_out, self.preview) if p is not None]

    def describe(self) -> dict:
        """The JSON record's job fields (input, outputs, size, seed, options)."""
        opts = self.options
        record = {"input": self.exemplar, "outputs": self.outputs,
                  "size": [opts.width, opts.height, opts.depth], "seed": opts.seed,
                  "options": {"preset": self.preset, **dataclasses.asdict(opts)}}
        if len(self.files) == 3:
            record["axis_inputs"] = list(self.files)
        return record

    def run(self) -> dict:
        return run_solid_job(self)


def _read_exemplars(files):
    from osmap_cli.imageio import read_image

    cache = {}
    for f in files:
        if f not in cache:
            cache[f] = read_image(f)
    images = [cache[f] for f in files]
    channels = {im.pixels.shape[2] for im in images}
    if len(channels) != 1:
        counts = ", ".join(f"{n}: {im.pixels.shape[2]}" for n, im in zip(files, images))
        raise OsmapError(f"per-axis exemplars need the same number of channels ({counts})")
    for name, im in zip(files, images):
        if min(im.pixels.shape[:2]) < 8:
            raise OsmapError(f"{name}: exemplar is smaller than 8x8 pixels")
    return images


def run_solid_job(job: SolidJob) -> dict:
    """Synthesize one job's volume; returns its record (status "ok" or "skipped").

    Raises OsmapError for a bad input or output (nothing is written then).
    """
    from osmap_cli.batch import job_record, skip_or_refuse

    started = time.monotonic()
    skipped = skip_or_refuse(job, started)
    if skipped is not None:
        return skipped
    from osmap_cli.solid import volumeio
    from osmap_cli.solid.command import provenance

    images = _read_exemplars(job.files)
    options, output, kind = job.options, job.output, job.kind
    volumeio.check_target(output, kind)
    channels = images[0].pixels.shape[2]
    depth = 16 if max(im.bit_depth for im in images) >= 16 else 8
    if kind in ("png", "atlas") and channels > 4:
        raise OsmapError(f"{output}: PNG stores at most 4 channels, the exemplar has {channels}; "
                         "use --format exr, npy or nrrd")
    if kind == "atlas":
        volumeio.atlas_grid(output, options.depth)
    for path in (job.preview, job.uv_out):
        if path is not None:
            volumeio.check_target(path, "npy")

    from osmap_cli.solid.memory import check_memory

    check_memory(options.shape, channels, options.feature_dims)

    from osmap_cli.progress import ProgressBar
    from osmap_cli.solid.pipeline import synthesize_solid

    pixels = [im.pixels for im in images]
    with ProgressBar(enabled=job.progress, desc="osmap solid") as progress:
        result = synthesize_solid(pixels, options, progress=progress)

    # the outputs, all or nothing
    names = list(job.files) if len(job.files) == 3 else [job.files[0]]
    metadata = provenance(options, job.preset, names)
    staged = []
    try:
        staged.append(volumeio.stage_volume(
            output, result.voxels, kind, depth=depth, channel_names=images[0].channel_names,
            metadata=metadata, encoding=job.nrrd_encoding))
        if job.uv_out is not None:
            staged.append(volumeio.stage_npy(job.uv_out, result.uv()))
        if job.preview is not None:
            from osmap_cli.solid.command import stage_preview

            staged.append(stage_preview(job.preview, result.voxels, metadata))
        volumeio.commit(staged)
        staged = []
    finally:
        volumeio.discard(staged)

    line = f"wrote {output}: {options.width}x{options.height}x{options.depth} voxels, " \
           f"{channels} channel{'s' * (channels != 1)}, {kind}"
    if kind == "atlas":
        cols, rows = volumeio.atlas_grid(output, options.depth)
        line += f" {cols}x{rows}"
    extras = [p for p in (job.uv_out, job.preview) if p is not None]
    if extras:
        line += "; also " + ", ".join(extras)
    record = job_record(job, "ok", started)
    record["_line"] = f"{line} ({record['seconds']:.1f} s)"
    return record


def default_name(kind: str) -> tuple[str, str]:
    """(default --name template, the {ext} field) for an output format."""
    ext = {"npy": "npy", "nrrd": "nrrd", "atlas": "png", "png": "png", "exr": "exr"}[kind]
    return ("{stem}" if kind in ("png", "exr") else "{stem}.{ext}"), ext


__all__ = ["SolidJob", "default_name", "run_solid_job"]
