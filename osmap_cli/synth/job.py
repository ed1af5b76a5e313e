"""One `osmap synth` job: an exemplar -> its texture, --with maps and --uv-out positions.

    read (exemplar, --with maps, fields) -> check (formats, channels) -> compute (synthesize)
    -> stage (every output in one transaction) -> commit

:class:`SynthJob` is what ``osmap synth`` plans, one per exemplar, and osmap_cli.batch runs.
Its staging is a template: ``sized``, ``provenance`` and ``render_with`` are what a job that
writes the same outputs another way overrides (osmap_cli.synth.fill_job.FillJob).
"""

from __future__ import annotations

import dataclasses
import os
import sys
from dataclasses import dataclass

from osmap_cli.batch import Job
from osmap_cli.errors import OsmapError
from osmap_cli.image_formats import FORMAT_LABELS, check_jpeg_channels
from osmap_cli.imageio import output_depth

__all__ = ["SynthJob", "UV_DESCRIPTION", "map_renderer", "synth_args"]

# the largest output (pixels) of a job that computes beside another (batch.Job.overlaps): at
# about 45 bytes a pixel (docs/performance.md, "Memory") two of them add some 400 MiB at most
OVERLAP_PIXELS = 2048 * 2048

UV_DESCRIPTION = ("u = exemplar column (x), v = exemplar row (y), in exemplar pixels; "
                  "(0, 0) is the centre of the top-left exemplar pixel")


def read_also(paths, image, exemplar: str) -> tuple:
    """The --also exemplars, each with the main exemplar's channel count."""
    from osmap_cli.imageio import read_image

    out = []
    for path in paths:
        other = read_image(path)
        if other.pixels.shape[2] != image.pixels.shape[2]:
            raise OsmapError(f"{path}: {other.pixels.shape[2]} channels, but {exemplar} has "
                             f"{image.pixels.shape[2]} (--also exemplars need the same)")
        out.append(other)
    return tuple(out)


def announce(line: str) -> None:
    print(line, file=sys.stderr, flush=True)


def synth_args(options, preset: str, preset_values: dict | None, bit_depth: int,
               orientation_field: str | None = None, scale_field: str | None = None
               ) -> list[str]:
    """Canonical `osmap synth` flags (no exemplar, no -o) that resolve to `options` again.

    `preset_values` is the built-in preset's table; None for a preset *file*, in which case
    every tunable is written out (the file may be gone or changed when the command is re-run).
    The plain numbers (the options that are neither tunables nor whole numbers: --scale,
    --orientation, --anisotropy) are written when they differ from their defaults.
    """
    from osmap_cli.options import flag, flag_args, number_text, option_spec

    defaults = type(options)()
    args = ["--size", f"{options.width}x{options.height}", "--seed", str(options.seed),
            "--preset", preset]
    for field in dataclasses.fields(options):
        spec = option_spec(options, field.name)
        value = getattr(options, field.name)
        if spec.kind is float and not spec.tunable and value != getattr(defaults, field.name):
            args += [flag(field.name), number_text(value)]
    if options.tileable:
        args.append("--tileable")
    if options.quality != "default":
        args += ["--quality", options.quality]
    if options.method != "osmap":
        args += ["--method", options.method]
    baseline = None if preset_values is None else defaults.replace(**preset_values)
    args += flag_args(options, baseline)
    args += ["--bit-depth", str(bit_depth)]
    if orientation_field:
        args += ["--orientation-field", os.path.basename(orientation_field)]
    if scale_field:
        args += ["--scale-field", os.path.basename(scale_field)]
    return args


def map_renderer(positions, jacobian, wrap: bool, blend: int):
    """draw(pixels): an aligned map rendered as the texture was (its positions, the
    output-to-exemplar `jacobian` (2, 2) or per pixel, `wrap` and seam `blend`), for
    materials.render_map."""
    import numpy as np

    from osmap_cli.synth.render import render

    field = np.broadcast_to(np.asarray(jacobian, np.float32), (*positions.shape[:2], 2, 2))
    return lambda pixels: render(pixels, positions, field, wrap, blend)


@dataclass(frozen=True)
class _Inputs:
    image: object  # osmap_cli.imageio.Image
    maps: list  # [(WithMap, output path, Image)]
    fields: object  # osmap_cli.fields.ControlFields or None
    also: tuple = ()  # Images of --also
    guides: dict | None = None  # synthesize's guide / target_guide (--guide, --target-guide)


