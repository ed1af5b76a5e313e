"""Provenance: the metadata stored in every output, from which it can be made again.

Every file osmap writes carries string key/value pairs (imageio.write_image stores them as PNG
text chunks, EXR header attributes, or a JSON block in the TIFF ImageDescription / JPEG comment;
NRRD volumes as ``key:=value`` lines). Besides the version, exemplar name, preset, seed and full
option set, ``args`` holds the *canonical* flags of the run, made from the resolved options (not
from what was typed) by the command's job, so that a batch and a separate run store the same
text, and so that ``osmap info FILE`` (osmap_cli.commands.info, which reads it back) can print
a command line that writes the same bytes again.

Only file *names* (no directories) are stored: the same inputs in another folder reproduce the
same file.
"""

from __future__ import annotations

import dataclasses
import json
import os
import shlex

from osmap_cli import __version__

__all__ = ["header", "image_metadata", "volume_metadata"]


def header(command: str) -> dict[str, str]:
    """The first keys of every output's metadata: the software, its version and the command."""
    return {"software": f"osmap {__version__}", "osmap_version": __version__,
            "command": command}


def image_metadata(options: dict, preset: str, exemplar: str, exemplar_shape, args: list[str],
                   role: str = "image", extra: dict | None = None,
                   command: str = "synth") -> dict[str, str]:
    """The metadata of one image output of `osmap COMMAND` (synth, inpaint, tileable).

    options: the recorded options (a dict with at least "seed"); role: "image" (the main
    output), "with:NAME" (a --with map), or "uv" (--uv-out).
    """
    meta = {
        **header(command),
        "exemplar": os.path.basename(exemplar),
        "exemplar_size": f"{exemplar_shape[1]}x{exemplar_shape[0]}",
        "preset": preset,
        "seed": str(options["seed"]),
        "options": json.dumps(options, sort_keys=True),
        "role": role,
        "args": shlex.join(args),
    }
    meta.update(extra or {})
    return meta


def volume_metadata(options, preset: str, exemplars, args: list[str]) -> dict[str, str]:
    """The metadata of one `osmap solid` output (the keys of `osmap synth`'s that apply);
    three exemplars are the --x, --y and --z ones; args: the canonical flags."""
    names = [os.path.basename(n) for n in exemplars]
    meta = {
        **header("solid"),
        "exemplar": names[0] if len(set(names)) == 1 else ",".join(names),
        "preset": preset,
        "seed": str(options.seed),
        "options": json.dumps(dataclasses.asdict(options), sort_keys=True),
        "args": shlex.join(args),
    }
    if len(names) == 3:
        meta["inputs"] = shlex.join(["--x", names[0], "--y", names[1], "--z", names[2]])
    return meta
