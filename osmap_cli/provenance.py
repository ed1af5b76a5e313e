"""Provenance: the metadata stored in every output, and the command line that reproduces it.

Every file osmap writes carries string key/value pairs (imageio.write_image stores them as PNG
text chunks, EXR header attributes, or a JSON block in the TIFF ImageDescription / JPEG comment;
NRRD volumes as ``key:=value`` lines). Besides the version, exemplar name, preset, seed and full
option set, ``args`` holds the *canonical* flags of the run, made from the resolved options (not
from what was typed), so that a batch and a separate run store the same text, and so that
``osmap info FILE`` can print a command line that writes the same bytes again.

Only file *names* (no directories) are stored: the same inputs in another folder reproduce the
same file.
"""

from __future__ import annotations

import dataclasses
import json
import os
import shlex

from osmap_cli import __version__

__all__ = ["fill_args", "header", "image_metadata", "read_provenance", "reproduce_command",
           "synth_args", "volume_metadata"]

# the plain (not tunable) numeric flags written when they differ from their default
_PLAIN = ("scale", "orientation", "anisotropy")


def synth_args(options, preset: str, preset_values: dict | None, bit_depth: int,
               orientation_field: str | None = None, scale_field: str | None = None
               ) -> list[str]:
    """Canonical `osmap synth` flags (no exemplar, no -o) that resolve to `options` again.

    `preset_values` is the built-in preset's table; None for a preset *file*, in which case
    every tunable is written out (the file may be gone or changed when the command is re-run).
    """
    from osmap_cli.options import flag_args, number_text
    from osmap_cli.synth.options import SynthOptions

    defaults = SynthOptions()
    args = ["--size", f"{options.width}x{options.height}", "--seed", str(options.seed),
            "--preset", preset]
    for name in _PLAIN:
        value = getattr(options, name)
        if value != getattr(defaults, name):
            args += ["--" + name, number_text(value)]
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


def fill_args(options, preset: str, preset_values: dict | None, bit_depth: int,
              more: list[str]) -> list[str]:
    """Canonical `osmap inpaint` / `osmap tileable` flags: synth_args' without --size and
    --tileable (the image sets them), then MORE (--mask NAME, --border N)."""
    args = synth_args(options, preset, preset_values, bit_depth)[2:]
    return [a for a in args if a != "--tileable"] + list(more)


def header(command: str) -> dict[str, str]:
    """The first keys of every output's metadata: the software, its version and the command."""
    return {"software": f"osmap {__version__}", "osmap_version": __version__,
            "command": command}


def image_metadata(options, preset: str, exemplar: str, exemplar_shape, args: list[str],
                   role: str = "image", extra: dict | None = None,
                   command: str = "synth") -> dict[str, str]:
    """The metadata of one `osmap synth` output (or `osmap COMMAND`: inpaint, tileable).

    role: "image" (the main output), "with:NAME" (a --with map), or "uv" (--uv-out).
    """
    recorded = dataclasses.asdict(options)
    if "target_guide" not in (extra or {}):
        # unguided: the guide weight plays no part (and the records stay as before it existed)
        recorded.pop("guide_weight", None)
    meta = {
        **header(command),
        "exemplar": os.path.basename(exemplar),
        "exemplar_size": f"{exemplar_shape[1]}x{exemplar_shape[0]}",
        "preset": preset,
        "seed": str(options.seed),
        "options": json.dumps(recorded, sort_keys=True),
        "role": role,
        "args": shlex.join(args),
    }
    meta.update(extra or {})
    return meta


def volume_metadata(options, preset: str, exemplars) -> dict[str, str]:
    """The metadata of one `osmap solid` output (the keys of `osmap synth`'s that apply)."""
    names = [os.path.basename(n) for n in exemplars]
    return {
        **header("solid"),
        "exemplar": names[0] if len(set(names)) == 1 else ",".join(names),
        "preset": preset,
        "seed": str(options.seed),
        "options": json.dumps(dataclasses.asdict(options), sort_keys=True),
    }


def reproduce_command(meta: dict[str, str], path: str) -> str | None:
    """The command line that writes `path` again (None when the metadata cannot tell)."""
    command = meta.get("command")
    args = shlex.split(meta.get("args", ""))
    if command == "carve" and "args" in meta:
        from osmap_cli.carving.job import reproduce

        return reproduce(meta, path)
    if command == "apply" and meta.get("uv") and meta.get("map"):
        return shlex.join(["osmap", "apply", meta["uv"], meta["map"], "-o", path, *args])
    if command not in ("synth", "solid", "inpaint", "tileable") or "args" not in meta:
        return None
    inputs = shlex.split(meta["inputs"]) if "inputs" in meta else [meta.get("exemplar", "")]
    role = meta.get("role", "image")
    output = path
    stem, ext = os.path.splitext(path)
    if role.startswith("with:") and stem.endswith("_" + role[5:]):
        output = stem[: -len(role[5:]) - 1] + ext
    elif role == "uv":
        output = stem + "_image" + meta.get("image_ext", ".png")
        args += ["--uv-out", path]
    return shlex.join(["osmap", command, *inputs, "-o", output, *args])


def read_provenance(path: str) -> dict[str, str]:
    """The osmap key/value pairs stored in an image or a NRRD file."""
    from osmap_cli.errors import OsmapError

    if os.path.isdir(path):
        raise OsmapError(f"{path}: is a directory (give one slice file)")
    if not os.path.isfile(path):
        raise OsmapError(f"{path}: no such file")
    with open(path, "rb") as handle:
        if handle.read(4) == b"NRRD":
            from osmap_cli.solid.volumeio import read_nrrd_header

            handle.seek(0)
            return read_nrrd_header(handle, path)[1]
    if path.lower().endswith((".glb", ".gltf", ".obj", ".mtl", ".ply")):
        from osmap_cli.carving.meshio import read_mesh_provenance

        return read_mesh_provenance(path)
    if path.lower().endswith(".npy"):
        raise OsmapError(f"{path}: .npy files cannot store metadata (no provenance)")
    from osmap_cli.imageio import read_metadata

    return read_metadata(path)