@dataclass(frozen=True)
class SynthJob(Job):
    """One exemplar and where its outputs go."""

    index: int
    exemplar: str
    output: str
    options: object  # SynthOptions (validated)
    preset: str  # as recorded: a built-in name or a preset file's name
    preset_values: dict | None  # the built-in preset's table; None for a preset file
    bit_depth: str | None = None
    uv_out: str | None = None
    withs: tuple = ()  # ((WithMap with the path filled in, output path), ...)
    orientation_field: str | None = None
    scale_field: str | None = None
    also: tuple = ()  # more exemplars of the same material (--also)
    guide: str | None = None  # the exemplar's guide (--guide)
    target_guide: str | None = None  # the output's guide (--target-guide)
    replace: bool = True  # False: an existing output makes the job "skipped"
    refused: str | None = None  # why the job must not run (an output would replace an input)
    progress: bool = False
    quiet: bool = False
    verbose: bool = False  # the summary also says what the analysis found (the lattice)
    label: str = "osmap synth"

    @property
    def overlaps(self) -> bool:
        """Whether this job may compute beside another in one process (osmap_cli.batch): its
        kernels release the GIL, but not with a progress bar (one bar at a time), nor above
        OVERLAP_PIXELS, nor when its size comes from its input (a job that overrides sized:
        its memory is not known before it is read), nor when Numba's threading layer cannot
        take parallel kernels from two threads at once."""
        if self.progress or type(self).sized is not SynthJob.sized:
            return False
        if self.options.width * self.options.height > OVERLAP_PIXELS:
            return False
        from osmap_kernels import parallel_launches_threadsafe

        return parallel_launches_threadsafe()

    @property
    def outputs(self) -> list[str]:
        paths = [self.output] + [path for _, path in self.withs]
        return paths + ([self.uv_out] if self.uv_out else [])

    def recorded_options(self) -> dict:
        """The options as the record and the metadata store them."""
        recorded = dataclasses.asdict(self.options)
        if not self.target_guide:
            recorded.pop("guide_weight")  # plays no part without a guide
        return recorded

    def describe(self) -> dict:
        opts = self.options
        record = {"input": self.exemplar, "outputs": self.outputs,
                  "size": [opts.width, opts.height], "seed": opts.seed,
                  "options": {"preset": self.preset, **self.recorded_options()}}
        if self.also:
            record["also"] = list(self.also)
        if self.target_guide:
            record["target_guide"] = self.target_guide
            if self.guide:
                record["guide"] = self.guide
        return record

    def read(self) -> _Inputs:
        from osmap_cli.fields import load_fields
        from osmap_cli.imageio import read_image
        from osmap_cli.materials import load_aligned

        image = read_image(self.exemplar)
        maps = [(spec, path, load_aligned(spec.path, image.pixels.shape, self.exemplar))
                for spec, path in self.withs]
        fields = load_fields(self.orientation_field, self.scale_field,
                             (self.options.height, self.options.width), self.options.scale)
        if self.also:
            return _Inputs(image, maps, fields, read_also(self.also, image, self.exemplar))
        if self.target_guide:
            return _Inputs(image, maps, fields, guides=self._read_guides(image))
        return _Inputs(image, maps, fields)

    def _read_guides(self, image) -> dict:
        from osmap_cli.synth.guide import load_guide

        guides = {"target_guide": load_guide(self.target_guide, "--target-guide")}
        if self.guide:
            guide = load_guide(self.guide, "--guide")
            h, w = image.pixels.shape[:2]
            if guide.shape != (h, w):
                raise OsmapError(f"{self.guide}: {guide.shape[1]}x{guide.shape[0]}, but "
                                 f"{self.exemplar} is {w}x{h} (--guide needs the exemplar's "
                                 "size)")
            guides["guide"] = guide
        return guides

    def sized(self, inputs) -> SynthJob:
        """This job with its output size known (a synthesis: as asked)."""
        return self

    def check(self, inputs: _Inputs) -> None:
        from osmap_cli.memory import check_memory, texture_bytes

        job, image = self.sized(inputs), inputs.image
        width, height = job.options.width, job.options.height
        extra = sum(m.pixels.shape[2] for _, _, m in inputs.maps) + 2 * (self.uv_out is not None)
        check_memory(texture_bytes(width, height, image.pixels.shape[2], extra,
                                   atlas=bool(self.also)), f"a {width}x{height} texture")
        fmt, _ = output_depth(self.output, self.bit_depth, image.pixels.shape[2],
                              image.bit_depth)
        check_jpeg_channels(self.output, fmt, tuple(image.channel_names))
        for _, path, mapped in inputs.maps:
            fmt, _ = output_depth(path, self.bit_depth, mapped.pixels.shape[2], mapped.bit_depth)
            check_jpeg_channels(path, fmt, tuple(mapped.channel_names))

    def compute(self, inputs: _Inputs):
        from osmap_cli import synth
        from osmap_cli.progress import ProgressBar
        from osmap_cli.synth.warm import ensure_compiled

        # a first run compiles the kernels (two processes at once) and says so, unless --quiet
        ensure_compiled(None if self.quiet else announce)

        with ProgressBar(enabled=self.progress, desc=self.label) as progress:
            if inputs.also:
                from osmap_cli.synth.atlas import synthesize_several

                exemplars = [inputs.image.pixels, *(a.pixels for a in inputs.also)]
                return synthesize_several(exemplars, self.options, progress=progress)
            extra = {"fields": inputs.fields} if inputs.fields is not None else {}
            extra.update(inputs.guides or {})
            return synth.synthesize(inputs.image.pixels, self.options, progress=progress,
                                    **extra)

    def provenance(self, inputs, depth: int) -> tuple[list[str], dict, str]:
        """(canonical flags, extra metadata, command) for the outputs' provenance."""
        args = synth_args(self.options, self.preset, self.preset_values, depth,
                          self.orientation_field, self.scale_field)
        extra = {}
        if self.target_guide:
            if self.guide:
                args += ["--guide", os.path.basename(self.guide)]
                extra["guide"] = os.path.basename(self.guide)
            args += ["--target-guide", os.path.basename(self.target_guide)]
            extra["target_guide"] = os.path.basename(self.target_guide)
        if self.also:
            names = [os.path.basename(a) for a in self.also]
            args += [arg for name in names for arg in ("--also", name)]
            extra["also"] = ",".join(names)
        if self.orientation_field:
            extra["orientation_field"] = os.path.basename(self.orientation_field)
        if self.scale_field:
            extra["scale_field"] = os.path.basename(self.scale_field)
        return args, extra, "synth"

    def render_with(self, spec, mapped, inputs, result):
        """A --with map (materials.WithMap SPEC, its Image MAPPED) rendered like the texture."""
        from osmap_cli.materials import render_map
        from osmap_cli.synth.render import render_settings

        jacobian = result.jacobian if result.jacobian is not None else self.options.jacobian()
        draw = map_renderer(result.positions, jacobian, *render_settings(self.options))
        return render_map(mapped, draw, jacobian, spec.normal, spec.path)

    def stage(self, outputs, inputs: _Inputs, result) -> tuple[str, list[str]]:
        from osmap_cli.imageio import encode_image
        from osmap_cli.provenance import image_metadata

        job, image = self.sized(inputs), inputs.image
        channels = image.pixels.shape[2]
        fmt, depth = output_depth(self.output, self.bit_depth, channels, image.bit_depth)
        args, extra, command = job.provenance(inputs, depth)
        extra.update(lattice_meta(result))
        recorded = job.recorded_options()

        def meta(role, more_args=(), more_extra=None):
            return image_metadata(recorded, self.preset, self.exemplar, image.pixels.shape,
                                  args + list(more_args), role, {**extra, **(more_extra or {})},
                                  command=command)

        def stage_image(path, pixels, bits, names, metadata):
            outputs.stage(path, lambda temp: encode_image(temp, pixels, bits, names, metadata,
                                                          name=path))

        stage_image(self.output, result.pixels, depth, tuple(image.channel_names),
                    meta("image"))
        for spec, path, mapped in inputs.maps:
            _, map_depth = output_depth(path, self.bit_depth, mapped.pixels.shape[2],
                                        mapped.bit_depth)
            pixels = job.render_with(spec, mapped, inputs, result)
            source = os.path.basename(spec.path)
            stage_image(path, pixels, map_depth, tuple(mapped.channel_names),
                        meta(f"with:{spec.name}", ["--with", f"{spec.name}={source}"],
                             {"source": source, "normal_map": str(spec.normal).lower()}))
        if self.uv_out is not None:
            uv = result.positions[..., ::-1]  # (row, col) -> (u = col, v = row)
            ext = os.path.splitext(self.output)[1].lower()
            stage_image(self.uv_out, uv, 32, ("u", "v"),
                        meta("uv", (), {"uv_channels": UV_DESCRIPTION, "image_ext": ext}))
        return verbose_summary(self, job._summary(fmt, depth, channels, inputs), result)

    def _summary(self, fmt: str, depth: int, channels: int, inputs: _Inputs):
        kept = channels - 1 if fmt == "jpeg" and channels in (2, 4) else channels
        sample = {16: "half", 32: "float"}[depth] if fmt == "openexr" else f"{depth}-bit"
        if fmt == "tiff" and depth == 32:
            sample = "float"
        line = (f"wrote {self.output}: {self.options.width}x{self.options.height}, {kept} "
                f"channel{'s' * (kept != 1)}, {sample} {FORMAT_LABELS[fmt]}")
        if inputs.maps:
            line += "; " + ", ".join(f"{spec.name} in {path}" for spec, path, _ in inputs.maps)
        if self.uv_out is not None:
            line += f"; positions in {self.uv_out}"
        warnings = []
        if fmt == "jpeg" and channels in (2, 4):
            warnings.append(f"{self.output}: JPEG cannot store alpha; the alpha channel was "
                            "dropped")
        return line, warnings


def lattice_meta(result) -> dict:
    """The lattice the output keeps, for its provenance (none for the paper method)."""
    from osmap_cli.synth.regular import lattice_text

    return {"lattice": lattice_text(getattr(result, "lattice", None))}


def verbose_summary(job, summary, result):
    """(line, warnings) with what the analysis found appended when the job is verbose."""
    if not job.verbose:
        return summary
    from osmap_cli.synth.regular import describe

    line, warnings = summary
    return f"{line}; lattice: {describe(getattr(result, 'lattice', None))}", warnings
