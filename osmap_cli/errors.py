"""The one exception type the CLI turns into a one-line message and a non-zero exit."""


class OsmapError(Exception):
    """A user-facing error: bad input file, bad option value, unwritable output.

    The message is shown as-is on one line, so it must name the file or option and the problem:

    >>> raise OsmapError("bricks.png: not an image OpenImageIO can read")
    """


class UsageError(OsmapError):
    """A malformed or out-of-range option value found outside click's parsing (exit code 2).

    `option` names the flag, as click's own usage errors do:

    >>> raise UsageError("'abc' is not a number", option="--size")
    """

    def __init__(self, message: str, option: str | None = None):
        super().__init__(f"Invalid value for '{option}': {message}" if option else message)


class Terminated(BaseException):
    """SIGTERM or SIGHUP: the run stops like on Ctrl-C (staged outputs are removed, nothing is
    replaced) and osmap exits with 128 + the signal number. A BaseException, so that no
    ``except Exception`` swallows it."""

    def __init__(self, signum: int):
        super().__init__(signum)
        self.signum = signum
