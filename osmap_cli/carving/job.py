"""One `osmap carve` job: a mesh and a material -> the carved mesh, its texture map, the maps of
its material set and a preview.

    read (mesh, volume or exemplars, --with maps) -> check (mesh, volume kind, channels, memory)
    -> compute (synthesize the volume if asked, carve) -> stage (texture, maps, mesh + MTL,
    preview in one transaction) -> commit
"""

from __future__ import annotations

import dataclasses
import json
import os
import shlex
import tempfile
from dataclasses import dataclass

from osmap_cli.batch import Job
from osmap_cli.errors import OsmapError

__all__ = ["CarveJob", "Material", "carve_args", "carve_bytes", "reproduce"]

PREVIEW_SIZE = 384


@dataclass(frozen=True)
class Material:
    """Where the volume comes from: a volume file (`volume`), or exemplars synthesized with
    `solid` (SolidOptions) and preset `preset`; `files`: the x, y, z exemplars (one entry: the
    same for all); `tileable`: --tileable given (a volume file's own flag is read from it)."""

    volume: str | None = None
    files: tuple = ()
    solid: object = None
    preset: str = "default"
    preset_values: dict | None = None
    tileable: bool = False

    @property
    def synthesized(self) -> bool:
        return self.volume is None

    def names(self) -> list[str]:
        return [self.volume] if self.volume else list(dict.fromkeys(self.files))


@dataclass(frozen=True)
class _Inputs:
    mesh: object  # carve Mesh
    volume: object  # float32 (Z, Y, X, C), or None until synthesized
    tileable: bool
    images: list  # the exemplars' Images (synthesis)
    withs: list  # [(name, output path, volume or [Image, ...])]


def carve_bytes(texels: int, channels: int, maps: int, voxels: int, vertices: int) -> int:
    """Peak working set of a carve, kept on the safe side: per texel the triangle index (twice
    while padding), two masks, and per channel of every map the colours, a copy and the
    encoder's temporaries (20 bytes); the volume (and a converted copy); per vertex the mesh,
    its topology and normals; and the preview. BENCHMARKS.md "Carve" measured 427 MiB at
    2048x2048 and 1062 MiB at 4096x4096 (RGB, 128^3 volume); this gives 1.4x that."""
    from osmap_cli.memory import BASE_BYTES

    per_texel = 4 * 2 + 2 + 20 * channels * (1 + maps)
    preview = 3 * (2 * PREVIEW_SIZE) ** 2 * (4 + 8 + 12)
    return (BASE_BYTES + texels * per_texel + voxels * channels * 4 * 2 + vertices * 200
            + preview)


