"""`osmap carve`: a solid texture carved into real objects (meshes), baked into a texture map.

The command checks every option and plans every output before any work, then runs one
osmap_cli.carving.job.CarveJob per mesh. Only click and the standard library are imported at
module level, so `osmap carve --help` stays fast.
"""

from __future__ import annotations

import os

import click

from osmap_cli.commands.common import (
    CONTEXT_SETTINGS,
    SizeType,
    batch_options,
    check_destination,
    claim_output,
    cluster_spec,
    expand_inputs,
    fill_template,
    input_fields,
    parse_withs,
    real_paths,
    refusal,
    run_batch,
    show_progress,
    tuning_flags,
)
from osmap_cli.commands.solid import (
    VOLUME_PARAMS,
    Angles,
    axis_set,
    volume_options,
    volume_settings,
)
from osmap_cli.errors import OsmapError
from osmap_cli.solid.options import SolidOptions

__all__ = ["carve_command"]

MESH_OUTPUTS = (".glb", ".gltf", ".obj", ".ply")

HELP = """Carve a solid texture into MESH: bake the volume where the surface passes
through it into a texture map on the mesh's UV layout, and write the textured
mesh to OUT.

\b
The material: --volume FILE (a volume osmap solid wrote: .npy, .nrrd, a .png
atlas or a slice folder), or a volume synthesized on the fly from --exemplar
FILE and/or --x/--y/--z FILE with any osmap solid option (--size, --seed,
--preset, --quality, --tileable, --orientation and the tuning flags; see
'osmap solid --help'). A tileable volume (--tileable, or one whose provenance
says so) wraps around; elsewhere the object is kept inside the volume and
points that overrun it take its border colours (clamped, with a warning).

\b
Placement: the object's bounding box is centred on the volume. --scale fit
(default) makes the object (turned by --rotate) fill the volume along its
tightest axis; --scale N puts N voxels on one object unit; --scale Nx repeats
the volume N times across the object's longest side. --offset DX,DY,DZ moves
the material (voxels); --rotate RX,RY,RZ turns it (degrees about x, then y,
then z; e.g. a wood grain along the object's axis).

\b
Baking: every texel that a triangle of the UV layout covers gets the 3D point
it maps to and the volume there (trilinear, or --interpolation tricubic); each
UV island is grown by --padding texels (the island's border colours carried
outwards) so that mip-maps show no seams; texels no island reaches take the
mean colour. A mesh without UVs (or with --atlas) gets a new UV atlas (xatlas).
UVs outside [0, 1] are refused (--atlas makes a new layout); overlapping UV
islands are a warning (the overlapping parts share texels).

\b
Outputs (by OUT's extension):
  .glb / .gltf  the mesh with the texture embedded (glTF 2.0, one file)
  .obj          the mesh, an .mtl beside it and the texture map it names
  .ply          the mesh with the volume's colours at its vertices
The texture map is also written as an image (--texture, default
OUT-stem_color.png; .png 8 or 16 bits, .exr, .tif; --bit-depth), and each
--with NAME=MAP beside it as OUT-stem_NAME.EXT: with a synthesized volume MAP
is an image aligned with the exemplar (normal, roughness ... maps; {stem},
{name}, {dir} fields name it per exemplar), rendered into the volume and baked
the same way; with --volume it is an aligned volume file. Normal maps are
baked as plain values (not turned into the surface's frame). --vertex-colors
samples the volume at the vertices instead of baking a map (.ply, .glb,
.gltf). --preview FILE.png renders the carved object from three sides.
Every output carries osmap's provenance ('osmap info OUT').

\b
Batches: several MESHes (or '-': paths from stdin, one per line) with
--out-dir DIR; each is named by --name TEMPLATE, fields {stem} {name}
{parent} {index} and {ext} (default {stem}.glb); --texture and --preview are
then templates too. A failing mesh is one line on stderr and does not stop
the others (--fail-fast does); an existing output is kept ("skipped") unless
--overwrite. --json prints one JSON object per finished job; -j N runs N jobs
at once; --scheduler runs them on a Dask cluster. Same inputs and options
give the same bytes with any thread count.

\b
Memory: the working set (texture map, volume) is estimated first and a size
that does not fit (or OSMAP_MEMORY_LIMIT) is refused.
Exit codes: 0 every job written or skipped, 1 a job failed, 2 usage error,
130 interrupted.
"""

