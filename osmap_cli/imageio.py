"""Image files in and out, all through OpenImageIO: the public face of osmap's image I/O.

    image = read_image("bricks.png")             # pixels float32 (H, W, C), channel names, ...
    write_image("out/b.exr", image.pixels, 32, image.channel_names, {"note": "copy"})
    read_metadata("out/b.exr")                   # {"note": "copy"}

Pixels are float32 arrays of shape (H, W, C): 8- and 16-bit files are normalised to [0, 1] on
reading and clipped and rounded on writing; float and half files (EXR, 32-bit TIFF) are kept as
stored; alpha is straight, never premultiplied. The output format follows the extension
(PNG, EXR, TIFF, JPEG; :func:`output_format` checks a path before any work). Writing is atomic
and verified (the file is read back). Every failure a user can cause raises OsmapError with one
line that starts with the path.

Behind it, one module per job: osmap_cli.image_formats (the format rules: extensions, bit depths,
channels, where metadata goes), osmap_cli.image_read and osmap_cli.image_write.
"""

from __future__ import annotations

from osmap_cli.image_formats import SUPPORTED_EXTENSIONS, output_depth, output_format
from osmap_cli.image_read import Image, read_image, read_metadata
from osmap_cli.image_write import encode_image, write_image

__all__ = [
    "Image",
    "SUPPORTED_EXTENSIONS",
    "encode_image",
    "output_depth",
    "output_format",
    "read_image",
    "read_metadata",
    "write_image",
]
