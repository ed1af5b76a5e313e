"""The one exception type the CLI turns into a one-line message and a non-zero exit."""


class OsmapError(Exception):
    """A user-facing error: bad input file, bad option value, unwritable output.

    The message is shown as-is on one line, so it must name the file or option and the problem:

    >>> raise OsmapError("bricks.png: not an image OpenImageIO can read")
    """