EPILOG = """\b
Examples:
  osmap carve samples/vase.obj --volume marble.npy -o out/vase.glb --texture-size 2048
  osmap carve bowl.ply --exemplar samples/wood_side.png --x samples/wood_end.png \\
      -o out/bowl.obj --tileable --size 64 --scale 2x --rotate 90,0,0
  osmap carve samples/torus_knot.ply --volume granite.nrrd -o out/knot.glb \\
      --preview out/knot.png
  osmap carve scan.ply --volume granite.npy -o out/scan_vc.ply --vertex-colors
  osmap carve meshes/*.obj --volume marble.npy --out-dir out --name '{stem}.glb' -j 2
  osmap info out/vase.glb
"""


class Offset(click.ParamType):
    """DX,DY,DZ voxels."""

    name = "DX,DY,DZ"

    def convert(self, value, param, ctx):
        if isinstance(value, tuple):
            return value
        try:
            numbers = tuple(float(p) for p in str(value).replace(" ", "").split(","))
        except ValueError:
            numbers = ()
        if len(numbers) != 3 or not all(abs(n) <= 1e6 for n in numbers):
            self.fail(f"{value!r} is not three numbers of voxels (example: 0,12.5,-4)", param,
                      ctx)
        return numbers


class Scale(click.ParamType):
    name = "fit|N|Nx"

    def convert(self, value, param, ctx):
        from osmap_cli.carving.options import parse_scale

        if isinstance(value, tuple):
            return value
        try:
            return parse_scale(value)
        except OsmapError as exc:
            self.fail(str(exc).removeprefix("--scale: "), param, ctx)


@click.command("carve", help=HELP, epilog=EPILOG, short_help="Carve a solid texture into a mesh.",
               context_settings=CONTEXT_SETTINGS)
@click.argument("meshes", nargs=-1, type=click.Path(path_type=str), metavar="MESH...")
@click.option("-o", "--output", default=None, type=click.Path(path_type=str), metavar="OUT",
              help="The carved mesh (one MESH): .glb, .gltf, .obj or .ply. Replaced "
              "atomically if it exists.")
@click.option("--out-dir", type=click.Path(path_type=str), default=None, metavar="DIR",
              help="Write each mesh's outputs into DIR (created if missing), named by --name.")
@click.option("--name", "name_template", default=None, metavar="TEMPLATE",
              help="Output name in --out-dir (fields above). [default: {stem}.glb]")
@batch_options
@click.option("--volume", type=click.Path(path_type=str), default=None, metavar="FILE",
              help="The volume to carve: .npy, .nrrd, a .png atlas or a slice folder "
              "(osmap solid's outputs).")
@click.option("--exemplar", type=click.Path(path_type=str), default=None, metavar="FILE",
              help="Synthesize the volume from this exemplar (with the osmap solid options).")
@volume_options
@click.option("--texture-size", type=SizeType(), default="1024", show_default=True,
              help="Texture map size in texels: N for NxN, or WxH.")
@click.option("--padding", type=click.IntRange(0, 64), default=4, show_default=True,
              metavar="N", help="Texels each UV island is grown by.")
@click.option("--scale", "scale", type=Scale(), default="fit", show_default=True,
              help="fit, N voxels per object unit, or Nx repeats across the object.")
@click.option("--offset", type=Offset(), default="0,0,0", show_default=True,
              help="Move the material by this many voxels along the volume's x, y, z.")
@click.option("--rotate", type=Angles(), default="0,0,0", show_default=True,
              help="Turn the material: degrees about x, then y, then z.")
@click.option("--interpolation", type=click.Choice(("trilinear", "tricubic")),
              default="trilinear", show_default=True, help="How the volume is sampled.")