@dataclass(frozen=True)
class CarveJob(Job):
    """One mesh and where its outputs go."""

    index: int
    exemplar: str  # the mesh (names the job)
    output: str
    material: Material
    options: object  # CarveOptions (validated)
    texture: str | None = None  # the colour map (None with vertex colours)
    withs: tuple = ()  # ((NAME, source path or paths, output path), ...)
    bit_depth: int | None = None
    preview: str | None = None
    replace: bool = True
    refused: str | None = None
    progress: bool = False

    @property
    def outputs(self) -> list[str]:
        from osmap_cli.carving.meshio import mtl_path

        paths = [self.output]
        if self.output.lower().endswith(".obj"):
            paths.append(mtl_path(self.output))
        paths += [p for p in (self.texture, self.preview) if p is not None]
        return paths + [out for _, _, out in self.withs]

    def describe(self) -> dict:
        width, height = self.options.texture_size
        record = {"input": self.exemplar, "outputs": self.outputs,
                  "texture_size": None if self.options.vertex_colors else [width, height],
                  "options": dataclasses.asdict(self.options)}
        material = self.material
        if material.synthesized:
            solid = material.solid
            record.update(exemplars=list(material.files), seed=solid.seed,
                          volume_options={"preset": material.preset,
                                          **dataclasses.asdict(solid)})
        else:
            record["volume"] = material.volume
        return record

    # -- read, check ---------------------------------------------------------------------------

    def read(self) -> _Inputs:
        from osmap_cli.carving.meshio import read_mesh
        from osmap_cli.carving.volume import read_volume_file
        from osmap_cli.imageio import read_image

        mesh = read_mesh(self.exemplar)
        material = self.material
        volume, tileable, images = None, material.tileable, []
        if material.synthesized:
            cache = {}
            for f in material.files:
                if f not in cache:
                    cache[f] = read_image(f)
            images = [cache[f] for f in material.files]
        else:
            volume, own = read_volume_file(material.volume)
            tileable = tileable or own
        withs = []
        for name, source, out in self.withs:
            if material.synthesized:
                withs.append((name, out, [read_image(p) for p in source]))
            else:
                withs.append((name, out, read_volume_file(source)[0]))
        return _Inputs(mesh, volume, tileable, images, withs)

    def check(self, inputs: _Inputs) -> None:
        import numpy as np

        from osmap_cli.carving.mesh import check_mesh
        from osmap_cli.imageio import output_format
        from osmap_cli.memory import volume_bytes

        options = self.options
        check_mesh(inputs.mesh, need_uv=not options.vertex_colors and not options.atlas)
        material = self.material
        if material.synthesized:
            channels = {im.pixels.shape[2] for im in inputs.images}
            if len(channels) != 1:
                raise OsmapError("per-axis exemplars need the same number of channels")
            channels = channels.pop()
            for name, im in zip(material.files, inputs.images):
                if min(im.pixels.shape[:2]) < 8:
                    raise OsmapError(f"{name}: exemplar is smaller than 8x8 pixels")
                if not np.all(np.isfinite(im.pixels)):
                    raise OsmapError(f"{name}: the exemplar has NaN or infinite pixel values")
            if channels > 4:
                raise OsmapError(f"{material.files[0]}: {channels} channels; a carved colour "
                                 "map holds 1 to 4")
            shape = material.solid.synthesis_shape()
            voxels = shape[0] * shape[1] * shape[2]
            extra = volume_bytes(shape, channels, material.solid.feature_dims)
            for name, _, images in inputs.withs:
                for image, exemplar, source in zip(images, inputs.images, material.files):
                    if image.pixels.shape[:2] != exemplar.pixels.shape[:2]:
                        h, w = exemplar.pixels.shape[:2]
                        raise OsmapError(f"{image.path}: --with {name}: the map is not the "
                                         f"size of the exemplar {source} ({w}x{h}); maps "
                                         "must be aligned with their exemplar")
        else:
            channels = inputs.volume.shape[3]
            voxels = int(np.prod(inputs.volume.shape[:3]))
            extra = 0
            for name, _, other in inputs.withs:
                if other.shape[:3] != inputs.volume.shape[:3]:
                    raise OsmapError(f"--with {name}: the volume is {_size(other)} voxels, "
                                     f"{material.volume} is {_size(inputs.volume)}; aligned "
                                     "volumes have the same size")
        if self.texture is not None:
            output_format(self.texture, self.bit_depth, channels)
        width, height = options.texture_size
        texels = 0 if options.vertex_colors else width * height
        need = carve_bytes(texels, channels, len(self.withs), voxels,
                           len(inputs.mesh.vertices)) + extra
        _check_memory(need, width, height, options.vertex_colors)

    # -- compute -------------------------------------------------------------------------------

    def compute(self, inputs: _Inputs):
        from osmap_cli.carving.bake import carve

        material = self.material
        volume, aligned = inputs.volume, {}
        if material.synthesized:
            from osmap_cli.carving.volume import synthesized
            from osmap_cli.solid import render_volume

            result = synthesized(material.files, inputs.images, material.solid)
            volume = result.voxels
            for name, _, images in inputs.withs:
                aligned[name] = render_volume(result.uv(), [im.pixels for im in images])
        else:
            aligned = {name: other for name, _, other in inputs.withs}
        options = self.options.replace(wrap=self.options.wrap or inputs.tileable)
        return carve(inputs.mesh, volume, options, aligned)

    # -- stage ---------------------------------------------------------------------------------

    def stage(self, outputs, inputs: _Inputs, result) -> tuple[str, list[str]]:
        from osmap_cli.carving import meshio
        from osmap_cli.imageio import encode_image
        from osmap_cli.output import write_bytes

        base = self.metadata(inputs.tileable)

        def meta(role: str) -> dict:
            return {**base, "role": role}

        png = None
        if self.texture is not None:
            depth = self.bit_depth
            captured = {}

            def write_texture(temp: str) -> None:
                encode_image(temp, result.texture, depth, metadata=meta("texture"),
                             name=self.texture)
                captured["path"] = temp

            outputs.stage(self.texture, write_texture)
            png = _embedded_png(self.texture, depth, result.texture, captured.get("path"),
                                meta("texture"))
            for name, out in ((n, o) for n, o, _ in inputs.withs):
                outputs.stage(out, lambda temp, n=name, o=out: encode_image(
                    temp, result.maps[n], depth, metadata=meta(f"with:{n}"), name=o))
        mesh = result.mesh
        files = meshio.mesh_files(self.output, mesh.vertices, mesh.faces, result.normals,
                                  mesh.uv if self.texture is not None else None,
                                  result.vertex_colors, png, self.texture or "", meta("mesh"))
        for target, data in files:
            outputs.stage(target, lambda temp, d=data: write_bytes(temp, d))
        if self.preview is not None:
            from osmap_cli.carving.preview import render_preview

            outputs.stage(self.preview, lambda temp: encode_image(
                temp, render_preview(result, PREVIEW_SIZE), 8, metadata=meta("preview"),
                name=self.preview))
        return self._summary(result), list(result.warnings)

    def _summary(self, result) -> str:
        mesh = result.mesh
        line = f"wrote {self.output}: {len(mesh.faces)} triangles"
        if self.texture is not None:
            h, w, c = result.texture.shape
            covered = 100.0 * float(result.covered.mean())
            line += f", {self.texture} {w}x{h} ({covered:.0f}% of the texels covered)"
        else:
            line += f", {len(mesh.vertices)} vertex colours"
        extras = [out for _, _, out in self.withs] + ([self.preview] if self.preview else [])
        if extras:
            line += "; also " + ", ".join(extras)
        return line

    # -- provenance ----------------------------------------------------------------------------

    def metadata(self, tileable: bool) -> dict:
        from osmap_cli.provenance import header

        material = self.material
        options = dataclasses.asdict(self.options.replace(wrap=self.options.wrap or tileable))
        meta = {**header("carve"), "mesh": os.path.basename(self.exemplar),
                "mesh_output": os.path.basename(self.output),
                "args": shlex.join(carve_args(self)), "options": json.dumps(options,
                                                                            sort_keys=True)}
        if self.texture is not None:
            meta["texture"] = os.path.basename(self.texture)
        if material.synthesized:
            names = [os.path.basename(n) for n in material.files]
            meta.update(exemplar=names[0] if len(set(names)) == 1 else ",".join(names),
                        preset=material.preset, seed=str(material.solid.seed),
                        volume_options=json.dumps(dataclasses.asdict(material.solid),
                                                  sort_keys=True))
        else:
            meta["volume"] = os.path.basename(material.volume)
        return meta


