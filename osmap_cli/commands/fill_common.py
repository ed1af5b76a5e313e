"""What `osmap inpaint` and `osmap tileable` share: their options (those of `osmap synth` that
apply to an image of fixed size) and the planning of their jobs (osmap_cli.synth.fill_job)."""

from __future__ import annotations

import os

import click

from osmap_cli.commands.common import (
    batch_options,
    check_destination,
    cluster_spec,
    expand_inputs,
    image_outputs,
    input_fields,
    load_preset,
    parse_withs,
    real_paths,
    refusal,
    resolve_options,
    run_batch,
    show_progress,
    tuning_flags,
)
from osmap_cli.synth.options import QUALITIES, SynthOptions

__all__ = ["NAME_FIELDS", "OSMAP_ONLY", "fill_options", "plan_fill"]

# the OS-Map's tunables: a fill starts from the kept pixels, not from an OS-Map layout
OSMAP_ONLY = ("window_scale", "som_steps_per_node", "som_sigma_max", "som_sigma_min",
              "som_alpha_max", "som_alpha_min", "som_anisotropy", "som_range")

NAME_FIELDS = ("stem", "name", "ext", "parent", "index", "seed", "preset", "quality")

FILL_COMMON_HELP = """\b
Batches: give several images (or "-" to read paths from stdin) with
--out-dir DIR; each output is named by --name TEMPLATE (default
"{stem}.{ext}"; fields {stem} {name} {ext} {parent} {index} {seed}
{preset} {quality}). Existing outputs in --out-dir are kept unless
--overwrite; -j N runs N jobs at a time; --json prints one JSON record per
job. The output format follows the extension (.png .exr .tif .tiff .jpg);
--with maps (normal, roughness, ...) aligned with IMAGE get the same
treatment, so a material set stays aligned; --uv-out writes the exemplar
position of every pixel (kept pixels: their own position). Same inputs,
options and seed give the same bytes, with any thread count.
"""


def fill_options(function):
    """The options both commands take (after their own)."""
    decorators = [
        click.argument("images", nargs=-1, required=True, type=click.Path(path_type=str),
                       metavar="IMAGE..."),
        click.option("-o", "--output", "output", default=None, type=click.Path(path_type=str),
                     metavar="OUTPUT", help="Output image (one IMAGE); the extension picks the "
                     "format. An existing file is replaced (atomically)."),
        click.option("--out-dir", type=click.Path(path_type=str), default=None, metavar="DIR",
                     help="Write each image's output into DIR, named by --name."),
        click.option("--name", "name_template", default=None, metavar="TEMPLATE",
                     help="Output file name in --out-dir. [default: {stem}.{ext}]"),
        batch_options,
        click.option("--seed", type=int, default=0, show_default=True,
                     help="Random seed (a whole number >= 0)."),
        click.option("--preset", default="default", show_default=True, metavar="NAME|FILE.toml",
                     help="Tuning preset: a built-in name (see 'osmap presets') or a TOML "
                     "file."),
        click.option("--quality", type=click.Choice(QUALITIES), default="default",
                     show_default=True, help="Speed / quality trade-off."),
        click.option("--bit-depth", type=click.Choice(["8", "16", "32"]), default=None,
                     help="Bits per sample of OUTPUT (as for 'osmap synth'). [default: the "
                     "format's, at least IMAGE's]"),
        click.option("--with", "with_maps", multiple=True, metavar="[NAME=]MAP",
                     help="An extra map aligned with IMAGE, treated the same way and written "
                     "as <output stem>_NAME<ext>. Repeatable; {stem} {name} {dir} in MAP refer "
                     "to each image."),
        click.option("--uv-out", type=click.Path(path_type=str), default=None,
                     metavar="FILE.exr", help="Also write the exemplar position of every "
                     'pixel: float EXR, channels "u" (x) and "v" (y). With --out-dir: a name '
                     "template."),
        click.option("-q", "--quiet", is_flag=True, help="No progress bar, no summary line."),
        click.option("--verbose", is_flag=True, help="The summary line also says what the "
                     "image's analysis found: the lattice the fill keeps (--lattice)."),
        tuning_flags(SynthOptions, skip=OSMAP_ONLY),
    ]
    for decorate in reversed(decorators):
        function = decorate(function)
    return function


def plan_fill(mode: str, *, images, output, out_dir, name_template, jobs, fail_fast, json_lines,
              overwrite, scheduler, scheduler_file, threads, seed, preset, quality, bit_depth,
              with_maps, uv_out, quiet, verbose=False, mask=None, border=0, exemplars=(),
              **tuning) -> int:
    """Check every option, plan every output, run one FillJob per image; the exit code. The
    keywords are the click parameters of fill_options (the tuning flags land in `tuning`)."""
    from osmap_cli.materials import expand_path
    from osmap_cli.presets import is_preset_path
    from osmap_cli.synth.fill_job import FillJob

    cluster = cluster_spec(scheduler, scheduler_file, threads, jobs)
    loaded = load_preset(preset, "synth")
    options = resolve_options(SynthOptions, loaded.values,
                              {"seed": seed, "quality": quality}, tuning)
    for given, flag, why in (
            (with_maps, "--with", "the exemplars have no maps aligned with them"),
            (uv_out, "--uv-out", "a position in one of several images has no single image "
             "to refer to")):
        if exemplars and given:
            raise click.UsageError(f"--exemplar does not combine with {flag} ({why})")
    inputs = expand_inputs(images)
    withs = parse_withs(with_maps)
    if uv_out is not None and os.path.splitext(uv_out)[1].lower() != ".exr":
        raise click.BadParameter(f"{uv_out}: must be an .exr file", param_hint="'--uv-out'")
    check_destination(output, out_dir, len(inputs), name_template, overwrite)
    preset_name = os.path.basename(preset) if is_preset_path(preset) else preset
    preset_values = None if is_preset_path(preset) else dict(loaded.values)

    plans, owners = [], {}
    for index, image in enumerate(inputs, 1):
        base = input_fields(image, index)
        fields = {**base, "ext": os.path.splitext(base["name"])[1].lstrip(".").lower(),
                  "seed": options.seed, "preset": preset_name, "quality": options.quality}
        main, maps, uv = image_outputs(image, fields, output, out_dir, name_template, uv_out,
                                       withs, bit_depth, owners)
        image_mask = expand_path(mask, image) if mask not in (None, "alpha") else mask
        plans.append((image, main, maps, uv, image_mask,
                      tuple(expand_path(e, image) for e in exemplars)))

    input_paths = real_paths([*inputs, *(s.path for _, _, ms, _, _, _ in plans for s, _ in ms),
                              *(p[4] for p in plans if p[4] not in (None, "alpha")),
                              *(e for p in plans for e in p[5])])
    job_list = []
    for index, (image, main, maps, uv, image_mask, image_exemplars) in enumerate(plans, 1):
        refused = refusal([main, *(o for _, o in maps), *([uv] if uv else [])], input_paths)
        job_list.append(FillJob(
            index=index, exemplar=image, output=main, options=options, preset=preset_name,
            preset_values=preset_values, bit_depth=bit_depth, uv_out=uv, withs=tuple(maps),
            replace=output is not None or overwrite, refused=refused,
            progress=show_progress(quiet, jobs), quiet=quiet, verbose=verbose,
            label=f"osmap {mode}" if len(plans) == 1 else os.path.basename(image),
            mode=mode, mask=image_mask, border=border, exemplars=image_exemplars))
    return run_batch(job_list, jobs, fail_fast, json_lines, quiet, cluster)