@click.option("--atlas", is_flag=True, help="Make a new UV atlas (xatlas) even when the mesh "
              "has UVs.")
@click.option("--vertex-colors", is_flag=True, help="Colours at the vertices instead of a "
              "texture map (.ply, .glb, .gltf).")
@click.option("--texture", default=None, metavar="FILE",
              help="The texture map's file (.png, .exr, .tif); with --out-dir a name template "
              "in DIR. [default: OUT's stem + _color.png]")
@click.option("--bit-depth", type=click.Choice(("8", "16", "32")), default=None,
              help="Texture map bit depth (PNG 8/16, EXR 16/32, TIFF 8/16/32). [default: the "
              "format's]")
@click.option("--with", "with_maps", multiple=True, metavar="NAME=MAP",
              help="Also carve an aligned map of the material (repeatable; see above).")
@click.option("--preview", type=click.Path(path_type=str), default=None, metavar="FILE.png",
              help="Also write a picture of the carved object from three sides; with "
              "--out-dir a name template in DIR.")
@click.option("-q", "--quiet", is_flag=True, help="No progress bar and no summary line.")
@tuning_flags(SolidOptions)
@click.pass_context
def carve_command(ctx, meshes, output, out_dir, name_template, jobs, fail_fast, json_lines,
                  overwrite, scheduler, scheduler_file, threads, volume, exemplar, size, seed,
                  preset, quality, tileable, orientation, ex_x, ex_y, ex_z, texture_size,
                  padding, scale, offset, rotate, interpolation, atlas, vertex_colors, texture,
                  bit_depth, with_maps, preview, quiet, **tuning):
    from osmap_cli.carving.job import CarveJob
    from osmap_cli.carving.options import CarveOptions

    cluster = cluster_spec(scheduler, scheduler_file, threads, jobs)
    if not meshes:
        raise click.UsageError("give MESH (one or more mesh files, or '-' for stdin)")
    material = _material(ctx, volume, exemplar, ex_x, ex_y, ex_z, size, seed, preset, quality,
                         tileable, orientation, tuning)
    if vertex_colors and (texture is not None or bit_depth is not None or with_maps):
        raise click.UsageError("--vertex-colors writes no texture map: drop --texture, "
                               "--bit-depth and --with")
    try:
        options = CarveOptions(
            texture_width=texture_size[0], texture_height=texture_size[1], padding=padding,
            scale_mode=scale[0], scale=scale[1], offset_x=offset[0], offset_y=offset[1],
            offset_z=offset[2], rotate_x=rotate[0], rotate_y=rotate[1], rotate_z=rotate[2],
            interpolation=interpolation, atlas=atlas, vertex_colors=vertex_colors,
            wrap=tileable).validated()
    except OsmapError as exc:
        raise click.UsageError(str(exc)) from None
    paths = expand_inputs(meshes)
    withs = parse_withs(with_maps)
    plans = _plan_outputs(paths, output, out_dir, name_template, texture, preview, withs,
                          material, options, bit_depth, overwrite)
    inputs = real_paths([*paths, *material.names(),
                         *(p for plan in plans for _, source, _ in plan[3]
                           for p in ([source] if isinstance(source, str) else source))])
    job_list = [CarveJob(
        index=index, exemplar=path, output=main, material=material, options=options,
        texture=tex, withs=tuple(maps), bit_depth=None if bit_depth is None else int(bit_depth),
        preview=prev, replace=output is not None or overwrite,
        refused=refusal([main, *(p for p in (tex, prev) if p), *(o for _, _, o in maps)],
                        inputs),
        progress=show_progress(quiet, jobs),
    ) for index, (path, (main, tex, prev, maps)) in enumerate(zip(paths, plans), 1)]
    return run_batch(job_list, jobs, fail_fast, json_lines, quiet, cluster)