def _size(volume) -> str:
    z, y, x = volume.shape[:3]
    return f"{x}x{y}x{z}"


def _check_memory(need: int, width: int, height: int, vertex_colors: bool) -> None:
    from osmap_cli.memory import ENV_LIMIT, available_bytes, human

    have = available_bytes()
    if need > have:
        what = "this carve" if vertex_colors else f"a {width}x{height} texture map"
        limited = f" (limited by {ENV_LIMIT})" if os.environ.get(ENV_LIMIT, "").strip() else ""
        raise OsmapError(f"{what} needs about {human(need)} of memory, but only {human(have)} "
                         f"is available{limited}; use a smaller --texture-size (or --size)")


def _embedded_png(texture: str, depth, pixels, written: str | None, metadata: dict) -> bytes:
    """The PNG a glTF embeds: the texture file's own bytes when it is an 8-bit RGB(A) PNG,
    else the map encoded so (grey expanded to RGB)."""
    import numpy as np

    from osmap_cli.imageio import encode_image

    channels = pixels.shape[2]
    plain = texture.lower().endswith(".png") and depth in (None, 8) and channels in (3, 4)
    if plain and written is not None:
        with open(written, "rb") as handle:
            return handle.read()
    if channels < 3:
        grey = np.repeat(pixels[..., :1], 3, axis=2)
        pixels = grey if channels == 1 else np.concatenate([grey, pixels[..., 1:2]], axis=2)
    with tempfile.TemporaryDirectory(prefix="osmap-carve-") as folder:
        path = os.path.join(folder, "texture.png")
        encode_image(path, pixels, 8, metadata=metadata, name=texture)
        with open(path, "rb") as handle:
            return handle.read()


