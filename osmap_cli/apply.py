"""Rendering a saved position map on another aligned map (`osmap apply UV MAP -o OUT`).

A position map is what `osmap synth --uv-out` writes (2-channel float EXR: u = exemplar column,
v = exemplar row, in exemplar pixels) or what `osmap solid --uv-out FILE.npy` writes (float32
(Z, Y, X, 3): u, v, exemplar index). Rendering it on a map aligned with the exemplar (normal,
roughness, height, ...) gives that map's version of the synthesized texture, pixel-aligned with
it: the same result as `--with` at synthesis time.
"""

from __future__ import annotations

import json
import os

import numpy as np

from osmap_cli.errors import OsmapError


def _is_normal(path: str, normal: bool | None) -> bool:
    return "normal" in os.path.basename(path).lower() if normal is None else normal


def read_positions(uv: str):
    """(positions float32 (H, W, 2) row/col, metadata) from a --uv-out EXR."""
    from osmap_cli.imageio import read_image, read_metadata

    image = read_image(uv)
    names = tuple(image.channel_names)
    if "u" in names and "v" in names:
        u, v = image.pixels[..., names.index("u")], image.pixels[..., names.index("v")]
    elif image.pixels.shape[2] == 2:
        u, v = image.pixels[..., 0], image.pixels[..., 1]
    else:
        raise OsmapError(f"{uv}: not a position map (expected channels u and v, got "
                         f"{', '.join(names)})")
    if image.bit_depth != 32:
        raise OsmapError(f"{uv}: a position map must be a float EXR (this one has "
                         f"{image.bit_depth}-bit samples)")
    if not (np.all(np.isfinite(u)) and np.all(np.isfinite(v))):
        raise OsmapError(f"{uv}: position map has NaN or infinite values")
    return np.ascontiguousarray(np.stack([v, u], -1), np.float32), read_metadata(uv)


def positions_jacobian(positions: np.ndarray, meta: dict) -> np.ndarray:
    """Output-to-exemplar Jacobian for rotating normals: from the recorded options when the
    run had no control fields, else estimated per pixel from the positions (the one-sided
    difference of smaller size, so seams between copies are ignored)."""
    from osmap_cli.fields import jacobians

    fielded = "orientation_field" in meta or "scale_field" in meta
    try:
        opts = json.loads(meta["options"])
        theta = np.radians(float(opts["orientation"]))
        scale, anisotropy = float(opts["scale"]), float(opts["anisotropy"])
    except (KeyError, ValueError, TypeError):
        fielded = True
    if not fielded:
        return jacobians(np.cos(theta), np.sin(theta), scale, anisotropy)
    pos = positions.astype(np.float64)
    out = np.zeros(pos.shape[:2] + (2, 2), np.float32)
    for axis in (0, 1):
        step = np.diff(pos, axis=axis)
        pad = [(0, 0), (0, 0), (0, 0)]
        pad[axis] = (0, 1)
        forward = np.pad(step, pad, mode="edge")
        pad[axis] = (1, 0)
        backward = np.pad(step, pad, mode="edge")
        pick = (np.linalg.norm(forward, axis=-1, keepdims=True)
                <= np.linalg.norm(backward, axis=-1, keepdims=True))
        out[..., :, axis] = np.where(pick, forward, backward)
    return out