def _material(ctx, volume, exemplar, ex_x, ex_y, ex_z, size, seed, preset, quality, tileable,
              orientation, tuning):
    """The Material: a volume file, or the exemplars and validated SolidOptions."""
    from osmap_cli.carving.job import Material

    axes = any(f is not None for f in (ex_x, ex_y, ex_z))
    if volume is not None:
        if exemplar is not None or axes:
            raise click.UsageError("give either --volume or --exemplar/--x/--y/--z, not both")
        given = [name for name in VOLUME_PARAMS if name != "tileable"
                 and ctx.get_parameter_source(name) == click.core.ParameterSource.COMMANDLINE]
        given += [name for name, value in tuning.items() if value is not None]
        if given:
            flag = "--" + given[0].removeprefix("ex_").replace("_", "-")
            raise click.UsageError(f"{flag} sets up a synthesized volume; with --volume the "
                                   "volume is already made (drop it, or use --exemplar)")
        return Material(volume=volume, tileable=tileable)
    if exemplar is None and not axes:
        raise click.UsageError("give the material: --volume FILE, or --exemplar FILE and/or "
                               "--x/--y/--z FILE")
    solid, loaded = volume_settings(size, seed, preset, quality, tileable, orientation, tuning)
    from osmap_cli.presets import is_preset_path

    files = axis_set(exemplar, ex_x, ex_y, ex_z, "--exemplar")[1] if axes else (exemplar,)
    if len(set(files)) == 1:
        files = files[:1]
    return Material(files=files, solid=solid, preset=loaded.name,
                    preset_values=None if is_preset_path(preset) else dict(loaded.values),
                    tileable=tileable)


def _plan_outputs(paths, output, out_dir, name_template, texture, preview, withs, material,
                  options, bit_depth, overwrite):
    """[(mesh output, texture or None, preview or None, [(NAME, source, output)])] per mesh,
    checked before any work."""
    from osmap_cli.carving.meshio import mtl_path
    from osmap_cli.imageio import output_format
    from osmap_cli.materials import expand_path
    from osmap_cli.surface.export import check_output_path

    if preview is not None and os.path.splitext(preview)[1].lower() != ".png":
        raise click.BadParameter(f"{preview}: must be a .png file", param_hint="'--preview'")
    check_destination(output, out_dir, len(paths), name_template, overwrite)
    owners: dict[str, str] = {}
    plans = []
    for index, path in enumerate(paths, 1):
        fields = {**input_fields(path, index), "ext": "glb"}
        if output is not None:
            main, tex, prev = output, texture, preview
        else:
            main = os.path.join(out_dir, fill_template(name_template or "{stem}.glb", fields,
                                                       "'--name'"))
            tex, prev = (os.path.join(out_dir, fill_template(p, fields, hint)) if p else None
                         for p, hint in ((texture, "'--texture'"), (preview, "'--preview'")))
        ext = os.path.splitext(main)[1].lower()
        check_output_path(main, "-o" if output is not None else "--name", MESH_OUTPUTS)
        if options.vertex_colors and ext == ".obj":
            raise click.UsageError(f"{main}: --vertex-colors needs .ply, .glb or .gltf (OBJ "
                                   "has no standard vertex colours)")
        if not options.vertex_colors and ext == ".ply":
            raise click.UsageError(f"{main}: PLY carries no texture: add --vertex-colors, or "
                                   "write .glb, .gltf or .obj")
        stem = os.path.splitext(main)[0]
        maps = []
        if not options.vertex_colors:
            tex = tex or f"{stem}_color.png"
            try:
                output_format(tex, None if bit_depth is None else int(bit_depth), 1)
            except OsmapError as exc:
                raise click.BadParameter(str(exc), param_hint="'--texture'") from None
            folder, tex_ext = os.path.dirname(tex), os.path.splitext(tex)[1]
            for w in withs:
                if material.synthesized:
                    source = tuple(expand_path(w.path, f) for f in material.files)
                else:
                    source = w.path
                target = os.path.join(folder, f"{os.path.basename(stem)}_{w.name}{tex_ext}")
                maps.append((w.name, source, target))
        targets = [main, tex, prev, *(t for _, _, t in maps)]
        if ext == ".obj":
            targets.append(mtl_path(main))
        for target in targets:
            if target is not None:
                claim_output(owners, target, path)
        plans.append((main, tex, prev, maps))
    return plans