# ---------------------------------------------------------------------------------------------
# the command line that makes the same files


def carve_args(job: CarveJob) -> list[str]:
    """Canonical `osmap carve` flags (no mesh, no -o) that make the job's outputs again."""
    from osmap_cli.carving.options import CarveOptions
    from osmap_cli.options import flag_args, number_text
    from osmap_cli.solid.options import SolidOptions

    options, material = job.options, job.material
    default = CarveOptions()
    args = []
    if material.synthesized:
        files = [os.path.basename(f) for f in material.files]
        args += ["--exemplar", files[0]] if len(files) == 1 else \
            ["--x", files[0], "--y", files[1], "--z", files[2]]
        solid = material.solid
        args += ["--size", f"{solid.width}x{solid.height}x{solid.depth}", "--seed",
                 str(solid.seed), "--preset", material.preset]
        if solid.quality != "default":
            args += ["--quality", solid.quality]
        if solid.tileable:
            args.append("--tileable")
        if any(solid.angles):
            args += ["--orientation", ",".join(number_text(a) for a in solid.angles)]
        baseline = None if material.preset_values is None else \
            SolidOptions().replace(**material.preset_values)
        args += flag_args(solid, baseline)
    else:
        args += ["--volume", os.path.basename(material.volume)]
        if material.tileable:
            args.append("--tileable")
    if not options.vertex_colors:
        args += ["--texture-size", f"{options.texture_width}x{options.texture_height}"]
    if options.padding != default.padding:
        args += ["--padding", str(options.padding)]
    if options.scale_mode != "fit":
        args += ["--scale", options.scale_text()]
    if any(options.offset):
        args += ["--offset", ",".join(number_text(v) for v in options.offset)]
    if any(options.angles):
        args += ["--rotate", ",".join(number_text(v) for v in options.angles)]
    if options.interpolation != default.interpolation:
        args += ["--interpolation", options.interpolation]
    for flag in ("atlas", "vertex_colors"):
        if getattr(options, flag):
            args.append("--" + flag.replace("_", "-"))
    if job.bit_depth is not None:
        args += ["--bit-depth", str(job.bit_depth)]
    for name, source, _ in job.withs:
        source = source if isinstance(source, str) else source[0]
        args += ["--with", f"{name}={os.path.basename(source)}"]
    return args


def reproduce(meta: dict, path: str) -> str | None:
    """The `osmap carve` command line that writes PATH (any output of a carve) again."""
    folder = os.path.dirname(path)
    role = meta.get("role", "mesh")
    output = os.path.join(folder, meta.get("mesh_output", ""))
    command = ["osmap", "carve", meta.get("mesh", ""), "-o", output]
    if "texture" in meta:
        command += ["--texture", path if role == "texture" else
                    os.path.join(folder, meta["texture"])]
    if role == "preview":
        command += ["--preview", path]
    return shlex.join(command + shlex.split(meta.get("args", "")))