def apply_image(uv: str, map_path: str, output: str, normal: bool | None,
                bit_depth: str | None) -> str:
    """Render one 2D position map on one map and write it; returns the summary line."""
    from osmap_cli.image_formats import check_jpeg_channels
    from osmap_cli.imageio import encode_image, output_depth, read_image
    from osmap_cli.materials import render_map
    from osmap_cli.output import write_atomically
    from osmap_cli.provenance import header
    from osmap_cli.synth.job import map_renderer
    from osmap_cli.synth.render import render_settings

    output_depth(output, bit_depth, 1, 8)  # path and --bit-depth checks before any work
    positions, meta = read_positions(uv)
    image = read_image(map_path)
    h, w = image.pixels.shape[:2]
    if "exemplar_size" in meta and meta["exemplar_size"] != f"{w}x{h}":
        raise OsmapError(f"{map_path}: map is {w}x{h} but {uv} was made from a "
                         f"{meta['exemplar_size']} exemplar; the map must be aligned with it")
    if positions[..., 0].min() < -0.5 or positions[..., 0].max() > h - 0.5 \
            or positions[..., 1].min() < -0.5 or positions[..., 1].max() > w - 0.5:
        raise OsmapError(f"{map_path}: map is {w}x{h} but the positions in {uv} reach "
                         f"{positions[..., 1].max():.0f}, {positions[..., 0].max():.0f}; "
                         "the map must be aligned with the exemplar")
    names = tuple(image.channel_names)
    fmt, depth = output_depth(output, bit_depth, len(names), image.bit_depth)
    check_jpeg_channels(output, fmt, names)
    is_normal = _is_normal(map_path, normal)
    jacobian = positions_jacobian(positions, meta)
    try:
        recorded = json.loads(meta.get("options", "{}"))
    except ValueError:
        recorded = {}
    wrap, blend = render_settings(recorded if isinstance(recorded, dict) else {})
    draw = map_renderer(positions, jacobian, wrap, blend)
    pixels = render_map(image, draw, jacobian, is_normal, map_path)
    args = ["--bit-depth", str(depth)]
    if normal is not None:
        args.insert(0, "--normal" if normal else "--not-normal")
    import shlex

    metadata = {
        **header("apply"), "uv": os.path.basename(uv), "map": os.path.basename(map_path),
        "normal_map": str(is_normal).lower(), "args": shlex.join(args),
    }
    for key in ("exemplar", "exemplar_size", "preset", "seed", "options"):
        if key in meta:
            metadata[key] = meta[key]
    write_atomically(output, lambda temp: encode_image(temp, pixels, depth, names, metadata,
                                                       name=output))
    height, width = pixels.shape[:2]
    plural = "s" * (len(names) != 1)
    return f"wrote {output}: {width}x{height}, {len(names)} channel{plural}, {map_path} " \
           f"through {uv}"


def apply_volume(uv: str, maps: tuple[str, ...], output: str, normal: bool | None) -> None:
    """Render a solid position map (.npy, (Z, Y, X, 3)) on one map per exemplar."""
    from osmap_cli.imageio import read_image

    try:
        from osmap_cli.solid import render_volume
    except (ImportError, AttributeError):
        raise OsmapError(f"{uv}: volume position maps need osmap solid's render_volume, "
                         "which this osmap does not have") from None
    ext = os.path.splitext(output)[1].lower()
    if ext not in (".npy", ".nrrd"):
        raise OsmapError(f"{output}: a volume goes to .npy or .nrrd")
    try:
        volume_uv = np.load(uv, allow_pickle=False)
    except (OSError, ValueError) as exc:
        raise OsmapError(f"{uv}: cannot read the position volume ({exc})") from None
    if volume_uv.ndim != 4 or volume_uv.shape[3] != 3:
        raise OsmapError(f"{uv}: expected a (Z, Y, X, 3) position volume, got shape "
                         f"{volume_uv.shape}")
    images = [read_image(p) for p in maps]
    used = int(volume_uv[..., 2].max()) + 1
    if len(images) not in (1, used):
        raise OsmapError(f"{uv}: the volume was made from {used} exemplars; give 1 or {used} "
                         f"maps, got {len(images)}")
    if any(_is_normal(p, normal) for p in maps):
        raise OsmapError(f"{output}: normal maps cannot be applied to volumes (a volume has "
                         "no tangent space); use --not-normal to copy the values as they are")
    pixels = [im.pixels for im in images]
    if len(pixels) == 1 and used > 1:
        pixels = pixels * used
    for image, p in zip(images, maps):
        if image.pixels.shape[2] != images[0].pixels.shape[2]:
            raise OsmapError(f"{p}: the maps must have the same channels")
    volume = np.asarray(render_volume(volume_uv.astype(np.float32), pixels), np.float32)
    _write_volume(output, volume, {"uv": os.path.basename(uv),
                                   "map": " ".join(os.path.basename(p) for p in maps)})


def _write_volume(output: str, volume: np.ndarray, metadata: dict) -> None:
    from osmap_cli.output import check_parent, write_atomically
    from osmap_cli.provenance import header
    from osmap_cli.solid import volumeio

    check_parent(output)
    fmt = "npy" if output.lower().endswith(".npy") else "nrrd"
    meta = {**header("apply"), **metadata}
    write, _ = volumeio.volume_writer(output, volume, fmt, depth=32, channel_names=None,
                                      metadata=meta)
    write_atomically(output, write)
