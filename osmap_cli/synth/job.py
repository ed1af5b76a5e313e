"""One `osmap synth` job: an exemplar -> its texture, --with maps and --uv-out positions.

    read (exemplar, --with maps, fields) -> check (formats, channels) -> compute (synthesize)
    -> stage (every output in one transaction) -> commit

:class:`SynthJob` is what ``osmap synth`` plans, one per exemplar, and osmap_cli.batch runs.
"""

from __future__ import annotations

import dataclasses
import os
import sys
from dataclasses import dataclass

from osmap_cli.batch import Job
from osmap_cli.errors import OsmapError
from osmap_cli.imageio import output_depth

__all__ = ["SynthJob", "UV_DESCRIPTION"]

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


def _refuse_jpeg_channels(path: str, names) -> None:
    if os.path.splitext(path)[1].lower() in (".jpg", ".jpeg") and len(names) in (2, 4) \
            and names[-1] != "A":
        raise OsmapError(f"{path}: JPEG cannot store {len(names)} channels "
                         f"({', '.join(names)}); use .png, .tif or .exr")


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
    def outputs(self) -> list[str]:
        paths = [self.output] + [path for _, path in self.withs]
        return paths + ([self.uv_out] if self.uv_out else [])

    def describe(self) -> dict:
        opts = self.options
        recorded = dataclasses.asdict(opts)
        if not self.target_guide:
            recorded.pop("guide_weight")  # plays no part without a guide
        record = {"input": self.exemplar, "outputs": self.outputs,
                  "size": [opts.width, opts.height], "seed": opts.seed,
                  "options": {"preset": self.preset, **recorded}}
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

    def check(self, inputs: _Inputs) -> None:
        from osmap_cli.memory import check_memory, texture_bytes

        image = inputs.image
        extra = sum(m.pixels.shape[2] for _, _, m in inputs.maps) + 2 * (self.uv_out is not None)
        check_memory(texture_bytes(self.options.width, self.options.height,
                                   image.pixels.shape[2], extra, atlas=bool(self.also)),
                     f"a {self.options.width}x{self.options.height} texture")
        output_depth(self.output, self.bit_depth, image.pixels.shape[2], image.bit_depth)
        _refuse_jpeg_channels(self.output, tuple(image.channel_names))
        for _, path, mapped in inputs.maps:
            output_depth(path, self.bit_depth, mapped.pixels.shape[2], mapped.bit_depth)
            _refuse_jpeg_channels(path, tuple(mapped.channel_names))

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

    def stage(self, outputs, inputs: _Inputs, result) -> tuple[str, list[str]]:
        from osmap_cli.imageio import encode_image
        from osmap_cli.materials import render_map
        from osmap_cli.provenance import image_metadata, synth_args
        from osmap_cli.synth.render import render_settings

        options, image = self.options, inputs.image
        channels = image.pixels.shape[2]
        fmt, depth = output_depth(self.output, self.bit_depth, channels, image.bit_depth)
        args = synth_args(options, self.preset, self.preset_values, depth,
                          self.orientation_field, self.scale_field)
        fields_meta = {}
        if self.target_guide:
            if self.guide:
                args += ["--guide", os.path.basename(self.guide)]
                fields_meta["guide"] = os.path.basename(self.guide)
            args += ["--target-guide", os.path.basename(self.target_guide)]
            fields_meta["target_guide"] = os.path.basename(self.target_guide)
        if self.also:
            names = [os.path.basename(a) for a in self.also]
            args += [arg for name in names for arg in ("--also", name)]
            fields_meta["also"] = ",".join(names)
        if self.orientation_field:
            fields_meta["orientation_field"] = os.path.basename(self.orientation_field)
        if self.scale_field:
            fields_meta["scale_field"] = os.path.basename(self.scale_field)
        fields_meta.update(lattice_meta(result))

        def meta(role, more_args=(), extra=None):
            return image_metadata(options, self.preset, self.exemplar, image.pixels.shape,
                                  args + list(more_args), role, {**fields_meta, **(extra or {})})

        def stage_image(path, pixels, bits, names, metadata):
            outputs.stage(path, lambda temp: encode_image(temp, pixels, bits, names, metadata,
                                                          name=path))

        stage_image(self.output, result.pixels, depth, tuple(image.channel_names),
                    meta("image"))
        jacobian = result.jacobian if result.jacobian is not None else options.jacobian()
        for spec, path, mapped in inputs.maps:
            _, map_depth = output_depth(path, self.bit_depth, mapped.pixels.shape[2],
                                        mapped.bit_depth)
            pixels = render_map(mapped, result.positions, jacobian, spec.normal, spec.path,
                                *render_settings(options))
            source = os.path.basename(spec.path)
            stage_image(path, pixels, map_depth, tuple(mapped.channel_names),
                        meta(f"with:{spec.name}", ["--with", f"{spec.name}={source}"],
                             {"source": source, "normal_map": str(spec.normal).lower()}))
        if self.uv_out is not None:
            uv = result.positions[..., ::-1]  # (row, col) -> (u = col, v = row)
            ext = os.path.splitext(self.output)[1].lower()
            stage_image(self.uv_out, uv, 32, ("u", "v"),
                        meta("uv", (), {"uv_channels": UV_DESCRIPTION, "image_ext": ext}))
        return verbose_summary(self, self._summary(fmt, depth, channels, inputs), result)

    def _summary(self, fmt: str, depth: int, channels: int, inputs: _Inputs):
        kept = channels - 1 if fmt == "jpeg" and channels in (2, 4) else channels
        label = {"png": "PNG", "openexr": "EXR", "tiff": "TIFF", "jpeg": "JPEG"}[fmt]
        sample = {16: "half", 32: "float"}[depth] if fmt == "openexr" else f"{depth}-bit"
        if fmt == "tiff" and depth == 32:
            sample = "float"
        line = (f"wrote {self.output}: {self.options.width}x{self.options.height}, {kept} "
                f"channel{'s' * (kept != 1)}, {sample} {label}")
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
